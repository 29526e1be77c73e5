"""Reading a Part 21 file's bytes and decoding them to text, byte by byte.

ISO 10303-21 edition 2 strings are ASCII with ``\\X\\``-style escapes, and
edition 3 allows UTF-8; files written by legacy tools also carry ISO 8859-1
(or Windows) bytes, usually inside strings. Decoding the whole file as
Latin-1 because one byte is not UTF-8 would silently turn every correctly
encoded character elsewhere into mojibake. So the text is decoded as UTF-8
where it is UTF-8, each byte that is not is read as ISO 8859-1 and reported
with its line and column, and no correctly encoded character changes.
"""

from __future__ import annotations

import re
import stat
import sys
from pathlib import Path
from typing import BinaryIO

from stepnc_graph.part21.diagnostics import Diagnostic, Part21SyntaxError

#: undecodable bytes reported one by one; beyond this, one summary diagnostic
MAX_ENCODING_DIAGNOSTICS = 100
#: how much of a file is read before it must look like Part 21 (so /dev/zero,
#: a binary or an endless stream fails at once instead of filling memory)
HEAD_BYTES = 1 << 16
_BOM = b"\xef\xbb\xbf"
_ESCAPED = re.compile("[\udc80-\udcff]")
_LATIN1 = {0xDC00 + b: chr(b) for b in range(0x80, 0x100)}
_MAGIC_HEAD = re.compile(rb"(?:[ \t\r\n\f\v]+|/\*.*?\*/)*ISO-10303-21", re.S)


def _not_part21(name: str, head: bytes) -> Part21SyntaxError:
    first = head.split(b"\n", 1)[0][:200].decode("latin-1")
    return Part21SyntaxError("not a Part 21 file: expected 'ISO-10303-21;' at the start", name, 1, 1, first,
                             None, ("ISO-10303-21;",))


def read_stream(stream: BinaryIO, name: str) -> bytes:
    """All bytes of ``stream``, after checking that its start is a Part 21 header.

    Raises :class:`Part21SyntaxError` (line 1) when the first bytes are not
    ``ISO-10303-21``, before reading the rest.
    """
    head = stream.read(HEAD_BYTES)
    body = head[len(_BOM):] if head.startswith(_BOM) else head
    if not _MAGIC_HEAD.match(body) and not (len(head) < HEAD_BYTES and _MAGIC_HEAD.match(body + b" ")):
        raise _not_part21(name, body)
    rest = stream.read()
    return head + rest if rest else head


def read_source(path: str | Path) -> bytes:
    """The bytes of the file at ``path``; only regular files, FIFOs and standard streams.

    A device such as ``/dev/zero`` or a directory is refused with ``OSError``
    naming the path (it would never end, or is not a file).
    """
    p = Path(path)
    mode = p.stat().st_mode
    if not (stat.S_ISREG(mode) or stat.S_ISFIFO(mode)):
        raise IsADirectoryError(f"{p}: a directory, not a Part 21 file") if stat.S_ISDIR(mode) else \
            OSError(f"{p}: not a regular file (a device or socket); give a Part 21 file")
    with open(p, "rb") as fh:
        return read_stream(fh, str(p))


def decode_source(raw: bytes, filename: str) -> tuple[str, list[Diagnostic]]:
    """The text of a Part 21 file and one P21-ENCODING warning per byte that is not UTF-8.

    A UTF-8 byte-order mark is dropped (it is not content).
    """
    if raw.startswith(_BOM):
        raw = raw[len(_BOM):]
    text = raw.decode("utf-8", errors="surrogateescape")
    if not _ESCAPED.search(text):
        return text, []
    diagnostics: list[Diagnostic] = []
    line, line_start, counted, total = 1, 0, 0, 0
    for m in _ESCAPED.finditer(text):
        total += 1
        if total > MAX_ENCODING_DIAGNOSTICS:
            continue
        k = m.start()
        newlines = text.count("\n", counted, k)
        if newlines:
            line += newlines
            line_start = text.rfind("\n", counted, k) + 1
        counted = k
        byte = ord(m.group()) - 0xDC00
        diagnostics.append(Diagnostic.make(
            "P21-ENCODING", filename, line, k - line_start + 1, None,
            f"byte 0x{byte:02X} is not UTF-8; read as ISO 8859-1 {chr(byte)!r}"))
    if total > MAX_ENCODING_DIAGNOSTICS:
        last = diagnostics[-1]
        diagnostics.append(Diagnostic.make(
            "P21-ENCODING", filename, last.line, last.column, None,
            f"{total - MAX_ENCODING_DIAGNOSTICS} more bytes that are not UTF-8 read as ISO 8859-1 "
            f"({total} in all; the file is probably ISO 8859-1)"))
    return text.translate(_LATIN1), diagnostics


def read_text_source(path: str | Path) -> tuple[str, bytes, list[Diagnostic]]:
    """Read and decode ``path``: (text, raw bytes, encoding diagnostics)."""
    raw = read_source(path)
    text, diagnostics = decode_source(raw, str(path))
    return text, raw, diagnostics


def read_stdin(stream: BinaryIO | None = None, name: str = "<stdin>") -> bytes:
    """Standard input (or ``stream``) as bytes, checked like a file."""
    return read_stream(stream if stream is not None else sys.stdin.buffer, name)
