"""Damaged Part 21 inputs and the checks every load of one must pass.

Used by ``bench/fuzz_load.py`` (hundreds of thousands of inputs, in worker
processes with a memory limit) and by the test suite (a few hundred). A damaged
input is a real program truncated, with bytes flipped, a span deleted or
repeated, a piece of another program spliced in, or a troublesome token
inserted. :func:`check` loads it strictly and leniently and asserts what
issue 7 promises: no exception but the documented ones, the lenient invariant
(every instance definition the reader saw is in the graph, or is a later
definition of an #id reported as such), and an export that parses strictly.
"""

from __future__ import annotations

import random
import tempfile
from dataclasses import dataclass
from pathlib import Path

#: tokens that break readers in interesting ways
NASTY = [b"'", b"/*", b"*/", b"(", b")", b";", b"#", b"#999999=", b"=", b"$", b"\x00", b"\xff\xfe", b"\xd8",
         b"\xe2\x80\x99", b"ENDSEC;", b"DATA;", b"END-ISO-10303-21;", b"\\X2\\", b"\\", b".", b",", b"\n",
         b"(" * 300, b"\x1b[31m", b"\r", b"\"0F\"", b"@7", b"<x>"]


def mutate(rng: random.Random, data: bytes, others: list[bytes]) -> tuple[str, bytes]:
    """One damaged variant of ``data`` and the name of the damage."""
    kind = rng.choice(["truncate", "flip", "delete", "repeat", "splice", "insert", "flips"])
    n = len(data)
    at = rng.randrange(n) if n else 0
    if kind == "truncate":
        return kind, data[:at]
    if kind == "flip":
        return kind, data[:at] + bytes([rng.randrange(256)]) + data[at + 1:]
    if kind == "flips":
        out = bytearray(data)
        for _ in range(rng.randint(2, 20)):
            out[rng.randrange(n)] = rng.randrange(256)
        return kind, bytes(out)
    if kind == "delete":
        return kind, data[:at] + data[at + rng.randint(1, 200):]
    if kind == "repeat":
        span = data[at:at + rng.randint(1, 400)]
        return kind, data[:at] + span + span + data[at + len(span):]
    if kind == "splice":
        other = rng.choice(others) if others else data
        start = rng.randrange(len(other)) if other else 0
        return kind, data[:at] + other[start:start + rng.randint(1, 2000)] + data[at:]
    return kind, data[:at] + rng.choice(NASTY) + data[at:]


@dataclass(frozen=True)
class Outcome:
    """What one damaged input did: ``ok`` (lenient load), ``rejected`` (a documented error in
    both modes, e.g. a broken header) or ``failed`` (a broken promise: ``detail`` says which)."""

    status: str
    detail: str = ""


def check(data: bytes, name: str = "fuzz.stp") -> Outcome:
    """Read ``data`` strictly, load it leniently and check the promises (see the module docstring)."""
    import stepnc_graph as sg
    from stepnc_graph.naming import P21_NS
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
    ids = {int(row[0].value) for row in store.query(
        f"SELECT ?id WHERE {{ GRAPH <{r.graph}> {{ ?s <{P21_NS}id> ?id }} }}")}
    kept = len(list(store.query(f"SELECT ?d WHERE {{ GRAPH <{r.graph}> {{ ?s <{P21_NS}duplicateDefinition> ?d }} }}")))
    if not (len(ids) == r.instances and r.defined == len(ids) + kept):
        return Outcome("failed", f"invariant: {r.defined} definitions read, {len(ids)} instances in the graph "
                                 f"({r.instances} counted), {kept} later definitions kept as text")
    exported = sg.export(store, "p21", r.graph).decode("utf-8")
    try:
        for _ in read_text(exported, "exported.stp").instances():
            pass
    except Part21SyntaxError as e:
        return Outcome("failed", f"the export does not parse strictly: {e.message} (line {e.line})")
    return Outcome("ok")
