"""Tokenizer of the scripting language (BT_SEMANTICS 1.6 lexical rules); called by the parser."""

from __future__ import annotations

import re
from dataclasses import dataclass

from coral.bt.errors import ScriptError

_OPERATORS = [
    ":=",
    "+=",
    "-=",
    "*=",
    "/=",
    "==",
    "!=",
    "<=",
    ">=",
    "&&",
    "||",
    "..",
    "=",
    "<",
    ">",
    "!",
    "~",
    "&",
    "|",
    "^",
    "+",
    "-",
    "*",
    "/",
    "?",
    ":",
    "(",
    ")",
    ";",
]
_IDENT = re.compile(r"[A-Za-z_@][A-Za-z0-9_]*")
_HEX = re.compile(r"0[xX][0-9a-fA-F]+")
_NUMBER = re.compile(r"[0-9]+(\.[0-9]+)?([eE][+-]?[0-9]+)?")


@dataclass(frozen=True)
class Token:
    kind: str  # "num", "str", "id", "op", "end"
    value: object
    pos: int


def tokenize(text: str) -> list[Token]:
    tokens: list[Token] = []
    i = 0
    n = len(text)
    while i < n:
        ch = text[i]
        if ch.isspace():
            i += 1
            continue
        if ch == "'":
            close = text.find("'", i + 1)
            if close < 0:
                raise ScriptError(f"unterminated string at position {i} in [{text}]")
            tokens.append(Token("str", text[i + 1 : close], i))
            i = close + 1
            continue
        if ch.isdigit():
            m = _HEX.match(text, i)
            if m:
                value: object = int(m.group(0), 16)
                end = m.end()
            else:
                m = _NUMBER.match(text, i)
                assert m is not None
                end = m.end()
                lit = m.group(0)
                value = float(lit) if (m.group(1) or m.group(2)) else int(lit)
            if end < n and (text[end].isalnum() or text[end] in "_.@") and text[end : end + 2] != "..":
                raise ScriptError(f"malformed number '{text[i : end + 1]}' in [{text}]")
            tokens.append(Token("num", value, i))
            i = end
            continue
        m = _IDENT.match(text, i)
        if m:
            word = m.group(0)
            if word == "true":
                tokens.append(Token("num", 1.0, i))
            elif word == "false":
                tokens.append(Token("num", 0.0, i))
            else:
                tokens.append(Token("id", word, i))
            i = m.end()
            continue
        for op in _OPERATORS:
            if text.startswith(op, i):
                tokens.append(Token("op", op, i))
                i += len(op)
                break
        else:
            raise ScriptError(f"unexpected character '{ch}' at position {i} in [{text}]")
    tokens.append(Token("end", None, n))
    return tokens
