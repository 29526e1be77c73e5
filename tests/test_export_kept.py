"""An export read from the text the graph's load kept (issue 32: an export should cost well under
its load) is the export read from the store, byte for byte, in every format; and the kept text is
not read where it no longer describes the graph."""

from __future__ import annotations

import random
import zlib
from collections.abc import Iterator
from pathlib import Path

import pyoxigraph as ox
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

import stepnc_graph as sg
from stepnc_graph.core.errors import StepncGraphError
from stepnc_graph.core.naming import STEPNC_NS
from stepnc_graph.store import GraphStore
from stepnc_graph.store.reading import OxigraphReads
from stepnc_graph.testing.fuzz_part21 import mutate
from stepnc_graph.testing.synth import random_program

from conftest import FIXTURES, ROOT

PROGRAMS = sorted([*(ROOT / "examples").glob("*.stp"), *(FIXTURES / "p21").glob("*.stp"),
                   *(FIXTURES / "editions").glob("*.stp"), *(FIXTURES / "validate").glob("*.stp")])


def exports(store: GraphStore, graph: str | None, monkeypatch: pytest.MonkeyPatch,
            fmt: str = "p21") -> tuple[bytes, bytes, int]:
    """The export as the exporter makes it, the one read from the store (the kept text refused),
    and how many times the kept text was used for the first."""
    used = []
    real = OxigraphReads.kept_text

    def spy(self: OxigraphReads, name: str, path: Path, store_labels: bool = True) -> bool:
        found = real(self, name, path, store_labels)
        used.append(found)
        return found

    with monkeypatch.context() as m:
        m.setattr(OxigraphReads, "kept_text", spy)
        exported = sg.export(store, fmt, graph)
    with monkeypatch.context() as m:
        m.setattr(OxigraphReads, "kept_text", lambda *args, **kwargs: False)
        dumped = sg.export(store, fmt, graph)
    return exported, dumped, sum(used)


@pytest.mark.parametrize("path", PROGRAMS, ids=lambda p: f"{p.parent.name}/{p.stem}")
def test_the_export_from_the_kept_text_is_the_export_from_the_store(path: Path, tmp_path: Path,
                                                                     monkeypatch: pytest.MonkeyPatch) -> None:
    with sg.open_store(tmp_path / "s") as store:
        [r] = sg.load(store, [path], lenient=True)
        exported, part21, used = exports(store, r.graph, monkeypatch)
        assert used == 1  # the kept text was read, and it gave the same bytes
        assert exported == part21
        for fmt in ("nt", "ttl", "nq", "jsonld"):  # the graph alone: the load's blank node labels
            exported, dumped, used = exports(store, r.graph, monkeypatch, fmt)
            assert used == 1 and exported == dumped, fmt
        exported, dumped, used = exports(store, f"{r.graph}/derived", monkeypatch, "nt")
        assert used == 1 and exported == dumped
        if path.name == "shaft_two_setups.stp":  # the program beside its links
            sg.link(store, ROOT / "examples" / "shaft_plm_links.csv", r.graph)
        for fmt in ("nq", "trig"):  # the whole store: the store's labels
            exported, dumped, used = exports(store, None, monkeypatch, fmt)
            assert used >= 1 and exported == dumped, fmt  # the program, and its link graph
    with sg.open_store(tmp_path / "s", readonly=True) as reader:  # another process's reader
        assert exports(reader, r.graph, monkeypatch)[::2] == (part21, 1)


@pytest.mark.parametrize("path", PROGRAMS, ids=lambda p: f"{p.parent.name}/{p.stem}")
def test_the_kept_text_is_the_stores_text(path: Path, tmp_path: Path) -> None:
    """Every line without a blank node is the line Oxigraph writes for it (literals in the form it
    writes them back), so the exports above need not convert any."""
    with sg.open_store(tmp_path / "s") as store:
        [r] = sg.load(store, [path], lenient=True)
        for graph in (r.graph, f"{r.graph}/derived"):
            store.kept_text(graph, tmp_path / "kept.nt", store_labels=False)
            kept = {line for line in (tmp_path / "kept.nt").read_bytes().splitlines() if b"_:" not in line}
            dumped = {line for line in store.dump(ox.RdfFormat.N_TRIPLES, graph).splitlines() if b"_:" not in line}
            assert kept == dumped and len(kept) > 10


def damaged(seed: int) -> Iterator[bytes]:
    """Damaged copies of the shipped example, as the loader fuzz harness makes them."""
    rng = random.Random(seed)
    data = (ROOT / "examples" / "shaft_two_setups.stp").read_bytes()
    for _ in range(3):
        yield mutate(rng, data, [])[1]


@settings(max_examples=8, deadline=None)
@given(st.integers(min_value=0, max_value=10**6))
def test_random_and_damaged_programs_export_alike_both_ways(seed: int) -> None:
    """Random schema-valid programs and damaged real ones (raw instances, repaired text, huge
    numbers): the same bytes either way, whenever the program loads."""
    import tempfile

    with tempfile.TemporaryDirectory() as d, pytest.MonkeyPatch.context() as monkeypatch:
        for k, data in enumerate([random_program(seed).encode("utf-8"), *damaged(seed)]):
            path = Path(d) / f"p{k}.stp"
            path.write_bytes(data)
            with sg.open_store(Path(d) / f"s{k}") as store:
                try:
                    [r] = sg.load(store, [path], lenient=True)
                except StepncGraphError:  # refused with a positioned error: nothing to export
                    continue
                for fmt in ("p21", "nt"):
                    exported, dumped, used = exports(store, r.graph, monkeypatch, fmt)
                    assert used == 1 and exported == dumped, fmt


EXAMPLE = ROOT / "examples" / "shaft_two_setups.stp"
CHANGE = """DELETE {{ GRAPH <{g}> {{ ?s ?p ?o }} }} INSERT {{ GRAPH <{g}> {{ ?s ?p "CHANGED" }} }} WHERE {{
  {{ SELECT ?s ?p ?o WHERE {{ GRAPH <{g}> {{ ?s ?p ?o FILTER(isLiteral(?o) && datatype(?o) = <http://www.w3.org/2001/XMLSchema#string>
                                                    && STRSTARTS(STR(?p), "{ns}") && ?o != "CHANGED") }} }} LIMIT 1 }} }}"""


def test_a_graph_changed_outside_a_load_is_read_from_the_store(tmp_path: Path,
                                                                monkeypatch: pytest.MonkeyPatch) -> None:
    """A SPARQL update, or a write through the handed-out database, leaves the kept text behind:
    the export reads the store (and shows the change)."""
    with sg.open_store(tmp_path / "s") as store:
        [r] = sg.load(store, [EXAMPLE])
        before = sg.export(store, "p21", r.graph)
        store.update(f"DELETE WHERE {{ GRAPH <{r.graph}> {{ <{r.graph}/i1> ?p ?o }} }}")
        exported, dumped, used = exports(store, r.graph, monkeypatch)
        assert used == 0 and exported == dumped != before
    with sg.open_store(tmp_path / "t") as store:
        [r] = sg.load(store, [EXAMPLE])
        # a value changed in place: the graph's triple count is the same
        store.oxigraph.update(CHANGE.format(g=r.graph, ns=STEPNC_NS))
        exported, dumped, used = exports(store, r.graph, monkeypatch)
        assert used == 0 and exported == dumped and b"'CHANGED'" in exported


@pytest.mark.parametrize("damage", ["cut short", "a line added", "bytes flipped"])
def test_a_damaged_kept_text_is_not_read(damage: str, tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    with sg.open_store(tmp_path / "s") as store:
        [r] = sg.load(store, [EXAMPLE])
        expected = sg.export(store, "p21", r.graph)
        kept = store._kept.path(store._kept.valid(store.generation)[r.graph])
        data = kept.read_bytes()
        if damage == "cut short":
            data = data[: len(data) // 2]
        elif damage == "a line added":
            data = zlib.compress(zlib.decompress(data) + b'<urn:x> <urn:p> "not in the store" .\n', 1)
        else:
            middle = len(data) // 2
            data = data[:middle] + bytes(b ^ 0x55 for b in data[middle:middle + 8]) + data[middle + 8:]
        kept.write_bytes(data)
        exported, dumped, used = exports(store, r.graph, monkeypatch)
        assert used == 0 and exported == dumped == expected


def test_an_in_memory_store_has_no_kept_text(tmp_path: Path) -> None:
    store = sg.open_store(memory=True)
    [r] = sg.load(store, [EXAMPLE])
    assert not store.kept_text(r.graph, tmp_path / "g.nt") and EXAMPLE.read_bytes()


def test_a_text_kept_before_the_literals_took_the_stores_form_is_not_read(tmp_path: Path,
                                                                           monkeypatch: pytest.MonkeyPatch) -> None:
    """A store loaded by an earlier version kept texts of form 1 (the load time written ``+00:00``,
    which the store gives back as ``Z``): its index names no form, and they are not read."""
    import json

    with sg.open_store(tmp_path / "s") as store:
        [r] = sg.load(store, [EXAMPLE])
    index = tmp_path / "s" / "kept" / "index.json"
    entries = json.loads(index.read_text())
    for entry in entries["graphs"].values():
        del entry["form"]
    index.write_text(json.dumps(entries))
    with sg.open_store(tmp_path / "s", readonly=True) as store:
        for fmt in ("p21", "nt"):
            exported, dumped, used = exports(store, r.graph, monkeypatch, fmt)
            assert used == 0 and exported == dumped, fmt
