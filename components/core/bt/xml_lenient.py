"""Lenient XML reading as tinyxml2 (BT.CPP's parser) accepts it, keeping line numbers for errors.

The loader calls `parse_xml`. `sanitize` escapes only the three constructs real tree files contain
that strict XML rejects (raw `&` and `<` inside attribute values, `--` inside comments); a
well-formed document comes out byte-identical and no newline is added or removed, so the expat
line numbers still point into the original file.
"""

from __future__ import annotations

import re
from dataclasses import dataclass, field
from xml.parsers import expat

from coral_core.bt.errors import BTLoadError

_ENTITY = re.compile(r"&(#[0-9]+|#x[0-9a-fA-F]+|[A-Za-z_][\w.-]*);")


@dataclass
class XmlElement:
    tag: str
    attrib: dict[str, str]
    line: int
    children: list[XmlElement] = field(default_factory=list)
    text: str = ""

    def get(self, key: str, default: str | None = None) -> str | None:
        return self.attrib.get(key, default)


def _escape_attr_value(value: str) -> str:
    out: list[str] = []
    i = 0
    while i < len(value):
        ch = value[i]
        if ch == "<":
            out.append("&lt;")
        elif ch == "&":
            m = _ENTITY.match(value, i)
            if m:
                out.append(m.group(0))
                i = m.end()
                continue
            out.append("&amp;")
        else:
            out.append(ch)
        i += 1
    return "".join(out)


def sanitize(text: str) -> str:
    """Escapes raw `&`/`<` in attribute values and `--` in comments; everything else is kept."""
    out: list[str] = []
    i = 0
    n = len(text)
    while i < n:
        lt = text.find("<", i)
        if lt < 0:
            out.append(text[i:])
            break
        out.append(text[i:lt])
        if text.startswith("<!--", lt):
            end = text.find("-->", lt + 4)
            if end < 0:
                out.append(text[lt:])
                break
            body = text[lt + 4 : end]
            if "--" in body or body.endswith("-"):
                body = body.replace("-", " ")
            out.append("<!--" + body + "-->")
            i = end + 3
        elif text.startswith("<![CDATA[", lt):
            end = text.find("]]>", lt)
            end = n if end < 0 else end + 3
            out.append(text[lt:end])
            i = end
        elif text.startswith("<?", lt) or text.startswith("<!", lt):
            end = text.find(">", lt)
            end = n if end < 0 else end + 1
            out.append(text[lt:end])
            i = end
        else:
            i = _copy_tag(text, lt, out)
    return "".join(out)


def _copy_tag(text: str, start: int, out: list[str]) -> int:
    """Copies one start/end tag, escaping inside quoted attribute values; returns the next index."""
    i = start
    n = len(text)
    buf: list[str] = []
    while i < n:
        ch = text[i]
        if ch in "\"'":
            close = text.find(ch, i + 1)
            if close < 0:
                buf.append(text[i:])
                i = n
                break
            buf.append(ch + _escape_attr_value(text[i + 1 : close]) + ch)
            i = close + 1
            continue
        buf.append(ch)
        i += 1
        if ch == ">":
            break
    out.append("".join(buf))
    return i


def parse_xml(text: str, filename: str) -> XmlElement:
    """Parses (after sanitising) into XmlElement nodes; errors read "file:line: ..."."""
    clean = sanitize(text)
    parser = expat.ParserCreate()
    # expat hands text over a line at a time; merged, a run of newlines is one call, not one each.
    parser.buffer_text = True
    stack: list[XmlElement] = []
    # Text is gathered in pieces and joined once at the end tag: `text += data` copied the text so
    # far on every piece, quadratic in a run of newlines (11-15 s of CPU per pass on a tree inside
    # every limit; issue 47, item 9).
    pieces: list[list[str]] = []
    result: list[XmlElement] = []

    def start(tag: str, attrs: dict[str, str]) -> None:
        el = XmlElement(tag, dict(attrs), parser.CurrentLineNumber)
        if stack:
            stack[-1].children.append(el)
        else:
            result.append(el)
        stack.append(el)
        pieces.append([])

    def end(tag: str) -> None:
        stack.pop().text = "".join(pieces.pop())

    def chars(data: str) -> None:
        if pieces:
            pieces[-1].append(data)

    parser.StartElementHandler = start
    parser.EndElementHandler = end
    parser.CharacterDataHandler = chars
    try:
        parser.Parse(clean, True)
    except expat.ExpatError as err:
        raise BTLoadError(
            f"malformed XML: {expat.errors.messages.get(err.code, str(err))}", file=filename, line=err.lineno
        ) from None
    if not result:
        raise BTLoadError("empty XML document", file=filename, line=1)
    return result[0]
