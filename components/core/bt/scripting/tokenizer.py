"""Tokenizer of the scripting language (BT_SEMANTICS 1.6 lexical rules); called by the parser."""

from __future__ import annotations

import re
from dataclasses import dataclass

from coral_core.bt.anyvalue import text_to_double
from coral_core.bt.errors import ScriptError

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
_INT64_MAX = 2**63 - 1
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
                if m.group(1) or m.group(2):
                    try:
                        value = text_to_double(lit)
                    except ValueError:
                        # BT.CPP reads the literal with std::stod, which refuses a number that
                        # overflows or underflows a double, and the tree does not load.
                        raise ScriptError(
                            f"number '{lit}' is out of a double's range (stod) in [{text}]"
                        ) from None
                else:
                    value = int(lit)
            if isinstance(value, int) and value > _INT64_MAX:
                # BT.CPP's grammar reads integer literals as int64 (a minus sign is an operator).
                raise ScriptError(f"integer '{text[i:end]}' does not fit in 64 bits in [{text}]")
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
