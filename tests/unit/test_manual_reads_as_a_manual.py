"""The README is the user's manual and docs/ describe the design: neither becomes a lab notebook.

Issue 52: the README had grown to 478 lines, its "Known limits" about 80 lines of run-by-run
figures ("in the last 71 runs ... held in 54 of those 71"), and docs/architecture.md and
docs/performance.md narrated benchmark runs one by one. `make bench` prints the current figures;
the documents keep one current figure per measure and one paragraph per design choice. Code
comments cite docs sections by title, so a section renamed or cut must take its citations along.
"""

from __future__ import annotations

import re
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[2]
README = ROOT / "README.md"
DOCUMENTS = [README, *sorted((ROOT / "docs").glob("*.md"))]
MAX_README_LINES = 250

# Shapes of a sentence that reports benchmark runs one by one rather than a current figure.
RUN_NARRATION = [
    # "in the last 71 runs", "over the last 22 runs"
    re.compile(r"\b(?:in|over|of) the last \d+ (?:runs|pairs|missions|sessions)\b", re.I),
    # "in 54 of those 71", "in 10 of the 12 quiet ones", "both held in 21 of 28 runs"
    re.compile(r"\bin \d+ of (?:those |these |the )?\d+\b", re.I),
    # "medians of 0.909, 0.898, 0.926 and 0.897": four figures or more, one per run
    re.compile(r"(?:\b\d+\.\d+x?\b, ){3}"),
    # "in three runs before ... in four runs after", "thirteen runs on one day", "Nine more runs"
    re.compile(
        r"\b(?:\d+|two|three|four|five|six|seven|eight|nine|ten|eleven|twelve|thirteen)"
        r" (?:more )?runs (?:on|of|the same|before|after|from|with|interleaved)\b",
        re.I,
    ),
]

# A citation of a section in code or docs: docs/architecture.md, "Where the SLAM mission's CPU goes".
CITATION = re.compile(r"docs/([a-z0-9-]+\.md)[,;]?\s*\(?\"([^\"]+)\"")
CITING_SUFFIXES = {".py", ".md", ".yaml", ".yml", ".sh", ".toml"}
CITING_NAMES = {"Dockerfile", "Makefile"}
SKIPPED_FOLDERS = {".venv", ".git", "node_modules", "__pycache__", "out"}


def _flowing(text: str) -> str:
    """Text with line breaks, indentation and comment markers folded into single spaces, so a
    sentence or a citation wrapped over lines reads as one."""
    return re.sub(r"\s*\n\s*(?:#+\s|//\s|--\s)?\s*", " ", text)


def narrated_runs(text: str) -> list[str]:
    """The passages of `text` that list benchmark runs one by one."""
    flowing = _flowing(text)
    found = []
    for pattern in RUN_NARRATION:
        for match in pattern.finditer(flowing):
            start = max(0, match.start() - 60)
            found.append(f"...{flowing[start : match.end() + 20]}...")
    return found


def _headings(document: Path) -> set[str]:
    return {
        " ".join(line.lstrip("#").split())
        for line in document.read_text().splitlines()
        if line.startswith("#") and not line.startswith("#!")
    }


def _citing_files() -> list[Path]:
    files = []
    for path in ROOT.rglob("*"):
        if SKIPPED_FOLDERS.intersection(path.relative_to(ROOT).parts[:-1]):
            continue
        if path.is_file() and (path.suffix in CITING_SUFFIXES or path.name in CITING_NAMES):
            files.append(path)
    return files


def test_the_readme_stays_a_manual_of_at_most_250_lines() -> None:
    lines = len(README.read_text().splitlines())
    assert lines <= MAX_README_LINES, (
        f"README.md has {lines} lines (at most {MAX_README_LINES}): move depth to docs/"
    )


@pytest.mark.parametrize("document", DOCUMENTS, ids=lambda p: p.relative_to(ROOT).as_posix())
def test_no_document_narrates_benchmark_runs_one_by_one(document: Path) -> None:
    assert narrated_runs(document.read_text()) == [], (
        f"{document.relative_to(ROOT)} lists benchmark runs one by one; keep one current figure "
        "per measure (make bench prints them) and one paragraph per design choice"
    )


@pytest.mark.parametrize(
    "passage",
    [
        "at 0.85 to 1.08 of KISS-ICP's own pipeline,\n  by run, in the last 71 runs",
        "Both targets held in 54 of those 71, and in 27 of the 33 the benchmark called quiet",
        "four runs on one day gave medians of 0.909,\n0.898, 0.926 and 0.897, worst pairs 0.81 to 0.85",
        "36.0 to 37.5 s in three runs before, 28.7 to 33.2 s in four runs after",
        "Nine more runs with the same SLAM code on a later day",
    ],
)
def test_run_by_run_narration_of_the_old_manual_is_recognised(passage: str) -> None:
    assert narrated_runs(passage)


@pytest.mark.parametrize(
    "passage",
    [
        "the trajectory error against ground truth (300 of 300 scans, about 0.09 m ATE)",
        "`PodPerComponent` is ready in 0.85x the time of three DaemonSets (target 1.25x)",
        "the median of five ABBA pairs; single pairs spread by up to a fifth on a busy host",
        "trees are bounded before they are parsed (768 KiB, 50,000 elements, depth 128)",
    ],
)
def test_a_current_figure_is_not_taken_for_narration(passage: str) -> None:
    assert narrated_runs(passage) == []


def test_every_cited_docs_section_exists() -> None:
    missing = []
    for path in _citing_files():
        for document, section in CITATION.findall(_flowing(path.read_text(errors="replace"))):
            target = ROOT / "docs" / document
            if not target.is_file() or " ".join(section.split()) not in _headings(target):
                missing.append(f"{path.relative_to(ROOT)}: docs/{document}, {section!r}")
    assert missing == [], "cited sections that docs do not have:\n" + "\n".join(missing)
