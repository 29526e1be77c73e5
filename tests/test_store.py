"""The on-disk store: generations, readers, unload and replace by rebuild or batched deletes."""

from __future__ import annotations

import errno
import itertools
import json
import os
import re
import shutil
import subprocess
import sys
import threading
import time
from collections.abc import Callable, Iterable, Iterator
from contextlib import contextmanager
from pathlib import Path

import pyoxigraph as ox
import pytest

import stepnc_graph as sg
from stepnc_graph import store as store_module
from stepnc_graph.store import batches, difference, kept_graph, tuning
from stepnc_graph.store.removal import Removal
from stepnc_graph.store.replacement import Replacement
from stepnc_graph.store.handoff import Handoff
from stepnc_graph.core.naming import VOCABULARY_GRAPH
from stepnc_graph.store import GraphStore, StoreBusy, StoreError
from stepnc_graph.core.naming import listed_graphs

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
        assert listed_graphs(r2) == [] and r2.count() == r2.count(VOCABULARY_GRAPH) > 0  # the vocabulary stays


def test_unloading_beside_other_programs_deletes_in_batches(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    """Deletes predicate by predicate, in several batches each: the graph and its derived layer
    go (a blank node no IRI leads to too), nothing of the other programs, and the batches did
    the work (not the final removal of the graph's name)."""
    monkeypatch.setattr(tuning, "DELETE_BATCH", 5)  # several batches on a small graph
    monkeypatch.setattr(tuning, "FLUSH_DELETES", 12)  # memory tables flushed between batches
    deleted: list[int] = []
    running: list[int] = []  # deletes under way, as the threads saw them
    flushes: list[int] = []  # deletes under way at each flush
    real, real_flush = Removal._delete_predicate, Removal.flush

    def counted(self: Removal, item: tuple[ox.NamedNode, str, int]) -> None:
        node, predicate, n = item
        running.append(1)
        before = sum(1 for _ in self.store.oxigraph.quads_for_pattern(None, ox.NamedNode(predicate[1:-1]), None, node))
        real(self, item)
        deleted.append(before - sum(1 for _ in self.store.oxigraph.quads_for_pattern(
            None, ox.NamedNode(predicate[1:-1]), None, node)))
        assert deleted[-1] == n
        running.append(-1)

    def flush(self: Removal) -> None:
        flushes.append(sum(running))
        real_flush(self)

    monkeypatch.setattr(Removal, "_delete_predicate", counted)
    monkeypatch.setattr(Removal, "flush", flush)
    with sg.open_store(tmp_path / "s") as s:
        graphs = copies(s, 4)
        counts = {g: s.count(g) for g in graphs}
        lone = ox.NamedNode(graphs[1])
        for k in range(5):
            s.oxigraph.add(ox.Quad(ox.BlankNode(), ox.NamedNode("urn:p"), ox.Literal(str(k)), lone))
        for g in graphs[:2]:
            held = s.count(g) + s.count(g + "/derived")
            assert max(sum(q.predicate == p for q in s.quads(g)) for p in {q.predicate for q in s.quads(g)}) \
                > 2 * tuning.DELETE_BATCH
            deleted.clear()
            assert sg.unload(s, g) and s.last_removal == "delete" and sum(deleted) == held
            assert len(flushes) >= held // 12 - 1 and not any(flushes)  # never beside a running delete
            flushes.clear()
            assert not s.has_graph(g) and s.count(g) == s.count(g + "/derived") == 0
            assert {h: s.count(h) for h in graphs[2:]} == {h: counts[h] for h in graphs[2:]}
    with sg.open_store(tmp_path / "s", readonly=True) as r:
        assert listed_graphs(r) == sorted(graphs[2:])


def test_unloading_beside_other_programs_gives_the_space_back(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    """Deleted quads hold their space until RocksDB compacts them, and the deletes' write-ahead
    log until the database is opened again: an unload that compacts (here asked to) also
    reopens, so the whole store directory shrinks, not only the published generation readers
    open (the deletes go in several rounds with flushes between them, as a large program's do)."""
    monkeypatch.setattr(tuning, "FLUSH_DELETES", 20_000)
    big = generated(tmp_path, 5_000)
    with sg.open_store(tmp_path / "s") as s:
        graphs = [f"urn:copy:{k}" for k in range(3)]
        for g in graphs:
            sg.load(s, [big], base_iri=g)
        loaded = disk_bytes(tmp_path / "s")
        assert sg.unload(s, graphs[0], compact=True) and s.last_removal == "delete" and s.compacted
        assert s.deleted_quads == 0
        assert disk_bytes(tmp_path / "s") < loaded * 0.85
        assert s.count(graphs[1]) == s.count(graphs[2]) > 0  # the reopened database is the one in use
        # the published generation is a checkpoint: it copied the log of the last round (8 MB here)
        logs = (tmp_path / "s" / (tmp_path / "s" / "CURRENT").read_text().strip()).glob("*.log")
        assert sum(f.stat().st_size for f in logs) < 64 << 10


def program_quads(s: GraphStore, graph: str) -> int:
    """The quads an unload of ``graph`` deletes: the program and its derived layer."""
    return s.count(graph) + s.count(graph + "/derived")


def test_unloads_compact_once_the_deleted_quads_reach_compact_at(tmp_path: Path,
                                                                 monkeypatch: pytest.MonkeyPatch) -> None:
    """A compaction rewrites the whole database, so unloads beside other programs compact only
    once the quads deleted since the last one reach COMPACT_AT of what the store holds (the
    bound is put between the first and the second unload here). The count outlives the
    process, readers see it, `compact` and a compacting unload reset it."""
    with sg.open_store(tmp_path / "s") as s:
        graphs = copies(s, 4)
        n, held = program_quads(s, graphs[0]), s.count()
        first, second = n / (held - n), 2 * n / (held - 2 * n)  # deleted / left after each unload
        monkeypatch.setattr(tuning, "COMPACT_AT", (first + second) / 2)
        assert sg.unload(s, graphs[0]) and s.last_removal == "delete" and not s.compacted
        assert s.deleted_quads == n
    with sg.open_store(tmp_path / "s", readonly=True) as r:
        assert r.deleted_quads == n
    with sg.open_store(tmp_path / "s") as s:
        assert s.deleted_quads == n
        assert sg.unload(s, graphs[1]) and s.last_removal == "delete" and s.compacted
        assert s.deleted_quads == 0
        assert sg.unload(s, graphs[2], compact=True) and s.compacted and s.deleted_quads == 0
        sg.load(s, [EXAMPLE], base_iri=graphs[0])
        assert sg.unload(s, graphs[0]) and not s.compacted and s.deleted_quads == n
        sg.compact(s)
        assert s.deleted_quads == 0


def test_a_failed_unload_keeps_the_count_of_deleted_quads(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setattr(tuning, "COMPACT_AT", 10.0)  # never reached here
    with sg.open_store(tmp_path / "s") as s:
        graphs = copies(s, 4)
        n = program_quads(s, graphs[0])
        assert sg.unload(s, graphs[0]) and s.deleted_quads == n

        def failing(self: Removal, item: tuple[ox.NamedNode, str, int]) -> None:
            raise RuntimeError("disk full (injected)")

        monkeypatch.setattr(Removal, "_delete_predicate", failing)
        with pytest.raises(RuntimeError, match="injected"):
            sg.unload(s, graphs[1])
        assert s.deleted_quads == n and s.has_graph(graphs[1])


def test_a_replacement_counts_the_quads_it_deleted(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setattr(tuning, "COMPACT_AT", 10.0)
    with sg.open_store(tmp_path / "s") as s:
        copies(s, 3)
        sg.load(s, [EXAMPLE], base_iri=G)
        sg.load(s, [edited(tmp_path)], base_iri=G, replace=True)
        assert s.last_removal == "difference" and not s.compacted
        assert s.deleted_quads == s.last_difference["deleted"] > 50  # every shifted p21:line at least
        monkeypatch.setattr(tuning, "COMPACT_AT", 0.0)  # now any deletion reaches it
        sg.load(s, [EXAMPLE], base_iri=G, replace=True)
        assert s.compacted and s.deleted_quads == 0


def test_unload_compact_and_info_on_the_command_line(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    from click.testing import CliRunner

    from stepnc_graph.cli import main

    monkeypatch.setattr(tuning, "COMPACT_AT", 10.0)
    store = str(tmp_path / "s")
    with sg.open_store(store) as s:
        graphs = copies(s, 4)
        n = program_quads(s, graphs[0])
    runner = CliRunner()
    assert runner.invoke(main, ["unload", "--store", store, graphs[0]]).exit_code == 0
    doc = json.loads(runner.invoke(main, ["info", "--store", store, "--format", "json"]).output)
    assert doc["deleted_quads"] == n
    text = runner.invoke(main, ["info", "--store", store]).output
    assert f"{n:,} deleted quads hold disk space until the next compaction" in text
    res = runner.invoke(main, ["unload", "--store", store, "--compact", graphs[1], "urn:not-there"])
    assert res.exit_code == 2 and "removed: " + graphs[1] in res.output
    doc = json.loads(runner.invoke(main, ["info", "--store", store, "--format", "json"]).output)
    assert doc["deleted_quads"] == 0 and [g["graph"] for g in doc["graphs"]] == graphs[2:]
    assert "deleted quads" not in runner.invoke(main, ["info", "--store", store]).output


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
        assert quads(r) == before and listed_graphs(r) == sorted(graphs[1:])


def test_a_failed_compact_leaves_the_store_as_it_was(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setattr(tuning, "REBUILD_BATCH", 100)  # several calls a graph
    with sg.open_store(tmp_path / "s") as s:
        copies(s, 2)
        before = quads(s)

        seen: list[int] = []

        def failing(done: int, total: int) -> None:
            seen.append(done)
            if done > 300:
                raise RuntimeError("disk full (injected)")

        with pytest.raises(RuntimeError, match="injected"):
            sg.compact(s, failing)
        assert seen[:3] == [100, 200, 300]  # it failed between two bulk calls of one graph
        assert quads(s) == before
        assert sg.compact(s).quads == len(before) and quads(s) == before  # and it can be compacted after
    with sg.open_store(tmp_path / "s", readonly=True) as r:
        assert quads(r) == before


def test_compact_needs_a_store_directory() -> None:
    """A SPARQL endpoint manages its own storage (nothing is sent to it); an in-memory store has no
    disk space to give back."""
    from stepnc_graph.store.remote import Endpoint, RemoteStore

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

        def failing(*args: object, **kwargs: object) -> None:
            raise RuntimeError("disk full (injected)")

        monkeypatch.setattr(GraphStore, "_bulk_load", failing)
        with pytest.raises(RuntimeError, match="injected"):
            sg.load(s, [program])
        # beside others the new version is staged in memory first: the failure comes before any write
        assert s.last_removal == ("rebuild" if others == 0 else None)
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

        def interrupted(self: GraphStore, *args: object, **kwargs: object) -> None:
            database = self._db  # noqa: F841 -- held by this frame while the interrupt propagates
            raise KeyboardInterrupt

        monkeypatch.setattr(GraphStore, "_bulk_load", interrupted)
        with pytest.raises(KeyboardInterrupt):
            sg.load(s, [EXAMPLE], base_iri="urn:another")  # a new graph: loaded straight into the database
        with pytest.raises(StoreError, match="open it again"):
            s.count()
    with sg.open_store(tmp_path / "s", readonly=True) as r:
        assert quads(r) == before
    with sg.open_store(tmp_path / "s", readonly=False) as w:  # the next writer recovers work/
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
    with sg.open_store(tmp_path / "s", readonly=False):
        with pytest.raises(StoreBusy, match=r"being written by pid \d+"):
            sg.open_store(tmp_path / "s", readonly=False)
        with pytest.raises(StoreBusy):
            sg.open_store(tmp_path / "s", readonly=False, wait=0.3)
        assert listed_graphs(sg.open_store(tmp_path / "s", readonly=True)) == []
        lazy = sg.open_store(tmp_path / "s", wait=0.3)  # opened to read: not busy until it writes
        with pytest.raises(StoreBusy):
            sg.load(lazy, [EXAMPLE])
        assert listed_graphs(lazy) == []  # still reads
    sg.load(lazy, [EXAMPLE])  # the writer closed: this time it takes the lock
    assert listed_graphs(lazy) == [G]
    lazy.close()


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
        assert listed_graphs(r) == ["urn:g"]
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
        assert doc["quads"] == r.count() and listed_graphs(r) == graphs[1:]
    text = runner.invoke(main, ["compact", "--store", store])
    assert text.exit_code == 0 and text.output.startswith("compacted ") and f"({doc['quads']:,} quads)" in text.output


# -- replacing beside other programs: only what changed is written ---------------------------------

_PROV_TIMES = [f"http://www.w3.org/ns/prov#{t}AtTime" for t in ("generated", "started", "ended")]


def graph_of(store: GraphStore, name: str) -> set[str]:
    """One graph in canonical form (RDFC-1.0: blank nodes differ from load to load), without the
    load's timestamps (two loads differ there too)."""
    times = {ox.NamedNode(p) for p in _PROV_TIMES}
    dataset = ox.Dataset(ox.Quad(q.subject, q.predicate, q.object) for q in store.quads(name)
                         if q.predicate not in times)
    dataset.canonicalize(ox.CanonicalizationAlgorithm.RDFC_1_0)
    return {str(q) for q in dataset}


def assert_as_a_fresh_load(s: GraphStore, graph: str, path: Path) -> None:
    """``graph`` and its derived layer are what a load of ``path`` into an empty store gives
    (isomorphic: blank nodes differ from load to load), and the Part 21 export is the same."""
    with sg.open_store(memory=True) as fresh:
        sg.load(fresh, [path], base_iri=graph)
        for name in (graph, graph + "/derived"):
            assert graph_of(s, name) == graph_of(fresh, name), name
        assert shared_blank_nodes(s, graph) == shared_blank_nodes(fresh, graph) > 0
        assert sg.export(s, "p21", graph) == sg.export(fresh, "p21", graph)


def shared_blank_nodes(store: GraphStore, graph: str) -> int:
    """Blank nodes of the program graph that its derived layer points at (its list index): one
    node in both graphs, which a comparison graph by graph would not see."""
    rows = store.query(f"SELECT (COUNT(DISTINCT ?b) AS ?n) WHERE {{ GRAPH <{graph}/derived> {{ ?x ?p ?b }} "
                       f"GRAPH <{graph}> {{ ?b ?q ?y }} FILTER(isBlank(?b)) }}")
    return int(next(iter(rows))[0].value)


def blank_nodes(store: GraphStore, graph: str) -> int:
    rows = store.query(f"SELECT (COUNT(DISTINCT ?b) AS ?n) WHERE {{ GRAPH <{graph}> {{ ?b ?p ?o }} FILTER(isBlank(?b)) }}")
    return int(next(iter(rows))[0].value)


def loads_own_labels(store: GraphStore) -> list[str]:
    """Blank nodes of the store labelled as a load's text labels them (``_:b17``): unique in one
    load, not in the store, so a replacement must never write them."""
    return re.findall(r"_:b\d+\b", store.dump(ox.RdfFormat.N_QUADS).decode())


def edited(tmp_path: Path) -> Path:
    """The example with the edits a re-load usually brings: a comment that shifts every line
    below it, a changed value, a list one member shorter, a new instance."""
    text = EXAMPLE.read_text()
    for old, new in [("DATA;\n", "DATA;\n/* revision B */\n"),
                     ("TENSILE STRENGTH 650 N/MM2", "TENSILE STRENGTH 700 N/MM2"),
                     ("(#35,#36,#37)", "(#35,#36)"),
                     ("#12=PROPERTY_PARAMETER(", "#9999=PROPERTY_PARAMETER('HARDNESS 200 HB');\n#12=PROPERTY_PARAMETER(")]:
        assert old in text
        text = text.replace(old, new, 1)
    path = tmp_path / "shaft_rev_b.stp"
    path.write_text(text)
    return path


@pytest.fixture(params=["in memory", "on disk, compared in parts"])
def staging(request: pytest.FixtureRequest, monkeypatch: pytest.MonkeyPatch) -> list[int]:
    """Where a replacement by difference stages the new version: in memory (a program of up to
    STAGE_IN_MEMORY_QUADS), or on disk with each graph compared in parts (a larger one, here
    made so by small bounds). Gives the part counts of the splits done."""
    splits: list[int] = []
    if request.param != "in memory":
        monkeypatch.setattr(tuning, "STAGE_IN_MEMORY_QUADS", 0)
        monkeypatch.setattr(tuning, "COMPARE_BYTES", 4096)
        real = difference.split_lines

        def split(lines: Iterable[bytes], parts: int, stem: Path) -> list[Path]:
            splits.append(parts)
            return real(lines, parts, stem)

        monkeypatch.setattr(difference, "split_lines", split)
    return splits


def staged_as(staging: list[int], s: GraphStore) -> None:
    """The replacement staged where the ``staging`` fixture asked, in parts if on disk."""
    on_disk = s.last_difference["staged in memory"] == 0
    assert on_disk == bool(staging) and all(parts > 1 for parts in staging)


@pytest.mark.parametrize("version", ["same file", "edited", "another program"])
def test_a_replacement_beside_other_programs_writes_only_what_changed(tmp_path: Path, version: str,
                                                                      staging: list[int]) -> None:
    new = {"same file": EXAMPLE, "edited": edited(tmp_path), "another program": generated(tmp_path, 300)}[version]
    with sg.open_store(tmp_path / "s") as s:
        others = copies(s, 3)
        sg.load(s, [EXAMPLE])
        theirs = {g: graph_of(s, g) for g in others}
        [r] = sg.load(s, [new], base_iri=G, replace=True)
        assert s.last_removal == "difference" and not r.diagnostics
        staged_as(staging, s)
        assert s.last_difference["new version dumped"] == 0  # compared as the load wrote it
        assert s.last_difference["old version kept"] == 2  # the old one too (stepnc_graph.store.kept)
        assert_as_a_fresh_load(s, G, new)
        assert not loads_own_labels(s)
        assert all(graph_of(s, g) == theirs[g] for g in others)
        written, nodes = s.last_difference, blank_nodes(s, G)
        if version == "same file":  # at most the load's three timestamps changed
            assert written["deleted"] == written["inserted"] <= 3 and written["blank nodes kept"] == nodes
        elif version == "edited":  # each list cell kept its node: one cell now ends the shorter list
            assert written["inserted with a blank node"] == 1 and written["blank nodes kept"] == nodes
        else:
            assert written["blank nodes kept"] < nodes
    with sg.open_store(tmp_path / "s", readonly=True) as reader:  # what was published
        assert_as_a_fresh_load(reader, G, new)


def test_a_replacement_flushes_the_tombstones_of_its_deletes(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    """The lines a replacement deletes leave tombstones in RocksDB's memory tables until they
    are flushed: it flushes every FLUSH_DELETES deleted lines, as batched deletes do, and the
    result is still the new version."""
    monkeypatch.setattr(tuning, "DELETE_LINES", 5)
    monkeypatch.setattr(tuning, "FLUSH_DELETES", 10)
    flushes: list[int] = []
    real = Removal.flush
    monkeypatch.setattr(Removal, "flush", lambda self: (flushes.append(1), real(self)))
    new = edited(tmp_path)
    with sg.open_store(tmp_path / "s") as s:
        copies(s, 3)
        sg.load(s, [EXAMPLE], base_iri=G)
        sg.load(s, [new], base_iri=G, replace=True)
        deleted = s.last_difference["deleted"]
        assert s.last_removal == "difference" and deleted > 90
        assert len(flushes) >= deleted // 10 - 3 > 0  # each graph's last lines may fall short of the bound
        assert_as_a_fresh_load(s, G, new)


def test_a_difference_that_does_not_add_up_falls_back_to_delete_and_load(tmp_path: Path,
                                                                         monkeypatch: pytest.MonkeyPatch) -> None:
    """If the graphs on disk do not end with the staged counts (here: a stray quad the difference
    left), they are dropped and loaded whole from the staged store."""
    real = Replacement._apply_difference

    def apply_and_spoil(self: Replacement, *args: object, **kwargs: object) -> dict[str, int]:
        counts = real(self, *args, **kwargs)  # type: ignore[arg-type]
        self.store.oxigraph.add(ox.Quad(ox.NamedNode("urn:stray"), ox.NamedNode("urn:p"), ox.Literal("x"), ox.NamedNode(G)))
        return counts

    monkeypatch.setattr(Replacement, "_apply_difference", apply_and_spoil)
    with sg.open_store(tmp_path / "s") as s:
        copies(s, 3)
        sg.load(s, [EXAMPLE])
        sg.load(s, [edited(tmp_path)], base_iri=G, replace=True)
        assert s.last_removal == "difference, then delete"
        assert_as_a_fresh_load(s, G, edited(tmp_path))
        assert not loads_own_labels(s)


def test_a_fallback_that_does_not_add_up_either_changes_nothing(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    """If the graphs loaded whole do not end with the staged counts either (here: one line of
    the new version lost on the way), the replacement fails and the store stays as it was."""
    real = Replacement._apply_difference

    def apply_and_spoil(self: Replacement, *args: object, **kwargs: object) -> dict[str, int]:
        counts = real(self, *args, **kwargs)  # type: ignore[arg-type]
        self.store.oxigraph.add(ox.Quad(ox.NamedNode("urn:stray"), ox.NamedNode("urn:p"), ox.Literal("x"), ox.NamedNode(G)))
        return counts

    def lose_a_line(new: dict[str, Path | None], match: object, path: Path) -> Path:
        path = real_relabelled(new, match, path)  # type: ignore[arg-type]
        path.write_bytes(b"".join(path.read_bytes().splitlines(keepends=True)[1:]))
        return path

    real_relabelled = Replacement._relabelled
    monkeypatch.setattr(Replacement, "_apply_difference", apply_and_spoil)
    monkeypatch.setattr(Replacement, "_relabelled", staticmethod(lose_a_line))
    with sg.open_store(tmp_path / "s") as s:
        copies(s, 3)
        sg.load(s, [EXAMPLE], base_iri=G)
        before, quads_before = graph_of(s, G), program_quads(s, G)
        with pytest.raises(StoreError, match="did not add up"):
            sg.load(s, [edited(tmp_path)], base_iri=G, replace=True)
        assert graph_of(s, G) == before and program_quads(s, G) == quads_before


def test_a_write_the_load_text_does_not_show_makes_the_replacement_dump_the_staged_store(
        tmp_path: Path, staging: list[int]) -> None:
    """The new version is compared as the load wrote it only when its text holds each staged
    graph whole: a quad written otherwise (here by SPARQL Update inside the load) makes the
    count differ, and the staged store is dumped instead -- the quad is not lost."""
    from stepnc_graph.loading.loader import ntriples_chunks

    extra = "<urn:x> <urn:p> \"written by an update\" ."
    with sg.open_store(tmp_path / "s") as s:
        copies(s, 3)
        sg.load(s, [EXAMPLE], base_iri=G)
        text = "".join(ntriples_chunks(EXAMPLE, base_iri=G))
        s.replace_graph(G, [text], lambda target: s.update(f"INSERT DATA {{ GRAPH <{target(G)}> {{ {extra} }} }}"),
                        companions=(G + "/derived",))
        assert s.last_removal == "difference" and s.last_difference["new version dumped"] == 1
        staged_as(staging, s)
        assert s.count(G) == text.count("\n") + 1 and not s.has_graph(G + "/derived")
        assert s.query(f"ASK {{ GRAPH <{G}> {{ {extra} }} }}")
        assert not loads_own_labels(s)


@pytest.mark.parametrize("when", ["while staging", "while writing the old version out", "while deleting what changed",
                                  "after writing the difference"])
def test_a_replacement_that_fails_while_writing_the_difference_changes_nothing(tmp_path: Path,
                                                                                monkeypatch: pytest.MonkeyPatch,
                                                                                when: str, staging: list[int]) -> None:
    def fail_staging(self: GraphStore, *args: object, **kwargs: object) -> None:
        raise RuntimeError("out of memory (injected)")

    def fail_after(real: Callable[..., None]) -> Callable[..., None]:
        def fail(*args: object, **kwargs: object) -> None:
            real(*args, **kwargs)
            raise RuntimeError("disk full (injected)")
        return fail

    with sg.open_store(tmp_path / "s") as s:
        copies(s, 3)
        sg.load(s, [EXAMPLE])
        before = quads(s)
        if when == "while staging":
            monkeypatch.setattr(GraphStore, "_bulk_load", fail_staging)
        elif when == "while writing the old version out":  # beside the staging, on a thread
            real_dump = Replacement._dump_graph

            def fail_old(store: ox.Store, name: str, path: Path) -> Path | None:
                if path.name.startswith("old"):
                    raise OSError("disk full (injected)")
                return real_dump(store, name, path)

            def fail_kept(path: Path, out: object) -> None:
                raise OSError("disk full (injected)")

            # the kept text fails (the old version is then dumped), and so does the dump
            monkeypatch.setattr(kept_graph, "read_without_blank_nodes", fail_kept)
            monkeypatch.setattr(Replacement, "_dump_graph", staticmethod(fail_old))
        elif when == "while deleting what changed":
            monkeypatch.setattr(Replacement, "_delete_lines", fail_after(Replacement._delete_lines))
        else:
            monkeypatch.setattr(Replacement, "_apply_difference", fail_after(Replacement._apply_difference))
        with pytest.raises((RuntimeError, OSError), match="injected"):
            sg.load(s, [edited(tmp_path)], base_iri=G, replace=True)
        assert quads(s) == before
        assert not (tmp_path / "s" / "difference").exists()  # the scratch, a staged store on disk too
    with sg.open_store(tmp_path / "s", readonly=True) as r:
        assert quads(r) == before


def test_a_replacement_rewrites_a_stale_vocabulary(tmp_path: Path) -> None:
    """The vocabulary graph is compared only when the load rewrote it (it was stale)."""
    from stepnc_graph.graphs.vocabulary_graph import DIGEST

    with sg.open_store(tmp_path / "s") as s:
        copies(s, 3)
        sg.load(s, [EXAMPLE])
        vocabulary = graph_of(s, VOCABULARY_GRAPH)
        s.update(f"DELETE {{ GRAPH <{VOCABULARY_GRAPH}> {{ ?s <{DIGEST}> ?d }} }} INSERT {{ GRAPH <{VOCABULARY_GRAPH}> "
                 f"{{ ?s <{DIGEST}> \"stale\" }} }} WHERE {{ GRAPH <{VOCABULARY_GRAPH}> {{ ?s <{DIGEST}> ?d }} }}")
        s.update(f"INSERT DATA {{ GRAPH <{VOCABULARY_GRAPH}> {{ <urn:old> <urn:p> \"left over\" }} }}")
        sg.load(s, [EXAMPLE], replace=True)
        assert s.last_removal == "difference"
        assert graph_of(s, VOCABULARY_GRAPH) == vocabulary


def test_a_killed_replacement_leaves_no_scratch_behind(tmp_path: Path) -> None:
    """A writer killed while replacing by difference leaves work/ dirty and its texts in
    difference/: the next writer's recovery removes them with the rest."""
    with sg.open_store(tmp_path / "s") as s:
        sg.load(s, [EXAMPLE])
        before = quads(s)
    (tmp_path / "s" / "difference").mkdir()
    (tmp_path / "s" / "difference" / "new0.nt").write_bytes(b"<urn:a> <urn:b> <urn:c> .\n")
    (tmp_path / "s" / "work.dirty").write_text("")
    with sg.open_store(tmp_path / "s", readonly=False) as w:  # the next writer recovers
        assert quads(w) == before
    assert not (tmp_path / "s" / "difference").exists()


def test_blank_nodes_are_matched_by_their_place_under_their_owner(tmp_path: Path) -> None:
    """The old and new versions' blank nodes are paired by the path from the instance that owns
    them; nodes with no place of their own (members of a SET of lists, a node reached twice, a
    cycle, a root nothing reaches) stay unpaired, and a literal that ends like a label is none."""
    from stepnc_graph.store.difference import BlankMatch

    rest, first = "<http://www.w3.org/1999/02/22-rdf-syntax-ns#rest>", "<http://www.w3.org/1999/02/22-rdf-syntax-ns#first>"

    def version(name: str, labels: dict[str, str]) -> Path:
        a, b, c, d, e, f, g, h = (labels[k] for k in "abcdefgh")
        path = tmp_path / name
        path.write_text("\n".join([
            f"<urn:i1> <urn:list> _:{a} .", f"_:{a} {first} \"1\" .", f"_:{a} {rest} _:{b} .",
            f"_:{b} {first} _:{c} .", f"_:{c} <urn:value> \"x _:{a}\" .",     # a nested list, a tricky literal
            f"<urn:i2> <urn:set> _:{d} .", f"<urn:i2> <urn:set> _:{e} .",     # a SET of two lists
            f"<urn:i3> <urn:p> _:{f} .", f"<urn:i4> <urn:p> _:{f} .",         # reached twice
            f"_:{g} {rest} _:{h} .", f"_:{h} {rest} _:{g} .",                 # a cycle
        ]) + "\n")
        return path

    old = version("old.nt", {k: f"old{k}" for k in "abcdefgh"})
    new = version("new.nt", {k: f"new{k}" for k in "abcdefgh"})
    match = BlankMatch(old, new)
    assert match.renamed == {b"newa": b"olda", b"newb": b"oldb", b"newc": b"oldc"}
    assert match.relabel(b'_:newc <urn:value> "x _:newa" .\n') == b'_:oldc <urn:value> "x _:newa" .\n'
    assert match.relabel(b"_:newa <urn:r> _:newb .\n") == b"_:olda <urn:r> _:oldb .\n"
    assert match.kept == 3
    # an unpaired node gets a new random label, one per node (the load's own labels are unique
    # in one load only), the same one wherever it is met
    fresh = match.relabel(b"_:newd <urn:r> <urn:x> .\n")
    assert re.fullmatch(rb"_:[0-9a-f]{32} <urn:r> <urn:x> \.\n", fresh)
    assert match.relabel(b"<urn:x> <urn:r> _:newd .\n") == b"<urn:x> <urn:r> " + fresh.split(b" ")[0] + b" .\n"
    assert match.relabel(b"_:newe <urn:r> <urn:x> .\n") != fresh
    assert BlankMatch(None, new).kept == 0 and BlankMatch(old, None).kept == 0


def test_a_large_graph_is_compared_in_parts_that_pair_equal_lines(tmp_path: Path,
                                                                  monkeypatch: pytest.MonkeyPatch) -> None:
    """Two dumps too large to hold at once are split by a hash of each line: every part pair
    holds the same lines as the whole files would have matched, the new lines relabelled, and
    the parts' files are gone once compared."""
    from stepnc_graph.store.difference import compared_parts

    monkeypatch.setattr(tuning, "COMPARE_BYTES", 200)
    old, new = tmp_path / "old.nt", tmp_path / "new.nt"
    old_lines = [f"<urn:s{k}> <urn:p> \"{k}\" .\n".encode() for k in range(100)] + [b"_:o1 <urn:p> <urn:x> .\n"]
    new_lines = [f"<urn:s{k}> <urn:p> \"{k}\" .\n".encode() for k in range(50, 150)] + [b"_:n1 <urn:p> <urn:x> .\n"]
    old.write_bytes(b"".join(old_lines))
    new.write_bytes(b"".join(new_lines))

    def relabel(line: bytes) -> bytes:
        return line.replace(b"_:n1", b"_:o1")

    pairs = 0
    matched: set[bytes] = set()
    seen_new: list[bytes] = []
    for old_part, new_part in compared_parts(old, new, relabel, tmp_path / "parts"):
        assert old_part is not None
        olds = set(old_part.read_bytes().splitlines(keepends=True))
        news = list(new_part)
        matched |= olds & set(news)
        seen_new += news
        pairs += 1
    assert pairs == -(-old.stat().st_size // 200) > 1
    assert sorted(seen_new) == sorted(relabel(line) for line in new_lines)
    assert matched == set(old_lines) & {relabel(line) for line in new_lines} and len(matched) == 51
    assert list((tmp_path / "parts").iterdir()) == []


def test_deletes_are_split_into_rounds_of_distinct_predicates() -> None:
    """Each round deletes at most the budget, a predicate at most once and at most its share per
    thread; together the rounds delete every quad."""
    from stepnc_graph.store.batches import delete_rounds

    g, h = ox.NamedNode("urn:g"), ox.NamedNode("urn:h")
    work = [(g, "<urn:a>", 23), (g, "<urn:b>", 4), (h, "<urn:a>", 7), (g, "<urn:c>", 0)]
    rounds = delete_rounds(work, 10, 2)
    for part in rounds:
        assert sum(n for _, _, n in part) <= 10 and all(0 < n <= 5 for _, _, n in part)
        assert len({(node, p) for node, p, _ in part}) == len(part)
    totals: dict[tuple[ox.NamedNode, str], int] = {}
    for part in rounds:
        for node, p, n in part:
            totals[(node, p)] = totals.get((node, p), 0) + n
    assert totals == {(g, "<urn:a>"): 23, (g, "<urn:b>"): 4, (h, "<urn:a>"): 7}
    assert len(rounds) == 5  # 34 quads; the last ones are all one predicate's


def test_large_additions_inside_a_load_go_in_bounded_calls(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    """A bulk addition of N-Triples text is split at line ends into calls of about BATCH_CHARS
    characters, and many quads go through the bulk loader in calls: every triple arrives, and a
    blank node keeps its identity across calls (the derived layer shares list cells)."""
    from stepnc_graph.store.batches import line_pieces

    text = "".join(f"<urn:s{k}> <urn:p> \"{k}\" .\n" for k in range(200))
    pieces = list(line_pieces(text, 100))
    assert "".join(pieces) == text and len(pieces) > 10 and all(p.endswith(" .\n") for p in pieces)
    monkeypatch.setattr(tuning, "BATCH_CHARS", 100)
    monkeypatch.setattr(tuning, "TRANSACTION_QUADS", 3)
    monkeypatch.setattr(tuning, "INSERT_BATCH", 4)
    cell = ox.BlankNode()

    def quads(n: int, graph: str) -> Iterator[ox.Quad]:  # a generator: add_quads pulls one at a time
        return (ox.Quad(cell, ox.NamedNode("urn:i"), ox.Literal(str(k)), ox.NamedNode(graph)) for k in range(n))

    with sg.open_store(tmp_path / "s") as s:
        s.add_ntriples("urn:g", text, bulk=True)
        assert s.add_quads(quads(10, "urn:h")) == 10  # bulk calls of 4, 4 and 2
        assert s.add_quads(quads(4, "urn:t4")) == 4  # one more than a transaction takes: bulk
        assert s.add_quads(quads(3, "urn:t3")) == 3  # a transaction
        assert s.add_quads(quads(0, "urn:t0")) == 0
        assert s.add_quads([ox.Quad(cell, ox.NamedNode("urn:j"), ox.Literal("x"), ox.NamedNode("urn:g"))]) == 1
        assert s.count("urn:g") == 201 and s.count("urn:h") == 10
        assert (s.count("urn:t4"), s.count("urn:t3"), s.has_graph("urn:t0")) == (4, 3, False)
        rows = s.query("SELECT (COUNT(DISTINCT ?b) AS ?n) WHERE { GRAPH <urn:g> { ?b <urn:j> ?x } "
                       "GRAPH <urn:h> { ?b <urn:i> ?y } }")
        assert int(next(iter(rows))[0].value) == 1


# -- a worker that fails, a full disk, a read-only one -----------------------------------------------------


class _FailingBulkLoads:
    """The database of an in-memory store whose bulk loads write, then fail as a full disk does."""

    def __init__(self, db: ox.Store) -> None:
        self.db = db

    def bulk_load(self, *args: object, **kwargs: object) -> None:
        self.db.bulk_load(*args, **kwargs)  # type: ignore[arg-type]
        raise OSError(errno.ENOSPC, "No space left on device (injected)")

    def __getattr__(self, name: str) -> object:
        return getattr(self.db, name)


def _finishes(work: Callable[[], object], seconds: float = 60) -> BaseException | None:
    """Run ``work`` on a thread; the exception it raised (None if none). Fails if it is still
    running after ``seconds``: a deadlock (the thread is left behind, a daemon)."""
    raised: list[BaseException] = []

    def run() -> None:
        try:
            work()
        except BaseException as exc:  # noqa: BLE001 -- handed to the test
            raised.append(exc)

    thread = threading.Thread(target=run, daemon=True)
    thread.start()
    thread.join(seconds)
    assert not thread.is_alive(), f"still running after {seconds} s: a deadlock"
    return raised[0] if raised else None


@pytest.mark.parametrize("when", ["after the end of input", "at the first read"])
def test_a_bulk_load_worker_that_fails_stops_the_load(tmp_path: Path, monkeypatch: pytest.MonkeyPatch,
                                                      when: str) -> None:
    """A worker that fails -- after it took the end of input, which deadlocked the load on a full
    disk, or while the producer still has chunks to hand over -- stops the producer and the other
    workers; the load fails with the worker's error, the store is as it was, the next writer writes."""
    big = generated(tmp_path, 3000)  # several batches, so the producer waits on full hand-offs
    read = batches.ChunkStream.readinto
    reads = itertools.count()

    def failing(self: batches.ChunkStream, target: object) -> int:
        n = read(self, target)
        if (n == 0) if when == "after the end of input" else next(reads) == 0:
            raise OSError(errno.ENOSPC, "No space left on device (injected)")
        return n

    with sg.open_store(tmp_path / "s") as s:
        sg.load(s, [EXAMPLE])
        before = quads(s)
        monkeypatch.setattr(batches.ChunkStream, "readinto", failing)
        error = _finishes(lambda: sg.load(s, [big]))
        assert error is not None and "No space left on device (injected)" in str(error)
        monkeypatch.undo()
        assert quads(s) == before
    with sg.open_store(tmp_path / "s") as s:  # the writer's lock is free, the store whole
        assert quads(s) == before and len(sg.load(s, [big])) == 1


def test_an_in_memory_bulk_load_that_fails_after_the_end_of_input_stops(tmp_path: Path) -> None:
    """Without a derived layer (validation's throw-away store) the program's last chunk is the last
    item, so the one worker takes the end of input before its bulk load fails."""
    s = GraphStore(None)
    db = s._store
    assert db is not None
    s._store = _FailingBulkLoads(db)  # type: ignore[assignment]
    error = _finishes(lambda: sg.load(s, [EXAMPLE], derived=False))
    assert isinstance(error, OSError) and error.errno == errno.ENOSPC
    s._store = db
    assert len(db) == 0  # the new graph was dropped


def test_keeping_a_text_on_a_full_disk_fails_without_waiting(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    """The kept text's compressor fails on its last write (the disk filled up): the load's text
    is not kept, and nothing waits for an end of input the compressor already took."""
    import zlib

    from stepnc_graph.store.kept import KeptTexts

    real = zlib.compressobj

    class Full:
        def __init__(self, level: int) -> None:
            self.real = real(level)

        def compress(self, data: bytes) -> bytes:
            return self.real.compress(data)

        def flush(self) -> bytes:
            raise OSError(errno.ENOSPC, "No space left on device (injected)")

    monkeypatch.setattr(zlib, "compressobj", Full)
    writing = KeptTexts(tmp_path / "kept").writing(["urn:g"])
    writing.write("urn:g", b"<urn:s> <urn:p> <urn:o> .\n")
    kept: dict[str, object] = {}
    assert _finishes(lambda: kept.update(writing.finish({"urn:g": 1}))) is None
    assert kept == {} and list((tmp_path / "kept").iterdir()) == []


def test_a_handoff_never_leaves_a_thread_waiting() -> None:
    """Aborting wakes a producer waiting on a full hand-off; closing wakes idle workers, after
    they took every item exactly once."""
    full: Handoff[int] = Handoff(1)
    assert full.put(1)
    blocked = threading.Thread(target=lambda: full.put(2))  # waits: the hand-off is full
    blocked.start()
    time.sleep(0.05)
    full.abort()
    blocked.join(5)
    assert not blocked.is_alive() and full.get() is None and full.put(3) is False

    work: Handoff[int] = Handoff(2)
    taken: list[int] = []

    def worker() -> None:
        while (item := work.get()) is not None:
            taken.append(item)

    workers = [threading.Thread(target=worker) for _ in range(3)]
    for t in workers:
        t.start()
    for k in range(1000):
        assert work.put(k)
    work.close()
    for t in workers:
        t.join(5)
    assert not any(t.is_alive() for t in workers) and sorted(taken) == list(range(1000))


@contextmanager
def _mounted(*args: str) -> Iterator[None]:
    """``mount ARGS``, unmounted after; the test is skipped where mounting is not permitted."""
    if shutil.which("mount") is None:
        pytest.skip("no mount command here: the test needs a real file system of its own")
    done = subprocess.run(["mount", *args], capture_output=True, text=True)
    if done.returncode != 0:
        pytest.skip(f"mount {' '.join(args)} is not permitted here ({done.stderr.strip()}): it needs root")
    try:
        yield
    finally:
        subprocess.run(["umount", "-l", args[-1]], capture_output=True)


def _cli(*args: str) -> subprocess.CompletedProcess[str]:
    return subprocess.run([sys.executable, "-m", "stepnc_graph.cli", *args], capture_output=True, text=True,
                          timeout=120)


@pytest.mark.parametrize("free_mb", [1, 3])
def test_a_full_disk_fails_the_load_cleanly(tmp_path: Path, free_mb: int) -> None:
    """A real ENOSPC: a small tmpfs holding a store with a program, filled to ``free_mb`` MB (the
    load deadlocked, holding the writer's lock, with 0.8-4 MB free). Exit 2 naming the store and
    the cause, the store as before, the next writer not refused."""
    small = shutil.move(generated(tmp_path, 300), tmp_path / "small.stp")
    big = generated(tmp_path, 3000)
    disk = tmp_path / "disk"
    disk.mkdir()
    with _mounted("-t", "tmpfs", "-o", "size=64m", "tmpfs", str(disk)):
        store = str(disk / "store")
        assert _cli("load", "--store", store, str(small)).returncode == 0
        before = _cli("export", "--store", store, "--format", "nq").stdout
        free = shutil.disk_usage(disk).free - free_mb * (1 << 20)
        with open(disk / "filler", "wb") as fh:
            fh.write(b"\0" * free)
        done = _cli("load", "--store", store, str(big))
        assert done.returncode == 2 and "Traceback" not in done.stderr
        assert f"store in {store}" in done.stderr and "No space left on device" in done.stderr
        assert _cli("export", "--store", store, "--format", "nq").stdout == before
        with sg.open_store(store, readonly=False) as s:  # not StoreBusy: the failed load let go of the lock
            assert [g.graph for g in sg.info(s)] == [sg.info(s)[0].graph] and s.count() > 0


def test_a_store_on_a_read_only_file_system_can_be_read(tmp_path: Path) -> None:
    """An archived store (a read-only mount): info, export, query and validate read it; the
    writing commands say why they cannot write, exit 2, without a traceback."""
    store, archived = tmp_path / "store", tmp_path / "archived"
    assert _cli("load", "--store", str(store), str(EXAMPLE)).returncode == 0
    archived.mkdir()
    with _mounted("--bind", str(store), str(archived)), _mounted("-o", "remount,bind,ro", str(archived)):
        assert not os.access(archived, os.W_OK) or _cannot_write(archived)
        at = ["--store", str(archived)]
        info = _cli("info", *at, "--format", "json")
        assert info.returncode == 0 and [g["graph"] for g in json.loads(info.stdout)["graphs"]] == [G]
        assert _cli("export", *at, "--graph", G, "--format", "p21").stdout == \
            _cli("export", "--store", str(store), "--graph", G, "--format", "p21").stdout != ""
        query = _cli("query", *at, "SELECT (COUNT(*) AS ?n) WHERE { GRAPH ?g { ?s ?p ?o } }", "--format", "json")
        assert query.returncode == 0, query.stderr
        assert _cli("validate", *at).returncode in (0, 1)
        for write in (["load", str(EXAMPLE)], ["unload", G], ["compact"],
                      ["link", str(ROOT / "examples" / "shaft_plm_links.csv")]):
            done = _cli(*write, *at)
            assert done.returncode == 2 and "Traceback" not in done.stderr
            assert "read-only file system" in done.stderr, done.stderr


def _cannot_write(path: Path) -> bool:
    try:
        (path / "probe").write_text("")
    except OSError as e:
        return e.errno == errno.EROFS
    return False


def test_an_export_that_cannot_be_written_names_the_output(tmp_path: Path) -> None:
    if not Path("/dev/full").exists():
        pytest.skip("no /dev/full here")
    store = str(tmp_path / "store")
    assert _cli("load", "--store", store, str(EXAMPLE)).returncode == 0
    done = _cli("export", "--store", store, "--format", "nq", "-o", "/dev/full")
    assert done.returncode == 2 and "Traceback" not in done.stderr
    assert "/dev/full" in done.stderr and "No space left on device" in done.stderr
