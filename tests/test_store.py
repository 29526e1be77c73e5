"""The on-disk store: generations, readers, unload and replace by rebuild or batched deletes."""

from __future__ import annotations

import json
import sys
from pathlib import Path

import pyoxigraph as ox
import pytest

import stepnc_graph as sg
from stepnc_graph import store as store_module
from stepnc_graph.naming import VOCABULARY_GRAPH
from stepnc_graph.store import GraphStore, StoreBusy, StoreError

from conftest import ROOT

EXAMPLE = ROOT / "examples" / "shaft_two_setups.stp"
G = "https://w3id.org/stepnc-graph/data/shaft_two_setups.stp"


def disk_bytes(path: Path) -> int:
    """Bytes on disk under ``path``, each hard-linked file counted once."""
    seen = {}
    for f in path.rglob("*"):
        if f.is_file():
            st = f.stat()
            seen[(st.st_dev, st.st_ino)] = st.st_blocks * 512
    return sum(seen.values())


def quads(s: GraphStore) -> list[str]:
    return sorted(str(q) for q in s.quads())


def copies(store: GraphStore, n: int) -> list[str]:
    graphs = [f"urn:copy:{k}" for k in range(n)]
    for g in graphs:
        sg.load(store, [EXAMPLE], base_iri=g)
    return graphs


def generated(tmp_path: Path, instances: int) -> Path:
    sys.path.insert(0, str(ROOT / "bench"))
    from generate import write  # type: ignore[import-not-found]

    path = tmp_path / "big.stp"
    write(instances, path)
    return path


def test_unloading_the_only_program_rebuilds_and_gives_the_space_back(tmp_path: Path) -> None:
    big = generated(tmp_path, 20_000)
    with sg.open_store(tmp_path / "s") as s:
        [r] = sg.load(s, [big])
        loaded = disk_bytes(tmp_path / "s")
        assert sg.unload(s, r.graph) and s.last_removal == "rebuild"
    assert disk_bytes(tmp_path / "s") < loaded / 5
    with sg.open_store(tmp_path / "s", readonly=True) as r2:
        assert r2.graphs() == [] and r2.count() == r2.count(VOCABULARY_GRAPH) > 0  # the vocabulary stays


def test_unloading_beside_other_programs_deletes_in_batches(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    """Deletes by IRI subjects, then the blank nodes' quads predicate by predicate, in several
    batches each: the graph and its derived layer go, a blank node no IRI leads to too, and
    nothing of the other programs."""
    monkeypatch.setattr(store_module, "DELETE_SUBJECTS", 7)  # several batches on a small graph
    monkeypatch.setattr(store_module, "DELETE_BATCH", 5)
    with sg.open_store(tmp_path / "s") as s:
        graphs = copies(s, 4)
        counts = {g: s.count(g) for g in graphs}
        lone = ox.NamedNode(graphs[1])
        for k in range(5):
            s.oxigraph.add(ox.Quad(ox.BlankNode(), ox.NamedNode("urn:p"), ox.Literal(str(k)), lone))
        for g in graphs[:2]:
            blank = sum(isinstance(q.subject, ox.BlankNode) for name in (g, g + "/derived") for q in s.quads(name))
            assert blank > 2 * store_module.DELETE_BATCH
            assert sg.unload(s, g) and s.last_removal == "delete" and s.blank_quads_deleted == blank
            assert not s.has_graph(g) and s.count(g) == s.count(g + "/derived") == 0
            assert {h: s.count(h) for h in graphs[2:]} == {h: counts[h] for h in graphs[2:]}
    with sg.open_store(tmp_path / "s", readonly=True) as r:
        assert r.graphs() == sorted(graphs[2:])


def test_unloading_beside_other_programs_gives_the_space_back(tmp_path: Path) -> None:
    """Deleted quads hold their space until RocksDB compacts them, and the deletes' write-ahead
    log until the database is opened again: an unload compacts and reopens, so the whole store
    directory shrinks, not only the published generation readers open."""
    big = generated(tmp_path, 5_000)
    with sg.open_store(tmp_path / "s") as s:
        graphs = [f"urn:copy:{k}" for k in range(3)]
        for g in graphs:
            sg.load(s, [big], base_iri=g)
        loaded = disk_bytes(tmp_path / "s")
        assert sg.unload(s, graphs[0]) and s.last_removal == "delete"
        assert disk_bytes(tmp_path / "s") < loaded * 0.85
        assert s.count(graphs[1]) == s.count(graphs[2]) > 0  # the reopened database is the one in use


def test_compact_gives_back_what_an_unload_beside_others_leaves(tmp_path: Path) -> None:
    """An unload's compaction keeps the strings only the removed program used (here its instance
    IRIs); `compact` rebuilds the database from its graphs: smaller on disk, the same quads, blank
    nodes included, and a reader that opened before still reads its generation."""
    big = generated(tmp_path, 5_000)
    with sg.open_store(tmp_path / "s") as s:
        graphs = [f"urn:copy:{k}" for k in range(3)]
        for g in graphs:
            sg.load(s, [big], base_iri=g)
        assert sg.unload(s, graphs[0]) and s.last_removal == "delete"
        before = quads(s)
        unloaded = s.disk_bytes()
        seen: list[tuple[int, int]] = []
        result = sg.compact(s, lambda done, total: seen.append((done, total)))
        assert quads(s) == before and result.quads == len(before) == s.count()
        assert result.before == unloaded and max(result.after, s.disk_bytes()) < unloaded * 0.9
        assert seen and seen[-1] == (len(before), len(before))
        with sg.open_store(tmp_path / "s", readonly=True) as reader:
            sg.compact(s)
            assert quads(reader) == before  # the generation it opened is still there
    with sg.open_store(tmp_path / "s", readonly=True) as r:
        assert quads(r) == before and r.graphs() == sorted(graphs[1:])


def test_a_failed_compact_leaves_the_store_as_it_was(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setattr(store_module, "REBUILD_BATCH", 100)  # several calls a graph
    with sg.open_store(tmp_path / "s") as s:
        copies(s, 2)
        before = quads(s)

        def failing(done: int, total: int) -> None:
            if done > 300:
                raise RuntimeError("disk full (injected)")

        with pytest.raises(RuntimeError, match="injected"):
            sg.compact(s, failing)
        assert quads(s) == before
        assert sg.compact(s).quads == len(before) and quads(s) == before  # and it can be compacted after
    with sg.open_store(tmp_path / "s", readonly=True) as r:
        assert quads(r) == before


def test_compact_needs_a_store_directory() -> None:
    """A SPARQL endpoint manages its own storage (nothing is sent to it); an in-memory store has no
    disk space to give back."""
    from stepnc_graph.remote import Endpoint, RemoteStore

    with pytest.raises(StoreError, match="store directory"):
        sg.compact(RemoteStore(Endpoint.from_options("http://127.0.0.1:9")))
    with sg.open_store(memory=True) as s:
        copies(s, 1)
        assert sg.compact(s).quads == s.count() > 0 and sg.compact(s).after == 0


@pytest.mark.parametrize("others", [0, 3], ids=["rebuild", "delete"])
def test_a_failed_replace_leaves_the_store_as_it_was(tmp_path: Path, monkeypatch: pytest.MonkeyPatch,
                                                     others: int) -> None:
    program = generated(tmp_path, 3_000) if others == 0 else EXAMPLE  # most of the store, or a small part
    with sg.open_store(tmp_path / "s") as s:
        copies(s, others)
        sg.load(s, [program])
        before = quads(s)

        def failing(*args: object) -> None:
            raise RuntimeError("disk full (injected)")

        monkeypatch.setattr(GraphStore, "_bulk_load", failing)
        with pytest.raises(RuntimeError, match="injected"):
            sg.load(s, [program])
        assert s.last_removal == ("rebuild" if others == 0 else "delete")
        assert quads(s) == before
    with sg.open_store(tmp_path / "s", readonly=True) as r:
        assert quads(r) == before


def test_an_interrupt_that_keeps_the_database_alive_is_still_the_error_raised(tmp_path: Path,
                                                                           monkeypatch: pytest.MonkeyPatch) -> None:
    """Ctrl-C during a load: its traceback holds the open database (a frame's local), so the rollback
    cannot reopen it in this process. The interrupt must still be what the caller sees (the CLI exits
    130), the store on disk must be as before, and this object must refuse further use clearly."""
    with sg.open_store(tmp_path / "s") as s:
        sg.load(s, [EXAMPLE])
        before = quads(s)

        def interrupted(self: GraphStore, *args: object) -> None:
            database = self._db  # noqa: F841 -- held by this frame while the interrupt propagates
            raise KeyboardInterrupt

        monkeypatch.setattr(GraphStore, "_bulk_load", interrupted)
        with pytest.raises(KeyboardInterrupt):
            sg.load(s, [EXAMPLE])
        with pytest.raises(StoreError, match="open it again"):
            s.count()
    with sg.open_store(tmp_path / "s", readonly=True) as r:
        assert quads(r) == before
    with sg.open_store(tmp_path / "s") as w:  # the next writer recovers work/
        assert quads(w) == before


def test_readers_keep_their_generation_while_a_writer_publishes(tmp_path: Path) -> None:
    with sg.open_store(tmp_path / "s") as w:
        sg.load(w, [EXAMPLE])
        reader = sg.open_store(tmp_path / "s", readonly=True)
        seen = reader.generation
        assert sg.unload(w, G)
        assert reader.has_graph(G) and reader.count(G) > 0  # its generation is still whole
        assert w.generation != seen and (tmp_path / "s" / str(seen)).is_dir()  # not collected while read
        reader.close()
        sg.load(w, [EXAMPLE])  # the next publication collects it
        assert not (tmp_path / "s" / str(seen)).exists()


def test_one_writer_at_a_time_in_one_process_too(tmp_path: Path) -> None:
    with sg.open_store(tmp_path / "s"):
        with pytest.raises(StoreBusy, match=r"being written by pid \d+"):
            sg.open_store(tmp_path / "s")
        with pytest.raises(StoreBusy):
            sg.open_store(tmp_path / "s", wait=0.3)
        assert sg.open_store(tmp_path / "s", readonly=True).graphs() == []


def test_a_read_only_store_refuses_writes(tmp_path: Path) -> None:
    sg.open_store(tmp_path / "s").close()
    with sg.open_store(tmp_path / "s", readonly=True) as r:
        with pytest.raises(StoreError, match="read-only"):
            sg.load(r, [EXAMPLE])


def test_a_format_1_store_is_migrated(tmp_path: Path) -> None:
    """A store written before generations (oxigraph/ + marker format 1) opens and keeps its data."""
    import pyoxigraph as ox

    old = tmp_path / "old"
    old.mkdir()
    (old / "stepnc-graph-store.json").write_text(json.dumps({"format": 1}) + "\n")
    db = ox.Store(str(old / "oxigraph"))
    db.add(ox.Quad(ox.NamedNode("urn:s"), ox.NamedNode("urn:p"), ox.Literal("kept"), ox.NamedNode("urn:g")))
    db.flush()
    del db
    with sg.open_store(old, readonly=True) as r:  # a reader asks the writer's lock to migrate
        assert r.graphs() == ["urn:g"]
    assert not (old / "oxigraph").exists() and json.loads((old / "stepnc-graph-store.json").read_text())[
        "format"] == store_module.FORMAT_VERSION


def test_the_compact_command(tmp_path: Path) -> None:
    from click.testing import CliRunner

    from stepnc_graph.cli import main

    store = str(tmp_path / "s")
    with sg.open_store(store) as s:
        graphs = copies(s, 2)
    runner = CliRunner()
    assert runner.invoke(main, ["unload", "--store", store, graphs[0]]).exit_code == 0
    res = runner.invoke(main, ["compact", "--store", store, "--format", "json"])
    assert res.exit_code == 0, res.output
    doc = json.loads(res.output)
    assert doc["store"] == str(Path(store).resolve()) and doc["before"] > 0 and doc["after"] > 0
    with sg.open_store(store, readonly=True) as r:
        assert doc["quads"] == r.count() and r.graphs() == graphs[1:]
    text = runner.invoke(main, ["compact", "--store", store])
    assert text.exit_code == 0 and text.output.startswith("compacted ") and f"({doc['quads']:,} quads)" in text.output
