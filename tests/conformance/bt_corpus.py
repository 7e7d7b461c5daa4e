"""Corpus helpers: reads SOURCES.md (plugin nodes to stub, main tree, BT.CPP 4.10 verdict per file) and
writes a copy of the corpus whose plugin nodes are port-less generic stubs (leaf -> StubLeaf,
decorator -> StubDecorator, control -> Sequence), so both engines can load the same files."""

from __future__ import annotations

import os
import re
import shutil
from dataclasses import dataclass, field
from pathlib import Path

CORPUS = Path(__file__).resolve().parents[2].parent / "shared" / "bt-corpus"
_KEEP = {"name", "ID"}


@dataclass
class CorpusEntry:
    path: str
    stubs: dict[str, str] = field(default_factory=dict)  # node ID -> leaf/decorator/control
    main_tree: str | None = None
    oracle_410: str = ""


def read_sources(corpus: Path = CORPUS) -> list[CorpusEntry]:
    text = (corpus / "SOURCES.md").read_text(encoding="utf-8")
    entries: list[CorpusEntry] = []
    for block in re.split(r"^## ", text, flags=re.M)[1:]:
        header = block.splitlines()[0].strip()
        if not header.startswith("`"):
            continue
        entry = CorpusEntry(header.strip("`"))
        stubs = re.search(r"plugin nodes to stub: (.*)", block)
        if stubs:
            for name, kind in re.findall(r"(\w+) \(([^()]*(?:\([^()]*\))?[^()]*)\) ×", stubs.group(1)):
                if kind in ("leaf", "decorator", "control"):
                    entry.stubs[name] = kind
        main = re.search(r"main tree passed explicitly: `([^`]+)`", block)
        entry.main_tree = main.group(1) if main else None
        verdict = re.search(r"BT\.CPP 4\.10 oracle: \*\*(\w+)\*\*", block)
        entry.oracle_410 = verdict.group(1) if verdict else ""
        entries.append(entry)
    return entries


_TAG = re.compile(r"<(/?)([A-Za-z_][\w.-]*)((?:\s+[^\s=>/]+\s*=\s*(?:\"[^\"]*\"|'[^']*'))*)\s*(/?)>")
_ATTR = re.compile(r"([^\s=>/]+)\s*=\s*(\"[^\"]*\"|'[^']*')")


def stub_text(text: str, stubs: dict[str, str]) -> str:
    """Rewrites plugin elements (compact or explicit syntax) into generic stubs without ports."""

    def replace(m: re.Match[str]) -> str:
        closing, tag, attr_text, selfclose = m.groups()
        attrs = _ATTR.findall(attr_text or "")
        node_id = tag
        explicit = tag in ("Action", "Condition", "Control", "Decorator")
        if explicit:
            node_id = next((v[1:-1] for k, v in attrs if k == "ID"), tag)
        kind = stubs.get(node_id)
        if kind is None:
            return m.group(0)
        new_tag = {"leaf": "StubLeaf", "decorator": "StubDecorator", "control": "Sequence"}[kind]
        if closing:
            return (
                f"</{'Decorator' if explicit and kind == 'decorator' else new_tag}>"
                if not explicit
                else f"</{tag}>"
            )
        kept = [(k, v) for k, v in attrs if k == "name" or k.startswith("_")]
        if explicit:
            kept = [("ID", f'"{new_tag}"')] + kept
            new_tag = tag
        rendered = "".join(f" {k}={v}" for k, v in kept)
        return f"<{new_tag}{rendered}{' /' if selfclose else ''}>"

    return _TAG.sub(replace, text)


def stubbed_copy(dest: Path, corpus: Path = CORPUS) -> dict[str, CorpusEntry]:
    """Copies the corpus to dest with every file's plugin nodes stubbed; returns entries by path."""
    entries = {e.path: e for e in read_sources(corpus)}
    all_stubs: dict[str, dict[str, str]] = {p: e.stubs for p, e in entries.items()}
    for root, _dirs, files in os.walk(corpus):
        for name in files:
            src = Path(root) / name
            rel = src.relative_to(corpus).as_posix()
            out = dest / rel
            out.parent.mkdir(parents=True, exist_ok=True)
            if name.endswith(".xml"):
                out.write_text(
                    stub_text(src.read_text(encoding="utf-8"), all_stubs.get(rel, {})), encoding="utf-8"
                )
            else:
                shutil.copy(src, out)
    return entries
