"""Damaged Part 21 inputs and the checks every load of one must pass (:mod:`.fuzz`).

A damaged Part 21 input (:func:`mutate`) is a real program truncated, with bytes
flipped, a span deleted or repeated, a piece of another program spliced in or a
troublesome token inserted; or the program joined onto one line, or with several
instances on each line, then damaged (an instance broken: its ``#id``'s digits, a
quote, a parenthesis, a ``;`` removed, a bad escape); or with an integer, real,
``#id`` or reference made huge. :func:`check` reads it strictly and loads it
leniently and asserts what the loader promises, each time by a measure of its own
rather than by the reader's counts: no exception but the documented ones; every
byte of the DATA sections is an instance's text, kept text (unreadable, a later
definition, text that names no instance), a section keyword or a comment; the
graph holds exactly the instances read, and every reference to an instance it
does not hold is reported; the export parses strictly and holds every kept text.
"""

from __future__ import annotations

import random
import re
import tempfile
from dataclasses import dataclass
from pathlib import Path
from typing import Any


#: tokens that break readers in interesting ways
NASTY = [b"'", b"/*", b"*/", b"(", b")", b";", b"#", b"#999999=", b"=", b"$", b"\x00", b"\xff\xfe", b"\xd8",
         b"\xe2\x80\x99", b"ENDSEC;", b"DATA;", b"END-ISO-10303-21;", b"\\X2\\", b"\\", b".", b",", b"\n",
         b"(" * 300, b"\x1b[31m", b"\r", b"\"0F\"", b"@7", b"<x>", b"\\S\\\xc3\xa9", b"9" * 5000,
         b"#" + b"8" * 4400 + b"=", b"(*", b"*)", b"';#5=X('"]

#: damage of the bytes of a program
BASIC = ["truncate", "flip", "delete", "repeat", "splice", "insert", "flips"]
#: damage of its lines and numbers (issue 26: one-line files, several instances a line, huge numbers)
LAYOUT = ["one-line", "multi-instance", "huge-number"]
KINDS = BASIC + LAYOUT


_INSTANCE_LINE = re.compile(rb"\r?\n(?=[ \t]*#[0-9]+[ \t]*=)")
_INSTANCE_START = re.compile(rb"#[0-9]+[ \t]*=")
_NUMBER = re.compile(rb"#[0-9]+|(?<![A-Za-z0-9_.#])[+-]?[0-9]+(?:\.[0-9]*(?:[Ee][+-]?[0-9]+)?)?")


def mutate(rng: random.Random, data: bytes, others: list[bytes], kinds: list[str] | None = None) -> tuple[str, bytes]:
    """One damaged variant of ``data`` and the name of the damage (one of ``kinds``, default all)."""
    kind = rng.choice(kinds or KINDS)
    if kind == "one-line":
        return kind, _damage(rng, re.sub(rb"\r?\n", rng.choice([b" ", b""]), data), others)
    if kind == "multi-instance":
        joined = rng.uniform(0.3, 1.0)
        return kind, _damage(rng, _INSTANCE_LINE.sub(lambda m: b"" if rng.random() < joined else m.group(), data),
                             others)
    if kind == "huge-number":
        out = _huge_numbers(rng, data)
        return kind, re.sub(rb"\r?\n", b" ", out) if rng.random() < 0.3 else out
    return kind, basic_damage(rng, kind, data, others)


def basic_damage(rng: random.Random, kind: str, data: bytes, others: list[bytes]) -> bytes:
    n = len(data)
    at = rng.randrange(n) if n else 0
    if kind == "truncate":
        return data[:at]
    if kind == "flip":
        return data[:at] + bytes([rng.randrange(256)]) + data[at + 1:]
    if kind == "flips":
        out = bytearray(data)
        for _ in range(rng.randint(2, 20)):
            out[rng.randrange(n)] = rng.randrange(256)
        return bytes(out)
    if kind == "delete":
        return data[:at] + data[at + rng.randint(1, 200):]
    if kind == "repeat":
        span = data[at:at + rng.randint(1, 400)]
        return data[:at] + span + span + data[at + len(span):]
    if kind == "splice":
        other = rng.choice(others) if others else data
        start = rng.randrange(len(other)) if other else 0
        return data[:at] + other[start:start + rng.randint(1, 2000)] + data[at:]
    return data[:at] + rng.choice(NASTY) + data[at:]


def _damage(rng: random.Random, data: bytes, others: list[bytes]) -> bytes:
    """A relaid program damaged once more: most often one instance broken, else any basic damage;
    one in ten left whole (it must load as the original did)."""
    roll = rng.random()
    if roll < 0.1:
        return data
    if roll < 0.7:
        for _ in range(rng.randint(1, 3)):
            data = _break_instance(rng, data)
        return data
    return basic_damage(rng, rng.choice(BASIC), data, others)


def _break_instance(rng: random.Random, data: bytes) -> bytes:
    """Break one instance the way hands and tools do: lose its ``#id``'s digits, a quote, a
    parenthesis or its ``;``; gain a bad escape, an empty parameter or a ``;`` in a string."""
    starts = [m.start() for m in _INSTANCE_START.finditer(data)]
    if not starts:
        return data
    k = rng.randrange(len(starts))
    start = starts[k]
    end = starts[k + 1] if k + 1 < len(starts) else len(data)
    body = data[start:end]
    how = rng.choice(["id-digits", "quote", "open-paren", "close-paren", "semicolon", "escape", "empty-param",
                      "string-boundary"])
    if how == "id-digits":
        body = re.sub(rb"^#[0-9]+", b"#", body)
    elif how == "escape":
        body = body.replace(b"'", b"'\\Q", 1) if b"'" in body else body + b"\\Q"
    elif how == "empty-param":
        body = body.replace(b"(", b"(,", 1)
    elif how == "string-boundary":
        body = body.replace(b"'", b"';#77=X('", 1) if b"'" in body else body
    else:
        char = {"quote": b"'", "open-paren": b"(", "close-paren": b")", "semicolon": b";"}[how]
        places = [i for i in range(len(body)) if body[i:i + 1] == char]
        if places:
            i = rng.choice(places)
            body = body[:i] + body[i + 1:]
    return data[:start] + body + data[end:]


def _huge_numbers(rng: random.Random, data: bytes) -> bytes:
    """``data`` with one to three numbers (integer, real, ``#id`` or reference) made huge."""
    found = list(_NUMBER.finditer(data))
    if not found:
        return data
    picked = sorted(rng.sample(found, min(len(found), rng.randint(1, 3))), key=lambda m: m.start(), reverse=True)
    for m in picked:
        data = data[:m.start()] + _huge(rng, m.group()) + data[m.end():]
    return data


def _huge(rng: random.Random, token: bytes) -> bytes:
    digits = b"9" * rng.choice([4300, 4301, 5000, 20_000, 200_000])
    if token.startswith(b"#"):
        return b"#" + digits
    return rng.choice([digits, b"-" + digits, digits + b".5", b"1." + digits, b"1.E" + digits, b"1.E-" + digits,
                       b"0." + digits + b"E+99999"])


# -- the Part 21 check ------------------------------------------------------------------------------


@dataclass(frozen=True)
class Outcome:
    """What one damaged input did: ``ok`` (lenient load), ``rejected`` (a documented error in
    both modes, e.g. a broken header) or ``failed`` (a broken promise: ``detail`` says which)."""

    status: str
    detail: str = ""


#: what may lie between the kept texts of the DATA sections, once comments are taken out:
#: white space, section keywords (in any case: the reader reads names so), DATA openers (with their parameters, strings and one level of
#: nested lists; a ';' the reader reported missing), the end marker, signatures, EXPRESS remarks
_STRING = r"'(?:[^']|'')*'"
_STRUCTURE = re.compile(rf"(?:\s+|(?i:ENDSEC)\s*;?|(?i:DATA)\s*(?:\((?:{_STRING}|[^()']|\((?:{_STRING}|[^()'])*\))*\))?\s*;?|"
                        r"END-ISO-10303-21\s*;?|SIGNATURE\b.*?\bENDSEC\s*;|\(\*.*?\*\))*+", re.S)  # possessive
_COMMENT = re.compile(r"/\*.*?\*/", re.S)


def check(data: bytes, name: str = "fuzz.stp") -> Outcome:
    """Read ``data`` strictly, load it leniently and check the promises (see the module docstring)."""
    import stepnc_graph as sg
    from stepnc_graph.part21 import Part21SyntaxError, read_text
    from stepnc_graph.part21.source import decode_source

    text, _ = decode_source(data, name)
    try:
        for _ in read_text(text, name).instances():
            pass
    except Part21SyntaxError:
        pass
    with tempfile.TemporaryDirectory() as d:
        path = Path(d) / name
        path.write_bytes(data)
        store = sg.open_store(memory=True)
        try:
            [r] = sg.load(store, [path], lenient=True)
        except Part21SyntaxError as e:
            if e.recoverable:
                return Outcome("failed", f"lenient load raised a recoverable error: {e.message}")
            return Outcome("rejected")
    reader = read_text(text, name, lenient=True)
    instances = list(reader.instances())
    for problem in (_unkept_text(reader, instances), _graph_problem(store, r, reader),
                    _unreported_reference(store, r), _export_problem(store, r)):
        if problem:
            return Outcome("failed", problem)
    return Outcome("ok")


def _unkept_text(reader: Any, instances: list[Any]) -> str:
    """Text of the DATA sections (and after them) that is neither an instance's nor kept nor
    structure: data lost without a word."""
    text = reader.text
    spans = sorted([(i.start, i.end) for i in instances] + [(s, e) for _, s, e, _ in reader.duplicate_texts]
                   + [(t.start, t.end) for t in reader.unreadable_texts])
    pos = reader.body_start
    for start, end in [*spans, (len(text), len(text))]:
        if start > pos:
            gap = _COMMENT.sub(" ", text[pos:start])
            m = _STRUCTURE.fullmatch(gap)
            if m is None:
                rest = _STRUCTURE.match(gap)
                lost = gap[rest.end() if rest else 0:][:60]
                return f"text neither loaded nor kept nor reported at offset {pos}: {lost!r}"
        pos = max(pos, end)
    return ""


def _graph_problem(store: Any, r: Any, reader: Any) -> str:
    """The graph holds exactly the instances read, the later definitions and the kept texts."""
    from stepnc_graph.core.naming import P21_NS

    ids = {int(row[0].value) for row in store.query(
        f"SELECT ?id WHERE {{ GRAPH <{r.graph}> {{ ?s <{P21_NS}id> ?id }} }}")}
    kept = len(list(store.query(f"SELECT ?d WHERE {{ GRAPH <{r.graph}> {{ ?s <{P21_NS}duplicateDefinition> ?d }} }}")))
    texts = len(list(store.query(f"SELECT ?d WHERE {{ GRAPH <{r.graph}> {{ ?s <{P21_NS}unreadableText> ?d }} }}")))
    if not (len(ids) == r.instances and r.defined == len(ids) + kept):
        return (f"invariant: {r.defined} definitions read, {len(ids)} instances in the graph ({r.instances} "
                f"counted), {kept} later definitions kept as text")
    if ids != reader.ids:
        return f"the graph's instances differ from those read: {sorted(ids ^ reader.ids)[:5]}"
    if texts != len(reader.unreadable_texts):
        return f"{len(reader.unreadable_texts)} texts naming no instance, {texts} kept in the graph"
    return ""


def _unreported_reference(store: Any, r: Any) -> str:
    """Every reference to an instance the graph does not hold is reported (P21-UNRESOLVED-REF)."""
    from stepnc_graph.core.naming import P21_NS, instance_prefix

    prefix = instance_prefix(r.graph)
    rows = store.query(f"""SELECT DISTINCT ?o WHERE {{ GRAPH <{r.graph}> {{ ?s ?p ?o
        FILTER(isIRI(?o) && STRSTARTS(STR(?o), "{prefix}i"))
        FILTER NOT EXISTS {{ ?o <{P21_NS}id> ?i }} FILTER NOT EXISTS {{ ?o <{P21_NS}externalReference> ?x }} }} }}""")
    reported = {int(m.group(1)) for d in r.diagnostics if d.code == "P21-UNRESOLVED-REF"
                for m in [re.search(r"#([0-9]+)", d.message)] if m}
    for row in rows:
        tail = row[0].value[len(prefix) + 1:]
        if tail.isdigit() and int(tail) not in reported:
            return f"a reference to #{tail}, which the graph does not hold, is not reported"
    return ""


def _export_problem(store: Any, r: Any) -> str:
    """The export parses strictly and holds every kept text (verbatim, or in a comment)."""
    import stepnc_graph as sg
    from stepnc_graph.mapping.writer import comment
    from stepnc_graph.core.naming import P21_NS
    from stepnc_graph.part21 import Part21SyntaxError, read_text

    exported = sg.export(store, "p21", r.graph).decode("utf-8")
    try:
        for _ in read_text(exported, "exported.stp").instances():
            pass
    except Part21SyntaxError as e:
        return f"the export does not parse strictly: {e.message} (line {e.line})"
    rows = store.query(f"""SELECT ?t ?fixed WHERE {{ GRAPH <{r.graph}> {{ ?s <{P21_NS}rawText> ?t
        OPTIONAL {{ ?s <{P21_NS}repairedText> ?fixed }} }} }}""")
    for row in rows:
        raw = row[1].value if row[1] is not None else row[0].value
        if raw not in exported and comment(raw)[3:-3] not in exported:
            return f"kept text missing from the export: {raw[:60]!r}"
    return ""
