"""The text each graph's last load wrote, kept beside the database for the next replacement."""

from __future__ import annotations

import io
import json
import zlib
from pathlib import Path

import pyoxigraph as ox
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

import stepnc_graph as sg
from stepnc_graph.store import kept as kept_module
from stepnc_graph.store.kept import KeptTexts, read_without_blank_nodes
from stepnc_graph.store.kept_graph import graph_from_kept
from stepnc_graph.core.naming import derived_graph_iri
from stepnc_graph.store import GraphStore
from stepnc_graph.store.difference import has_blank
from stepnc_graph.store.removal import Removal

from test_store import EXAMPLE, G, assert_as_a_fresh_load, copies

D = derived_graph_iri(G)


def index(store_dir: Path) -> dict:  # type: ignore[type-arg]
    return json.loads((store_dir / "kept" / "index.json").read_text())


def kept_lines(store_dir: Path, graph: str) -> list[bytes]:
    entry = index(store_dir)["graphs"][graph]
    return zlib.decompress((store_dir / "kept" / entry["file"]).read_bytes()).splitlines(keepends=True)


def same_count_edit(tmp_path: Path) -> Path:
    """The example with one value changed: as many quads as before, one of them different."""
    text = EXAMPLE.read_text()
    assert "TENSILE STRENGTH 650 N/MM2" in text
    path = tmp_path / "shaft_rev_c.stp"
    path.write_text(text.replace("TENSILE STRENGTH 650 N/MM2", "TENSILE STRENGTH 700 N/MM2", 1))
    return path


def test_a_load_keeps_its_text_and_the_index_follows_the_published_generations(tmp_path: Path) -> None:
    store_dir = tmp_path / "s"
    with sg.open_store(store_dir) as s:
        others = copies(s, 2)
        sg.load(s, [EXAMPLE])
        first = index(store_dir)
        assert first["generation"] == s.generation
        assert set(first["graphs"]) == {G, D, *others, *map(derived_graph_iri, others)}
        for graph in (G, D):  # every line of the graph, as the load wrote it (its own blank labels)
            lines = kept_lines(store_dir, graph)
            assert len(lines) == first["graphs"][graph]["lines"] == s.count(graph)
        assert sg.unload(s, others[0])
        after = index(store_dir)
        assert after["generation"] == s.generation and others[0] not in after["graphs"]
        assert after["graphs"][G] == first["graphs"][G]  # carried over: the unload left it alone
        s.compact()
        assert index(store_dir)["graphs"] == after["graphs"]
        sg.load(s, [EXAMPLE], replace=True)
        assert s.last_difference["old version kept"] == 2  # the program graph and its derived layer
        replaced = index(store_dir)
        assert replaced["graphs"][G]["file"] != first["graphs"][G]["file"]
        assert replaced["graphs"][others[1]] == first["graphs"][others[1]]
    named = {e["file"] for e in replaced["graphs"].values()}
    assert {p.name for p in (store_dir / "kept").iterdir()} == named | {"index.json"}  # superseded ones went


def as_stored(text: bytes) -> list[bytes]:
    """N-Triples lines as Oxigraph stores them (a literal by its value: ``+00:00`` is ``Z``),
    blank node labels kept."""
    store = ox.Store()
    store.bulk_extend(ox.Quad(t.subject, t.predicate, t.object, ox.DefaultGraph())
                      for t in ox.parse(text, ox.RdfFormat.N_TRIPLES))
    return sorted(store.dump(format=ox.RdfFormat.N_TRIPLES, from_graph=ox.DefaultGraph()).splitlines())


def test_the_old_version_read_from_the_kept_text_is_the_dump_of_the_store(tmp_path: Path) -> None:
    """Lines without blank node from the kept text, the others from the store: as a dump."""
    with sg.open_store(tmp_path / "s") as s:
        copies(s, 2)
        sg.load(s, [EXAMPLE])
        kept = s._kept.valid(s.generation)
        for graph in (G, D):
            path = tmp_path / "old.nt"
            assert graph_from_kept(s._disk, graph, s._kept.path(kept[graph]), kept[graph].lines, path, store_labels=True)
            dumped = s.dump(ox.RdfFormat.N_TRIPLES, graph)
            assert as_stored(path.read_bytes()) == sorted(dumped.splitlines())


def replace_and_check(s: GraphStore, path: Path, kept: int) -> None:
    sg.load(s, [path], base_iri=G, replace=True)
    assert s.last_removal.startswith("difference")  # type: ignore[union-attr]
    assert s.last_difference["old version kept"] == kept
    assert_as_a_fresh_load(s, G, path)


@pytest.mark.parametrize("write", ["SPARQL update", "database handed out"])
def test_a_write_outside_a_load_is_never_undone_by_a_stale_kept_text(tmp_path: Path, write: str) -> None:
    """A line changed in place keeps the graph's count: compared from the kept text, the same
    file would look unchanged and the changed line would stay. The replacement must dump."""
    with sg.open_store(tmp_path / "s") as s:
        copies(s, 2)
        sg.load(s, [EXAMPLE])
        change = (f"DELETE {{ GRAPH <{G}> {{ <{G}/i12> <https://w3id.org/stepnc-graph/p21#line> ?n }} }} "
                  f"INSERT {{ GRAPH <{G}> {{ <{G}/i12> <https://w3id.org/stepnc-graph/p21#line> 999 }} }} "
                  f"WHERE {{ GRAPH <{G}> {{ <{G}/i12> <https://w3id.org/stepnc-graph/p21#line> ?n }} }}")
        before = s.count(G)
        if write == "SPARQL update":
            s.update(change)
        else:
            s.oxigraph.update(change)
        assert s.count(G) == before
        replace_and_check(s, EXAMPLE, kept=0)
        replace_and_check(s, EXAMPLE, kept=2)  # kept again by the replacement


def test_a_kept_text_of_another_generation_is_not_used(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    """A writer killed after publishing a replacement but before writing the index leaves the
    index of the generation before: its text of the graph is the version before, and the store
    holds the same number of quads. Used, a re-load of that version would change nothing."""
    with sg.open_store(tmp_path / "s") as s:
        copies(s, 2)
        sg.load(s, [EXAMPLE])
        with monkeypatch.context() as m:
            m.setattr(KeptTexts, "publish", lambda *args, **kwargs: None)  # killed before the index
            replace_and_check(s, same_count_edit(tmp_path), kept=2)
        assert index(tmp_path / "s")["generation"] != s.generation
        replace_and_check(s, EXAMPLE, kept=0)


@pytest.mark.parametrize("damage", ["cut short", "a flipped byte", "a line more", "no index"])
def test_a_damaged_kept_text_makes_the_replacement_dump(tmp_path: Path, damage: str) -> None:
    store_dir = tmp_path / "s"
    with sg.open_store(store_dir) as s:
        copies(s, 2)
        sg.load(s, [EXAMPLE])
        entry = index(store_dir)["graphs"][G]
        path = store_dir / "kept" / entry["file"]
        data = path.read_bytes()
        if damage == "cut short":
            data = data[: len(data) // 2]
        elif damage == "a flipped byte":
            data = data[:100] + bytes([data[100] ^ 0x10]) + data[101:]
        elif damage == "a line more":  # a consistent file and index, one line more than the store
            text = zlib.decompress(data) + b'<urn:x> <urn:p> "not in the store" .\n'
            data = zlib.compress(text, 1)
            whole = index(store_dir)
            whole["graphs"][G].update(lines=entry["lines"] + 1, size=len(data))
            (store_dir / "kept" / "index.json").write_text(json.dumps(whole))
        if damage == "no index":
            (store_dir / "kept" / "index.json").unlink()
        else:
            path.write_bytes(data)
            if damage != "a line more":  # the size matches the index: only the contents tell
                whole = index(store_dir)
                whole["graphs"][G]["size"] = len(data)
                (store_dir / "kept" / "index.json").write_text(json.dumps(whole))
        replace_and_check(s, same_count_edit(tmp_path), kept=0 if damage == "no index" else 1)


def test_the_kept_line_counts_stand_for_counting_the_store(tmp_path: Path) -> None:
    """How to remove a graph, and when to compact, are chosen by quad counts; the kept texts
    give them without Oxigraph's scan, the graphs without one (the vocabulary) are counted."""
    with sg.open_store(tmp_path / "s") as s:
        others = copies(s, 2)
        sg.load(s, [EXAMPLE])
        s.add_ntriples("urn:unkept", "<urn:s> <urn:p> <urn:o> .\n")  # a graph no load wrote
        kept = s._kept.valid(s.generation)
        assert set(kept) == {G, D, *others, *map(derived_graph_iri, others)}
        removal = Removal(s)
        assert removal._quads_about(None, kept) == s.count() == removal._quads_about(None, {})
        assert removal._quads_about([G, D], kept) == s.count(G) + s.count(D)


def test_a_killed_writer_s_texts_are_collected_by_the_next_writer(tmp_path: Path) -> None:
    """A writer killed during a load leaves the text it was keeping; the index never named it."""
    store_dir = tmp_path / "s"
    with sg.open_store(store_dir) as s:
        sg.load(s, [EXAMPLE])
    stray = store_dir / "kept" / "0123456789abcdef.nt.z"
    stray.write_bytes(b"half a text")
    with sg.open_store(store_dir, readonly=True):
        assert stray.exists()  # readers change nothing
    with sg.open_store(store_dir, readonly=False):  # the next writer
        assert not stray.exists()
        assert {p.name for p in (store_dir / "kept").iterdir()} == {
            e["file"] for e in index(store_dir)["graphs"].values()} | {"index.json"}


def test_a_failed_load_keeps_nothing(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    store_dir = tmp_path / "s"
    with sg.open_store(store_dir) as s:
        copies(s, 1)
        before = index(store_dir)

        def fail(*args: object) -> None:
            raise RuntimeError("injected")

        monkeypatch.setattr(GraphStore, "_bulk_load", fail)
        with pytest.raises(RuntimeError):
            sg.load(s, [EXAMPLE])
    assert index(store_dir) == before
    assert {p.name for p in (store_dir / "kept").iterdir()} == {e["file"] for e in before["graphs"].values()} | {
        "index.json"}


def test_a_text_that_cannot_be_kept_fails_no_load(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    """Keeping is worth a faster replacement, never a failed load (a full disk, say)."""
    def full(*args: object) -> None:
        raise OSError(28, "No space left on device (injected)")

    monkeypatch.setattr(kept_module.zlib, "compressobj", full)
    with sg.open_store(tmp_path / "s") as s:
        copies(s, 1)
        [r] = sg.load(s, [EXAMPLE])
        assert s.count(G) > 0 and not r.diagnostics
        assert index(tmp_path / "s")["graphs"] == {}
        assert [p.name for p in (tmp_path / "s" / "kept").iterdir()] == ["index.json"]
        monkeypatch.undo()
        replace_and_check(s, EXAMPLE, kept=0)


def test_an_in_memory_store_keeps_nothing(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.chdir(tmp_path)  # where a default store would go
    with sg.open_store(memory=True) as s:
        sg.load(s, [EXAMPLE])
        sg.load(s, [EXAMPLE], replace=True)
        assert s.count(G) > 0
    assert not any(tmp_path.iterdir())


LINES = st.sampled_from([
    b"<urn:s> <urn:p> <urn:o> .\n",
    b"_:b1 <http://www.w3.org/1999/02/22-rdf-syntax-ns#first> <urn:o> .\n",
    b"_:b1 <http://www.w3.org/1999/02/22-rdf-syntax-ns#rest> _:b2 .\n",
    b"<urn:s> <urn:list> _:b3 .\n",
    b'<urn:s> <urn:label> "a _:b4 ." .\n',  # a literal that looks like a blank node
    b'<urn:s> <urn:label> "_:b5" .\n',
    b'<urn:s> <urn:p2> "x"^^<http://www.w3.org/2001/XMLSchema#string> .\n',
])


@settings(max_examples=200, deadline=None)
@given(st.lists(LINES, max_size=60), st.integers(min_value=40, max_value=400))
def test_reading_a_kept_text_separates_the_lines_with_a_blank_node(tmp_path_factory: pytest.TempPathFactory,
                                                                   lines: list[bytes], block: int) -> None:
    """Whatever the lines and the blocks they are read in: the lines without blank node come out
    in order, the others are counted and their predicates named (oracle: the store's own test)."""
    path = tmp_path_factory.mktemp("kept") / "t.nt.z"
    path.write_bytes(zlib.compress(b"".join(lines), 1))
    out = io.BytesIO()
    with pytest.MonkeyPatch.context() as m:
        m.setattr(kept_module, "BLOCK", block)
        found = read_without_blank_nodes(path, out)
    blank = [line for line in lines if has_blank(line)]
    assert out.getvalue() == b"".join(line for line in lines if not has_blank(line))
    assert (found.lines, found.blank) == (len(lines) - len(blank), len(blank))
    assert found.predicates == {line.split(b" ")[1] for line in blank}
