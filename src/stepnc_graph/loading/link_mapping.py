"""A link mapping file read with positions (:mod:`.link`): CSV or JSON rows of ``its_id``, ``scope``,
``p21_id``, ``identifier`` and ``same_as``; a malformed file is a :class:`LinkError` with its line and
column, and a row that cannot be used is a :class:`Problem` naming its line, never a dropped row.
"""

from __future__ import annotations

import csv
import io
import json
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from stepnc_graph.loading.common import SourceError, check_iri


COLUMNS = ("its_id", "scope", "p21_id", "identifier", "same_as")


@dataclass(frozen=True)
class Row:
    """One mapping entry: which entity (``its_id`` [+ ``scope``] or ``p21_id``), and what to attach."""

    line: int  # CSV line, or 1-based entry of a JSON list
    its_id: str | None
    scope: str | None
    p21_id: int | None
    identifier: str | None
    same_as: str | None

    def key(self) -> str:
        """The row's entity as the user wrote it, for messages."""
        if self.p21_id is not None:
            return f"#{self.p21_id}"
        return f"its_id {self.its_id!r}" + (f" ({self.scope})" if self.scope else "")


@dataclass(frozen=True)
class Problem:
    """A mapping row that links nothing, and why. ``pointer``: a JSON mapping's entry (RFC 6901)."""

    line: int
    key: str
    message: str
    pointer: str | None = None

    def __str__(self) -> str:
        where = f"line {self.line}" if self.pointer is None else f"entry {self.line} ({self.pointer})"
        return f"{where}: {self.key}: {self.message}"

    def asdict(self) -> dict[str, Any]:
        out: dict[str, Any] = {"line": self.line, "key": self.key, "message": self.message}
        if self.pointer is not None:
            out["pointer"] = self.pointer
        return out


class LinkError(SourceError):
    """A mapping that cannot be applied (unreadable, or rows matching no single entity): nothing
    written. ``line``/``column`` (a CSV file) or ``pointer`` (a JSON file) say where, when known."""

    def __init__(self, mapping: str, message: str, problems: list[Problem] | None = None, *,
                 line: int | None = None, column: int | None = None, pointer: str | None = None) -> None:
        self.mapping, self.problems = mapping, problems or []
        self.line, self.column, self.pointer = line, column, pointer
        listed = "".join(f"\n  {p}" for p in self.problems)
        where = mapping + (f":{line}" if line is not None else "") + (f":{column}" if column is not None else "")
        if pointer is not None:
            where += f" at {pointer}" if pointer else " at the top level"
        super().__init__(f"{where}: {message}{listed}")
        self.message = message

    def asdict(self) -> dict[str, Any]:
        return {"type": "LinkError", "file": self.mapping, "line": self.line, "column": self.column,
                "pointer": self.pointer, "message": self.message, "problems": [p.asdict() for p in self.problems]}


# -- reading a mapping ------------------------------------------------------------------------------


def read_mapping(path: Path) -> tuple[list[Row], list[Problem]]:
    """The rows of a CSV (header row with the :data:`COLUMNS` it uses) or JSON (a list of objects
    with those keys, or ``{"links": [...]}``) mapping, and the rows that are malformed."""
    name = str(path)
    try:
        text = path.read_bytes().decode("utf-8-sig")
    except UnicodeDecodeError as e:
        raise LinkError(name, f"not UTF-8 (byte {e.start})") from None
    json_file = path.suffix.lower() == ".json"
    records = _json_records(text, name) if json_file else _csv_records(text, name)
    rows: list[Row] = []
    problems: list[Problem] = []
    for line, record, where in records:
        try:
            rows.append(_row(line, record))
        except ValueError as e:
            problems.append(Problem(line, _describe(record), str(e), where))
    return rows, problems


#: the longest CSV field the reader takes (the csv module's limit; a mapping field is an its_id,
#: a #id, a scope, an identifier or an IRI)
FIELD_LIMIT = csv.field_size_limit()


def _csv_records(text: str, name: str) -> list[tuple[int, dict[str, Any], str | None]]:
    reader = csv.DictReader(io.StringIO(text, newline=""))
    try:
        header = reader.fieldnames or []
    except csv.Error as e:
        raise _csv_error(e, text, 1, name) from None
    fields = [f.strip().lower() for f in header]
    unknown = [f for f in fields if f not in COLUMNS]
    if not fields or unknown or not {"its_id", "p21_id"} & set(fields):
        raise LinkError(name, f"the first line must name the columns: its_id and/or p21_id, optional scope, "
                              f"identifier and/or same_as{f' (unknown: {unknown})' if unknown else ''}")
    for i, column in enumerate(fields):
        if column in fields[:i]:
            first = fields.index(column)
            starts = _field_starts(text, 0)
            raise LinkError(name, f"the header names the column {column!r} twice (columns {first + 1} and {i + 1}); "
                                  "a value would be taken from one of them and the other lost: name each column "
                                  "once", line=1, column=_position(text, starts[i][0])[1] if i < len(starts) else None)
    reader.fieldnames = fields
    records: list[tuple[int, dict[str, Any], str | None]] = []
    start = reader.line_num + 1
    while True:
        try:
            record = next(reader)
        except StopIteration:
            break
        except csv.Error as e:
            raise _csv_error(e, text, start, name) from None
        if None in record:
            records.append((reader.line_num, {"": "more fields than the header names"}, None))
        elif any((v or "").strip() for v in record.values()):
            records.append((reader.line_num, dict(record), None))
        start = reader.line_num + 1
    return records


def _csv_error(e: csv.Error, text: str, line: int, name: str) -> LinkError:
    """A CSV record the reader cannot take, placed where its long field (or the record) starts."""
    offset = _line_offset(text, line)
    long = [(start, n) for start, n in _field_starts(text, offset) if n > FIELD_LIMIT]
    if long:
        at_line, column = _position(text, long[0][0])
        index = _field_starts(text, offset).index(long[0])
        return LinkError(name, f"a field of more than {FIELD_LIMIT:,} characters (field {index + 1}"
                               f"{_column_name(text, index)}); a mapping field is an its_id, #id, scope, identifier "
                               "or IRI", line=at_line, column=column)
    return LinkError(name, f"not CSV that can be read ({e})", line=line)


def _column_name(text: str, index: int) -> str:
    header = next(csv.reader(io.StringIO(text.split("\n", 1)[0])), [])
    return f", {header[index].strip().lower()!r}" if index < len(header) else ""


def _line_offset(text: str, line: int) -> int:
    """Where 1-based ``line`` starts in ``text``."""
    offset = 0
    for _ in range(line - 1):
        found = text.find("\n", offset)
        if found < 0:
            return len(text)
        offset = found + 1
    return offset


def _position(text: str, offset: int) -> tuple[int, int]:
    """The 1-based line and column of ``offset``."""
    return text.count("\n", 0, offset) + 1, offset - (text.rfind("\n", 0, offset) + 1) + 1


def _field_starts(text: str, offset: int) -> list[tuple[int, int]]:
    """The fields of the CSV record at ``offset``: (where each starts, its length), as the csv
    module reads them (quotes, doubled quotes, line breaks inside quotes); stops early at a field
    longer than :data:`FIELD_LIMIT`."""
    fields: list[tuple[int, int]] = []
    start, length, quoted, i = offset, 0, False, offset
    while i < len(text):
        c = text[i]
        if quoted:
            if c == '"' and text[i + 1:i + 2] == '"':
                length, i = length + 1, i + 2
                continue
            if c == '"':
                quoted = False
            else:
                length += 1
        elif c == '"':
            quoted = True
        elif c == ",":
            fields.append((start, length))
            start, length = i + 1, 0
        elif c in "\r\n":
            break
        else:
            length += 1
        if length > FIELD_LIMIT:
            break
        i += 1
    fields.append((start, length))
    return fields


class _Twice(dict[str, Any]):
    """A JSON object that gave ``key`` twice (JSON keeps the last; a mapping refuses it)."""

    key = ""


def _json_object(pairs: list[tuple[str, Any]]) -> dict[str, Any]:
    out = dict(pairs)
    if len(out) == len(pairs):
        return out
    seen: set[str] = set()
    twice = _Twice(out)
    twice.key = next(k for k, _ in pairs if k in seen or seen.add(k))  # type: ignore[func-returns-value]
    return twice


class _LongNumber:
    """A JSON integer too long to be an instance number (Python reads at most 4,300 digits): the
    row check refuses it, showing it shortened."""

    __slots__ = ("text",)

    def __init__(self, text: str) -> None:
        self.text = text

    def __repr__(self) -> str:
        return f"{self.text[:20]}... ({len(self.text):,} digits)"


def _json_integer(text: str) -> int | _LongNumber:
    return int(text) if len(text) <= 20 else _LongNumber(text)


def _json_records(text: str, name: str) -> list[tuple[int, dict[str, Any], str | None]]:
    try:
        data = json.loads(text, object_pairs_hook=_json_object, parse_int=_json_integer)
    except json.JSONDecodeError as e:
        raise LinkError(name, f"not JSON: {e.msg}", line=e.lineno, column=e.colno) from None
    except RecursionError:
        raise LinkError(name, "not JSON that can be read: arrays and objects nested too deeply (a mapping is "
                              "a list of objects)") from None
    prefix = ""
    if isinstance(data, dict):
        if isinstance(data, _Twice):
            raise LinkError(name, f"the object gives the key {data.key!r} twice; JSON keeps only one of them",
                            pointer="")
        data, prefix = data.get("links"), "/links"
    if not isinstance(data, list):
        raise LinkError(name, 'a JSON mapping is a list of objects, or {"links": [...]}')
    records: list[tuple[int, dict[str, Any], str | None]] = []
    for i, entry in enumerate(data):
        where = f"{prefix}/{i}"
        if isinstance(entry, _Twice):
            entry = {"": f"gives the key {entry.key!r} twice; JSON keeps only one of them, so the other would be "
                         "lost", **entry}
        elif not isinstance(entry, dict):
            entry = {"": "not an object"}
        records.append((i + 1, entry, where))
    return records


def _describe(record: dict[str, Any]) -> str:
    return ", ".join(f"{k}={v!r}" for k, v in record.items() if k and v not in (None, "")) or "(row)"


def _row(line: int, record: dict[str, Any]) -> Row:
    """A :class:`Row`, or ValueError saying what is wrong with the record."""
    if "" in record:
        raise ValueError(str(record[""]))
    unknown = sorted(set(record) - set(COLUMNS))
    if unknown:
        raise ValueError(f"unknown keys {unknown}; use {', '.join(COLUMNS)}")

    def text(key: str) -> str | None:
        value = record.get(key)
        if value is None or (isinstance(value, str) and not value.strip()):
            return None
        if key == "p21_id" and isinstance(value, int) and not isinstance(value, bool):
            return str(value)
        if key == "p21_id" and isinstance(value, _LongNumber):
            raise ValueError(f"p21_id must be an instance number such as 30 or #30, not {value!r}")
        if not isinstance(value, str):
            raise ValueError(f"{key} must be a string, not {value!r}")
        return value.strip() if key != "its_id" else value

    its_id, scope, p21_id, identifier, same_as = (text(k) for k in COLUMNS)
    if (its_id is None) == (p21_id is None):
        raise ValueError("give either its_id or p21_id")
    number = None
    if p21_id is not None:
        digits = p21_id.lstrip("#")
        if not (digits.isascii() and digits.isdigit()) or len(digits) > 20:
            shown = p21_id if len(p21_id) <= 40 else f"{p21_id[:30]}... ({len(p21_id):,} characters)"
            raise ValueError(f"p21_id must be an instance number such as 30 or #30, not {shown!r}")
        number = int(digits)
    if identifier is None and same_as is None:
        raise ValueError("nothing to attach: give identifier and/or same_as")
    if same_as is not None:
        try:
            check_iri(same_as, "same_as")
        except SourceError as e:
            raise ValueError(str(e)) from None
    return Row(line, its_id, scope.lower() if scope else None, number, identifier, same_as)
