"""Part 21 string literals: decoding and encoding (ISO 10303-21 6.4.3).

Decoding handles ``''``, ``\\\\``, ``\\S\\`` with ``\\P?\\`` code pages, ``\\X\\hh``,
``\\X2\\...\\X0\\`` (UCS-2/UTF-16), ``\\X4\\...\\X0\\`` (UCS-4) and drops line breaks
and the print control directives ``\\N\\`` / ``\\F\\``, which carry no content.
Encoding writes ASCII only: other characters become ``\\X2\\`` / ``\\X4\\`` runs, so
any reader of edition 2 or 3 can read the output.
"""

from __future__ import annotations

import re

from stepnc_graph.core.errors import StepncGraphError

_CODE_PAGES = {c: f"iso8859_{i}" for i, c in enumerate("ABCDEFGHI", start=1)}
#: ``\S\c`` shifts a character of the basic alphabet (space to '~') to the upper half
_ESCAPE = re.compile(r"\\(?:\\|S\\([ -~])|P([A-I])\\|X\\([0-9A-Fa-f]{2})|X2\\((?:[0-9A-Fa-f]{4})*)\\X0\\|"
                     r"X4\\((?:[0-9A-Fa-f]{8})*)\\X0\\|N\\|F\\)", re.S)


class StringDecodeError(StepncGraphError, ValueError):
    """A backslash that starts no valid escape; ``offset`` is within the literal's content."""

    def __init__(self, message: str, offset: int) -> None:
        super().__init__(message)
        self.offset = offset


def decode(content: str) -> str:
    """Decode the content between the quotes of a Part 21 string literal."""
    if "\n" in content or "\r" in content:
        content = content.replace("\r", "").replace("\n", "")
    if "\\" not in content:
        return content.replace("''", "'")
    out: list[str] = []
    page = "iso8859_1"
    pos = 0
    while True:
        k = content.find("\\", pos)
        if k < 0:
            out.append(content[pos:])
            break
        out.append(content[pos:k])
        m = _ESCAPE.match(content, k)
        if m is None:
            raise StringDecodeError(f"invalid escape {content[k:k + 4]!r} in string", k)
        text = m.group(0)
        if text == "\\\\":
            out.append("\\")
        elif m.group(1) is not None:
            out.append(bytes([ord(m.group(1)) + 128]).decode(page, errors="replace"))
        elif m.group(2) is not None:
            page = _CODE_PAGES[m.group(2)]
        elif m.group(3) is not None:
            out.append(chr(int(m.group(3), 16)))
        elif m.group(4) is not None:
            out.append(bytes.fromhex(m.group(4)).decode("utf-16-be", errors="surrogatepass")
                       .encode("utf-16", "surrogatepass").decode("utf-16", errors="replace"))
        elif m.group(5) is not None:
            out.append(bytes.fromhex(m.group(5)).decode("utf-32-be", errors="replace"))
        pos = m.end()
    return "".join(out).replace("''", "'")


def encode(value: str) -> str:
    """The Part 21 literal (with quotes) for ``value``; ASCII-only output."""
    out: list[str] = []
    run: list[str] = []

    def flush() -> None:
        if run:
            wide = any(ord(c) > 0xFFFF for c in run)
            if wide:
                out.append("\\X4\\" + "".join(f"{ord(c):08X}" for c in run) + "\\X0\\")
            else:
                out.append("\\X2\\" + "".join(f"{ord(c):04X}" for c in run) + "\\X0\\")
            run.clear()

    for ch in value:
        if " " <= ch <= "~":
            flush()
            out.append("''" if ch == "'" else "\\\\" if ch == "\\" else ch)
        else:
            run.append(ch)
    flush()
    return "'" + "".join(out) + "'"
