"""Load benchmark: parse-only and end-to-end load rates, peak memory, where a load's and an export's
time goes, each next to a reference measured in the same run.

    pip install -e '.[bench]' && python bench/load_bench.py            # 10k and 100k
    python bench/load_bench.py --sizes 10000 100000 1000000             # add 1M
    python bench/load_bench.py --sizes 100000 --programs replicated     # the issue-32 figures only
    python bench/load_bench.py --sizes 100000 --parse-only --repeat 5 --baseline OLD/src  # parse vs older code
    python bench/load_bench.py --sizes 100000 --baseline OLD/src       # also the whole load vs older code

For each size, on a generated program and on a replicated real one (bench/generate.py: copies of the
shipped two-setup shaft unless ``--real`` names another), each measurement in a fresh process:

* **parse**: steputils' parse-only rate (the reference) and stepnc-graph's;
* **load**: the end-to-end load (parse, map, derived layer, diagnostics, kept text) into a fresh
  on-disk store: wall and CPU seconds (all threads), peak RSS;
* **store alone**: the same N-Triples, mapped before the clock starts, written by the same store code;
* **pyoxigraph bulk**: pyoxigraph's own ``Store.bulk_load`` of the very quads the load wrote (the
  program graph, its derived layer and the vocabulary graph, dumped as N-Quads before the clock
  starts) into a fresh on-disk store: the ceiling the store sets. The issue-32 target is a load
  within 1/0.85 of it (ratio <= 1.18).

Then, up to ``--profile-max`` instances (default 100k), for each program:

* **phases of the load** (one more load, instrumented from outside: the loader's functions wrapped,
  not changed): CPU seconds of the main thread in reading and decoding the file, Part 21 parsing,
  mapping, the derived layer written after the graph (lists, execution order, counts), diagnostics,
  the vocabulary, commit (checkpoint, publish); the rest of the main thread (chunks, the kept text's
  encoding, waits); and the other threads (the bulk loader's, RocksDB's, the kept text's
  compression). The derived layer's share of mapping is the difference to a load without it;
* **exports** of the loaded store (fresh process each): the program graph as N-Triples and as
  Part 21, the whole store as N-Quads, wall and CPU seconds and their ratio to the load, with the
  time spent reading the graphs (from the text their load kept, else Oxigraph's dump) apart from
  ordering and writing them; each beside the same export dumped from Oxigraph (the kept text
  refused: the reference), with whether the bytes are the same.

With ``--baseline OLD/src`` (an older source tree's ``src/``), the parse and the whole load are also
run with that code, runs alternating with this code's (so a change in the machine's load falls on
both): the ratio of the two, and of each to pyoxigraph's bulk load.

Rates and seconds are medians over ``--repeat`` runs (the profile and the exports: one run). The
machine is shared: read CPU seconds and the ratios beside wall seconds.
"""

from __future__ import annotations

import argparse
import json
import os
import resource
import shutil
import statistics
import subprocess
import sys
import tempfile
import threading
import time
from collections import defaultdict
from collections.abc import Callable, Iterator
from pathlib import Path
from typing import Any

HERE = Path(__file__).resolve().parent
sys.path.insert(0, str(HERE))

from generate import replicate, write  # noqa: E402

#: load phases, in the order printed: (key, what it is)
PHASES = [
    ("prepare", "read and decode the file, index its #ids"),
    ("parse", "Part 21 parsing (the reader)"),
    ("map", "mapping to N-Triples (with the derived layer's closure, generic values, labels)"),
    ("map_layer", "  of which the derived layer's part (mapping: this load minus one without the layer)"),
    ("derive", "derived layer after the graph is written (lists, execution order, counts)"),
    ("diagnostics", "diagnostics (dangling references, the count)"),
    ("vocabulary", "vocabulary graph (written into an empty store)"),
    ("commit", "commit (checkpoint, publish, kept texts' index)"),
    ("main_other", "rest of the main thread (chunks, encoding, the queue to the loader threads)"),
    ("threads", "other threads: bulk loader, RocksDB, the kept text's compression"),
]


def switch_off_derived_layer(loader: Any) -> None:
    """Make the loader module ``loader`` write no derived layer (the load without it, for the
    layer's cost): ``derive`` does nothing and the mapper gets no layer tables."""
    class _Nothing:
        triples = 0

    class _NoTables:
        @staticmethod
        def tables() -> None:
            return None  # the mapper writes no layer lines either

    loader.derive = lambda *args, **kwargs: _Nothing()
    loader.iso14649_rules = lambda: _NoTables()


def _rss_mb() -> float:
    return resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024


def child(kind: str, path: str, extra: list[str]) -> None:
    """Run one measurement in this (fresh) process and print it as JSON.

    Imports happen before the clock starts: start-up cost is not reading speed.
    For "store", parsing and mapping happen before the clock starts too.
    """
    if kind == "bulk":
        child_bulk(path)
        return
    if kind in ("profile", "profile-off"):
        child_profile(path, extra[0], kind == "profile", extra[1] if len(extra) > 1 else None)
        return
    if kind == "export":
        child_export(path, extra[0], extra[1], extra[2] if len(extra) > 2 else None)
        return
    import stepnc_graph as sg
    from stepnc_graph.loading.loader import ntriples_chunks
    from stepnc_graph.part21 import read_file
    from stepnc_graph.schema.catalog import iso14649

    iso14649()  # the schema model is built once per process; not part of a file's load
    triples = 0
    if kind == "store":
        chunks = list(ntriples_chunks(path))
        count = sum(1 for _ in read_file(path).instances())
    store_dir = tempfile.mkdtemp(prefix="stepnc-bench-")
    started, cpu_started = time.perf_counter(), time.process_time()
    try:
        if kind == "steputils":
            from steputils import p21  # imported here: a parse-only run needs no steputils

            doc = p21.readfile(path)
            count = sum(len(section.instances) for section in doc.data)
        elif kind == "parse":
            count = sum(1 for _ in read_file(path).instances())
        elif kind == "store":
            with sg.open_store(Path(store_dir) / "store") as store:
                store.replace_graph("urn:stepnc-graph:bench", chunks)
            triples = sum(c.count("\n") for c in chunks)
        else:
            with sg.open_store(Path(store_dir) / "store") as store:
                [result] = sg.load(store, [path])
            count, triples = result.instances, result.triples
            assert not result.diagnostics, result.diagnostics[:3]
        seconds, cpu = time.perf_counter() - started, time.process_time() - cpu_started
    finally:
        shutil.rmtree(store_dir, ignore_errors=True)
    print(json.dumps({"count": count, "seconds": seconds, "cpu": cpu, "triples": triples, "rss_mb": _rss_mb()}))


def child_bulk(nquads: str) -> None:
    """pyoxigraph's own bulk load of an N-Quads file into a fresh on-disk store."""
    import pyoxigraph as ox

    store_dir = tempfile.mkdtemp(prefix="stepnc-bench-bulk-")
    try:
        store = ox.Store(store_dir)
        started, cpu_started = time.perf_counter(), time.process_time()
        store.bulk_load(path=nquads, format=ox.RdfFormat.N_QUADS)
        store.flush()
        seconds, cpu = time.perf_counter() - started, time.process_time() - cpu_started
        count = len(store)
        del store
    finally:
        shutil.rmtree(store_dir, ignore_errors=True)
    print(json.dumps({"count": count, "seconds": seconds, "cpu": cpu, "triples": count, "rss_mb": _rss_mb()}))


class Clock:
    """CPU seconds of the calling thread spent in wrapped functions, by phase (nested phases are
    counted in the innermost only)."""

    def __init__(self) -> None:
        self.spent: dict[str, float] = defaultdict(float)
        self.main = threading.get_ident()
        self._stack: list[str] = []

    def _enter(self, key: str) -> float:
        now = time.thread_time()
        if self._stack:
            self.spent[self._stack[-1]] += now
        self._stack.append(key)
        self.spent[key] -= now
        return now

    def _leave(self) -> None:
        now = time.thread_time()
        self.spent[self._stack.pop()] += now
        if self._stack:
            self.spent[self._stack[-1]] -= now

    def wrap(self, fn: Callable[..., Any], key: str) -> Callable[..., Any]:
        def timed(*args: Any, **kwargs: Any) -> Any:
            if threading.get_ident() != self.main:
                return fn(*args, **kwargs)
            self._enter(key)
            try:
                return fn(*args, **kwargs)
            finally:
                self._leave()
        return timed

    def wrap_generator(self, fn: Callable[..., Iterator[Any]], key: str) -> Callable[..., Iterator[Any]]:
        def timed(*args: Any, **kwargs: Any) -> Iterator[Any]:
            it = fn(*args, **kwargs)
            while True:
                self._enter(key)
                try:
                    item = next(it)
                except StopIteration:
                    return
                finally:
                    self._leave()
                yield item
        return timed


def child_profile(path: str, store_dir: str, derived: bool, nquads: str | None) -> None:
    """One load with its phases timed (see PHASES); with ``nquads``, the store's quads are then
    dumped there (after the clock) for the bulk-load reference, and the store is kept."""
    import pyoxigraph as ox

    import stepnc_graph as sg
    import stepnc_graph.loading.loader as loader
    from stepnc_graph.loading.derive import iso14649_rules
    from stepnc_graph.mapping.mapper import InstanceMapper
    from stepnc_graph.part21.reader import Part21Reader
    from stepnc_graph.schema.catalog import iso14649
    from stepnc_graph.store.transaction import Transaction

    iso14649()
    iso14649_rules()
    clock = Clock()
    loader.read_source = clock.wrap(loader.read_source, "prepare")
    loader._Load.__init__ = clock.wrap(loader._Load.__init__, "prepare")  # type: ignore[method-assign]
    Part21Reader.instances = clock.wrap_generator(Part21Reader.instances, "parse")  # type: ignore[method-assign]
    InstanceMapper.map = clock.wrap(InstanceMapper.map, "map")  # type: ignore[method-assign]
    loader._Load.dangling = clock.wrap(loader._Load.dangling, "diagnostics")  # type: ignore[method-assign]
    loader._Load.diagnostics = clock.wrap(loader._Load.diagnostics, "diagnostics")  # type: ignore[method-assign]
    loader.ensure_vocabulary = clock.wrap(loader.ensure_vocabulary, "vocabulary")
    Transaction.commit = clock.wrap(Transaction.commit, "commit")  # type: ignore[method-assign]
    if derived:
        loader.derive = clock.wrap(loader.derive, "derive")
    else:
        switch_off_derived_layer(loader)
    with sg.open_store(store_dir) as store:
        started, cpu, main = time.perf_counter(), time.process_time(), time.thread_time()
        [result] = sg.load(store, [path])
        seconds, cpu, main = time.perf_counter() - started, time.process_time() - cpu, time.thread_time() - main
        assert not result.diagnostics, result.diagnostics[:3]
        if nquads:
            with open(nquads, "wb") as out:
                store.oxigraph.dump(out, ox.RdfFormat.N_QUADS)
    phases = dict(clock.spent)
    phases["main_other"] = main - sum(phases.values())
    phases["threads"] = cpu - main
    print(json.dumps({"seconds": seconds, "cpu": cpu, "phases": phases, "instances": result.instances,
                      "triples": result.triples, "derived": result.derived_triples, "rss_mb": _rss_mb(),
                      "graph": result.graph}))


def child_export(store_dir: str, how: str, fmt: str, graph: str | None) -> None:
    """One export from the kept store, its time split into reading the graphs (each graph's kept
    text, or Oxigraph's dump of it, split by subject; for Part 21 the kept text, or the quads read
    one by one) and ordering and writing them; ``how`` "dumped": the kept texts refused."""
    import hashlib
    import importlib

    import stepnc_graph as sg
    from stepnc_graph.store import GraphStore
    from stepnc_graph.store.reading import OxigraphReads

    export = importlib.import_module("stepnc_graph.exporting.exporter")  # the module: sg.export is the function
    clock = Clock()
    export._read_graph = clock.wrap(export._read_graph, "read")  # one graph's text, split by subject
    original_quads = GraphStore.quads  # the Part 21 writer's reading
    GraphStore.quads = clock.wrap_generator(original_quads, "read")  # type: ignore[method-assign]
    kept_text = OxigraphReads.kept_text if how == "kept" else (lambda *args, **kwargs: False)
    OxigraphReads.kept_text = clock.wrap(kept_text, "read")  # type: ignore[method-assign]
    with sg.open_store(store_dir, readonly=True) as store:
        started, cpu = time.perf_counter(), time.process_time()
        data = sg.export(store, fmt, graph)
        seconds, cpu = time.perf_counter() - started, time.process_time() - cpu
    print(json.dumps({"seconds": seconds, "cpu": cpu, "read": clock.spent.get("read", 0.0),
                      "bytes": len(data), "rss_mb": _rss_mb(), "sha": hashlib.sha256(data).hexdigest()}))


def run_child(*args: str, timeout: float = 3600, src: str | None = None) -> dict[str, Any] | None:
    """One measurement in a fresh process; ``src``: the stepnc_graph package of that source tree."""
    env = {**os.environ, "PYTHONPATH": src} if src else None
    try:
        done = subprocess.run([sys.executable, __file__, "--child", *args], capture_output=True, text=True,
                              timeout=timeout, check=True, env=env)
    except subprocess.TimeoutExpired:
        return None
    except subprocess.CalledProcessError as e:
        print(f"  {args[0]} failed: {e.stderr.strip().splitlines()[-1] if e.stderr.strip() else e}")
        return None
    result: dict[str, Any] = json.loads(done.stdout.strip().splitlines()[-1])
    return result


def measure(kind: str, path: Path, repeat: int, timeout: float) -> dict[str, float] | None:
    runs = []
    for _ in range(repeat):
        row = run_child(kind, str(path), timeout=timeout)
        if row is None:
            return None
        runs.append(row)
    seconds = statistics.median(r["seconds"] for r in runs)
    count = runs[0]["count"]
    return {"count": count, "seconds": seconds, "cpu": statistics.median(r["cpu"] for r in runs),
            "rate": count / seconds,
            "triples_rate": runs[0]["triples"] / seconds, "triples": runs[0]["triples"],
            "rss_mb": max(r["rss_mb"] for r in runs)}


def profile(program: str, path: Path, work: Path, load: dict[str, float], bulk_file: Path) -> dict[str, Any] | None:
    """The phases of one load (and of one without the derived layer), then the exports."""
    store_dir = work / f"profile-{program}"
    shutil.rmtree(store_dir, ignore_errors=True)
    off_dir = work / f"profile-{program}-off"
    on = run_child("profile", str(path), str(store_dir), str(bulk_file))
    off = run_child("profile-off", str(path), str(off_dir))
    shutil.rmtree(off_dir, ignore_errors=True)
    if on is None or off is None:
        return None
    phases = on["phases"]
    phases["map_layer"] = phases.get("map", 0.0) - off["phases"].get("map", 0.0)
    print(f"\n{program} program, {on['instances']:,} instances: where the load's time goes (one load, "
          f"{on['seconds']:.1f} s wall, {on['cpu']:.1f} s CPU; {on['triples']:,} triples, {on['derived']:,} derived)")
    for key, text in PHASES:
        value = phases.get(key, 0.0)
        print(f"  {text:92} {value:7.2f} s CPU {100 * value / on['cpu']:5.1f} %")
    print(f"  {'a load without the derived layer':92} {off['cpu']:7.2f} s CPU (the layer: "
          f"+{100 * (on['cpu'] / off['cpu'] - 1):.1f} % CPU, +{100 * (on['seconds'] / off['seconds'] - 1):.1f} % wall)")
    print(f"\n{program} program: exports of the loaded store against its load ({load['seconds']:.1f} s wall, "
          f"{load['cpu']:.1f} s CPU, median)")
    for fmt, graph, what in (("nt", on["graph"], "program graph as N-Triples"),
                             ("p21", on["graph"], "program graph as Part 21"),
                             ("nq", None, "whole store as N-Quads")):
        rows = {how: run_child("export", str(store_dir), how, fmt, *([graph] if graph else []))
                for how in ("kept", "dumped")}
        for how, row in rows.items():
            if row is None:
                continue
            same = "" if how == "kept" or rows["kept"] is None else \
                f", {row['cpu'] / rows['kept']['cpu']:.2f}x the above, {'same' if row['sha'] == rows['kept']['sha'] else 'OTHER'} bytes"
            print(f"  {what if how == 'kept' else '  the same, dumped':30} {row['seconds']:6.1f} s wall {row['cpu']:6.1f} s CPU "
                  f"({row['cpu'] / load['cpu']:4.2f}x the load's CPU; reading {row['read']:5.1f} s, ordering and writing "
                  f"{row['cpu'] - row['read']:5.1f} s) {row['bytes'] / 1e6:6.1f} MB, {row['rss_mb']:,.0f} MB peak{same}")
    shutil.rmtree(store_dir, ignore_errors=True)
    return on


def compare(kind: str, path: Path, repeat: int, baseline: str) -> dict[str, dict[str, float]]:
    """CPU of the ``baseline`` source tree's ``kind`` run ("parse", "load") and this one's, runs
    alternating (so that a change in the machine's load falls on both), each in a fresh process;
    returns the medians of each."""
    runs: dict[str, list[dict[str, Any]]] = {"baseline": [], "this code": []}
    for _ in range(repeat):
        for name, src in (("baseline", baseline), ("this code", None)):
            row = run_child(kind, str(path), src=src)
            assert row is not None, f"the {name} {kind} failed"
            runs[name].append(row)
    what = "parse only" if kind == "parse" else "whole load"
    print(f"  {what}, {repeat} runs each, alternating:  {'wall s':>8} {'CPU s':>8} {'best CPU':>9}")
    for name, rows in runs.items():
        print(f"  {name:42} {statistics.median(r['seconds'] for r in rows):8.2f} "
              f"{statistics.median(r['cpu'] for r in rows):8.2f} {min(r['cpu'] for r in rows):9.2f}")
    old, new = runs["baseline"], runs["this code"]
    print(f"  this code / baseline: {statistics.median(r['cpu'] for r in new) / statistics.median(r['cpu'] for r in old):.3f}x "
          f"median CPU, {min(r['cpu'] for r in new) / min(r['cpu'] for r in old):.3f}x best CPU, "
          f"{statistics.median(r['seconds'] for r in new) / statistics.median(r['seconds'] for r in old):.3f}x median wall",
          flush=True)
    return {name: {"cpu": statistics.median(r["cpu"] for r in rows),
                   "seconds": statistics.median(r["seconds"] for r in rows)} for name, rows in runs.items()}


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--sizes", type=int, nargs="+", default=[10_000, 100_000])
    ap.add_argument("--programs", nargs="+", choices=["generated", "replicated"], default=["generated", "replicated"])
    ap.add_argument("--repeat", type=int, default=3, help="runs per measurement below 1M instances (1M: 1 run)")
    ap.add_argument("--data", type=Path, default=Path(tempfile.gettempdir()) / "stepnc-graph-bench")
    ap.add_argument("--steputils-timeout", type=float, default=900)
    ap.add_argument("--profile-max", type=int, default=100_000,
                    help="largest size whose load is profiled and exported (0: none)")
    ap.add_argument("--real", type=Path, default=HERE.parent / "examples" / "shaft_two_setups.stp",
                    help="a real program to replicate beside the generated one (default: the shipped example)")
    ap.add_argument("--baseline", metavar="SRC",
                    help="also parse and load each program with the stepnc_graph of SRC (an older source tree's "
                         "src/), runs alternating with this code's, --repeat each: the ratios")
    ap.add_argument("--parse-only", action="store_true", help="measure the parse only (with --baseline: the ratio)")
    ap.add_argument("--child", nargs="+", help=argparse.SUPPRESS)
    args = ap.parse_args()
    if args.child:
        child(args.child[0], args.child[1], args.child[2:])
        return
    args.data.mkdir(parents=True, exist_ok=True)
    print(f"machine: {os.cpu_count()} cores, load average {os.getloadavg()[0]:.1f}; Python {sys.version.split()[0]}")
    runs = []
    for size in args.sizes:
        generated = args.data / f"turning_{size}.stp"
        real = args.data / (f"real_{size}.stp" if args.real.name == "shaft_two_setups.stp"
                            else f"real_{args.real.stem}_{size}.stp")
        if "generated" in args.programs:
            if not generated.exists():
                write(size, generated)
            runs.append(("generated", size, generated))
        if "replicated" in args.programs:
            if not real.exists():
                replicate(args.real, size, real)
            runs.append(("replicated", size, real))
    work = Path(tempfile.mkdtemp(prefix="stepnc-load-bench-", dir=args.data))
    try:
        for program, size, path in runs:
            repeat = 1 if size >= 1_000_000 else args.repeat
            print(f"\n== {program} program, {size:,} instances ({path.name}, {path.stat().st_size / 1e6:.1f} MB)",
                  flush=True)
            if args.baseline:
                compare("parse", path, repeat, args.baseline)
            if args.parse_only:
                if not args.baseline:
                    row = measure("parse", path, repeat, 3600)
                    assert row is not None
                    print(f"  stepnc-graph parse: {row['seconds']:.2f} s wall, {row['cpu']:.2f} CPU-s (medians)")
                continue
            ref = measure("steputils", path, repeat, args.steputils_timeout)
            parse = measure("parse", path, repeat, 3600)
            load = measure("load", path, repeat, 3600)
            base = compare("load", path, repeat, args.baseline) if args.baseline else None
            alone = measure("store", path, repeat, 3600)
            assert parse is not None and load is not None and alone is not None
            nquads = work / f"{program}-{size}.nq"
            on = profile(program, path, work, load, nquads) if size <= args.profile_max else None
            if on is None:  # the quads of a load, dumped for the reference
                on = run_child("profile", str(path), str(work / "dump"), str(nquads))
                shutil.rmtree(work / "dump", ignore_errors=True)
            bulk = measure("bulk", nquads, repeat, 3600) if on is not None else None
            nquads.unlink(missing_ok=True)
            print(f"\n  {'':28} {'wall s':>8} {'CPU s':>8} {'inst/s':>9} {'peak MB':>8}")
            if ref:
                print(f"  {'steputils parse':28} {ref['seconds']:8.2f} {ref['cpu']:8.2f} {ref['rate']:9,.0f} "
                      f"{ref['rss_mb']:8,.0f}")
            else:
                print(f"  {'steputils parse':28} {'timed out':>8}")
            for name, row in (("stepnc-graph parse", parse), ("end-to-end load", load), ("store alone", alone)):
                print(f"  {name:28} {row['seconds']:8.2f} {row['cpu']:8.2f} {row['rate']:9,.0f} {row['rss_mb']:8,.0f}")
            if bulk:
                print(f"  {'pyoxigraph bulk load':28} {bulk['seconds']:8.2f} {bulk['cpu']:8.2f} "
                      f"{load['count'] / bulk['seconds']:9,.0f} {bulk['rss_mb']:8,.0f}   "
                      f"({bulk['count']:,} quads: the load's, dumped)")
                ratio = load["seconds"] / bulk["seconds"]
                print(f"  load / pyoxigraph bulk load: {ratio:.2f}x wall ({bulk['seconds'] / load['seconds']:.2f} of "
                      f"the ceiling; target >= 0.85), {load['cpu'] / bulk['cpu']:.2f}x CPU, "
                      f"{load['rss_mb'] / bulk['rss_mb']:.2f}x peak memory"
                      + (f"; load / steputils parse {load['seconds'] / ref['seconds']:.2f}x wall" if ref else ""),
                      flush=True)
                if base:
                    print(f"  alternating runs against pyoxigraph bulk load: this code {base['this code']['cpu'] / bulk['cpu']:.2f}x "
                          f"CPU, baseline {base['baseline']['cpu'] / bulk['cpu']:.2f}x CPU", flush=True)
    finally:
        shutil.rmtree(work, ignore_errors=True)
    print("\nmedians of --repeat runs, each in a fresh process; 'peak MB' is that process's maximum RSS; steputils\n"
          "and stepnc-graph parse only; 'store alone' writes the already-mapped N-Triples with the loader's store\n"
          "code; 'replicated' is copies of a real program (its mix of entities; fewer triples per instance).")


if __name__ == "__main__":
    main()
