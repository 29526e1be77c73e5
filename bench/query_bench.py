"""Query benchmark: the cost of the derived layer at load time, and every library query's speed.

    pip install -e '.[bench]' && python bench/query_bench.py                 # 100k instances
    python bench/query_bench.py --sizes 100000 1000000 --rdflib-max 100000     # add 1M (Oxigraph only)

For each size, on one program written by bench/generate.py and in one run:

* **load**: the end-to-end load into an on-disk store with the derived layer, and the same load with
  the derivation switched off (the vocabulary graph already in the store in both), each in a fresh
  process, alternating, ``--load-repeat`` times: median wall seconds, CPU seconds, the instance rate,
  and the rate drop; data and derived triple counts. The one-off cost of writing the vocabulary
  graph into an empty store is printed apart.
* **queries**: every library query (and ``workingsteps-by-tool-type`` with a tool type every step
  matches) on the loaded on-disk store: one warm-up, then ``--repeat`` runs, median wall and CPU
  milliseconds, for running the query and writing its SPARQL 1.1 JSON results (what `stepnc-graph
  query --format json` does). Next to it, up to ``--rdflib-max`` instances, the same query text on
  an rdflib in-memory ``Dataset`` holding the same quads (the file's graph as a named graph, its
  derived layer and the vocabulary in the default graph, union default on: the semantics Oxigraph
  gets), with a per-query time limit; the ratio; and whether the targets (<= 100 ms median at 100k
  instances, <= 1 s at 1M, >= 20x rdflib) are met. Row counts of both engines are compared.

The machine is shared: read CPU seconds beside wall seconds.
"""

from __future__ import annotations

import argparse
import json
import os
import shutil
import signal
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path
from typing import Any

HERE = Path(__file__).resolve().parent
sys.path.insert(0, str(HERE))

from generate import write  # noqa: E402

EXAMPLE = HERE.parent / "examples" / "shaft_two_setups.stp"
#: A query variant every generated workingstep matches (the default grooving_tool matches none).
VARIANTS = [("workingsteps-by-tool-type", {"tool_type": "general_turning_tool"})]


# -- children (one measurement per process) ---------------------------------------------------------


def child_load(path: str, store_dir: str, derive: str) -> None:
    """Load ``path`` into a store that already holds the vocabulary; print seconds as JSON."""
    import stepnc_graph as sg
    import stepnc_graph.loader as loader
    from stepnc_graph.derive import iso14649_rules
    from stepnc_graph.schema.catalog import iso14649
    from stepnc_graph.vocabulary import ensure_vocabulary

    iso14649()
    iso14649_rules()  # the model and rules are built once per process, not per file
    if derive == "off":
        class _Nothing:
            triples = 0

        class _NoTables:
            @staticmethod
            def tables() -> None:
                return None  # the mapper writes no layer lines either

        loader.derive = lambda *args, **kwargs: _Nothing()  # type: ignore[assignment]
        loader.iso14649_rules = lambda: _NoTables()  # type: ignore[assignment]
    with sg.open_store(store_dir) as store:
        started = time.perf_counter()
        ensure_vocabulary(store)  # a store gets it once, with its first load
        vocabulary = time.perf_counter() - started
        wall, cpu = time.perf_counter(), time.process_time()
        [result] = sg.load(store, [path])
        wall, cpu = time.perf_counter() - wall, time.process_time() - cpu
    print(json.dumps({"wall": wall, "cpu": cpu, "instances": result.instances, "triples": result.triples,
                      "derived": result.derived_triples, "vocabulary": vocabulary}))


def child_rdflib(store_dir: str, graph: str, timeout: float, names: list[str]) -> None:
    """Run the library on an rdflib Dataset holding the store's quads; print one JSON line per query."""
    import rdflib
    import pyoxigraph as ox

    from stepnc_graph.naming import derived_graph_iri
    from stepnc_graph.query import PREFIXES, resolve
    from stepnc_graph.store import GraphStore

    started = time.perf_counter()
    ds = rdflib.Dataset(default_union=True)
    with GraphStore(store_dir) as store:
        file_graph = ds.graph(rdflib.URIRef(graph))
        file_graph.parse(data=store.dump(ox.RdfFormat.N_TRIPLES, graph).decode(), format="nt")
        for other in (derived_graph_iri(graph), "https://w3id.org/stepnc-graph/iso14649"):
            ds.default_graph.parse(data=store.dump(ox.RdfFormat.N_TRIPLES, other).decode(), format="nt")
    print(json.dumps({"loaded": time.perf_counter() - started, "quads": len(ds)}), flush=True)

    def alarm(*_: Any) -> None:
        raise TimeoutError

    signal.signal(signal.SIGALRM, alarm)
    for spec in names:
        name, _, params = spec.partition("?")
        query = resolve(name)
        bindings = {}
        for p in query.params:
            value = dict(pair.split("=", 1) for pair in params.split("&") if pair).get(p.name, p.default)
            bindings[p.name] = rdflib.URIRef(PREFIXES["stepnc"] + str(value))
        signal.alarm(int(timeout))
        wall, cpu = time.perf_counter(), time.process_time()
        try:
            result = ds.query(query.text, initBindings=bindings)
            data = result.serialize(format="json")
            rows = len(json.loads(data)["results"]["bindings"])
            wall, cpu = time.perf_counter() - wall, time.process_time() - cpu
            out: dict[str, Any] = {"name": spec, "wall": wall, "cpu": cpu, "rows": rows}
        except TimeoutError:
            out = {"name": spec, "timeout": timeout}
        except Exception as exc:  # noqa: BLE001 -- reported, the benchmark goes on
            out = {"name": spec, "error": f"{type(exc).__name__}: {str(exc)[:120]}"}
        finally:
            signal.alarm(0)
        print(json.dumps(out), flush=True)


# -- the measurements ------------------------------------------------------------------------------


def run_child(*args: str, timeout: float = 7200) -> list[dict[str, Any]]:
    done = subprocess.run([sys.executable, __file__, "--child", *args], capture_output=True, text=True,
                          timeout=timeout)
    if done.returncode != 0:
        raise RuntimeError(done.stderr.strip().splitlines()[-1] if done.stderr.strip() else "child failed")
    return [json.loads(line) for line in done.stdout.splitlines() if line.startswith("{")]


def measure_loads(path: Path, work: Path, repeat: int) -> dict[str, list[dict[str, Any]]]:
    runs: dict[str, list[dict[str, Any]]] = {"on": [], "off": []}
    for i in range(repeat):
        for mode in ("off", "on"):
            store_dir = work / f"load-{mode}-{i}"
            [row] = run_child("load", str(path), str(store_dir), mode)
            runs[mode].append(row)
            shutil.rmtree(store_dir, ignore_errors=True)
    return runs


def specs() -> list[str]:
    from stepnc_graph.query import library

    names = [q.name for q in library()]
    return names + [f"{n}?{'&'.join(f'{k}={v}' for k, v in p.items())}" for n, p in VARIANTS]


def measure_queries(store_dir: Path, repeat: int) -> dict[str, dict[str, Any]]:
    from stepnc_graph.query import execute, resolve
    from stepnc_graph.store import GraphStore

    out = {}
    with GraphStore(store_dir) as store:
        for spec in specs():
            name, _, params = spec.partition("?")
            query = resolve(name)
            given = dict(pair.split("=", 1) for pair in params.split("&") if pair)
            rows = len(json.loads(execute(store, query, given).serialize("json"))["results"]["bindings"])  # warm-up
            walls, cpus = [], []
            for _ in range(repeat):
                wall, cpu = time.perf_counter(), time.process_time()
                execute(store, query, given).serialize("json")
                walls.append(time.perf_counter() - wall)
                cpus.append(time.process_time() - cpu)
            out[spec] = {"wall": statistics.median(walls), "cpu": statistics.median(cpus), "rows": rows}
    return out


def report_load(size: int, runs: dict[str, list[dict[str, Any]]]) -> None:
    def med(mode: str, key: str) -> float:
        return statistics.median(r[key] for r in runs[mode])

    on, off = med("on", "wall"), med("off", "wall")
    first = runs["on"][0]
    rate_on, rate_off = first["instances"] / on, first["instances"] / off
    print(f"\nload of {first['instances']:,} instances ({len(runs['on'])} runs each, fresh process per run)")
    print(f"  without derived layer: {off:7.2f} s wall {med('off', 'cpu'):7.2f} s CPU  {rate_off:>9,.0f} inst/s")
    print(f"  with derived layer:    {on:7.2f} s wall {med('on', 'cpu'):7.2f} s CPU  {rate_on:>9,.0f} inst/s")
    print(f"  rate drop {100 * (1 - rate_on / rate_off):.1f} % (target <= 15 %); CPU "
          f"+{100 * (med('on', 'cpu') / med('off', 'cpu') - 1):.1f} %; triples: {first['triples']:,} data, "
          f"{first['derived']:,} derived (+{100 * first['derived'] / first['triples']:.1f} %)")
    print(f"  writing the vocabulary graph into an empty store (once per store): "
          f"{statistics.median(r['vocabulary'] for r in runs['on']):.2f} s")


def report_queries(size: int, ox_times: dict[str, dict[str, Any]]) -> list[str]:
    """Print the Oxigraph timings now (rdflib's follow as they come); return the queries over time."""
    target = 0.1 if size <= 100_000 else 1.0
    print(f"\nqueries at {size:,} instances, on-disk Oxigraph (target <= {target * 1000:.0f} ms median)")
    print(f"  {'query':58} {'rows':>6} {'wall ms':>8} {'CPU ms':>8}  verdict")
    misses = []
    for spec, t in ox_times.items():
        ok = t["wall"] <= target
        if not ok:
            misses.append(spec)
        print(f"  {spec:58} {t['rows']:>6} {t['wall'] * 1000:>8,.1f} {t['cpu'] * 1000:>8,.1f}  "
              f"{'ok' if ok else 'MISS time'}", flush=True)
    print(f"  {len(ox_times) - len(misses)} of {len(ox_times)} within {target * 1000:.0f} ms" +
          (f"; over: {', '.join(misses)}" if misses else ""), flush=True)
    return misses


def stream_rdflib(store_dir: Path, graph: str, timeout: float, ox_times: dict[str, dict[str, Any]]) -> None:
    """Run the library in rdflib (a child process) and print each query's ratio as it finishes."""
    proc = subprocess.Popen([sys.executable, __file__, "--child", "rdflib", str(store_dir), graph, str(timeout),
                             *ox_times], stdout=subprocess.PIPE, text=True)
    assert proc.stdout is not None
    slow = []
    for line in proc.stdout:
        if not line.startswith("{"):
            continue
        row = json.loads(line)
        if "loaded" in row:
            print(f"\nrdflib in-memory Dataset, same quads: {row['quads']:,} parsed in {row['loaded']:.0f} s; "
                  f"per query (time limit {timeout:.0f} s; target >= 20x)")
            print(f"  {'query':58} {'rdflib ms':>10} {'Oxigraph ms':>11} {'ratio':>8}  verdict")
            continue
        t = ox_times[row["name"]]
        if "wall" in row:
            ratio, rdf_text = row["wall"] / t["wall"], f"{row['wall'] * 1000:>10,.0f}"
            note = "" if row["rows"] == t["rows"] else f" (rdflib rows {row['rows']} != {t['rows']})"
        elif "timeout" in row:
            ratio, rdf_text, note = row["timeout"] / t["wall"], f">{row['timeout'] * 1000:>9,.0f}", " (time limit)"
        else:
            ratio, rdf_text, note = 0.0, f"{'error':>10}", f" {row['error']}"
        if ratio < 20:
            slow.append(row["name"])
        print(f"  {row['name']:58} {rdf_text} {t['wall'] * 1000:>11,.1f} {ratio:>7,.0f}x  "
              f"{'ok' if ratio >= 20 else 'MISS ratio'}{note}", flush=True)
    proc.wait()
    print(f"  {len(ox_times) - len(slow)} of {len(ox_times)} at least 20x faster than rdflib" +
          (f"; not: {', '.join(slow)}" if slow else ""))


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--sizes", type=int, nargs="+", default=[100_000])
    ap.add_argument("--repeat", type=int, default=5, help="timed runs per query (after one warm-up)")
    ap.add_argument("--load-repeat", type=int, default=3, help="loads with and without the layer (1M: 1; 0: skip)")
    ap.add_argument("--rdflib-max", type=int, default=100_000, help="largest size also run in rdflib")
    ap.add_argument("--rdflib-timeout", type=float, default=120, help="seconds per rdflib query")
    ap.add_argument("--data", type=Path, default=Path(tempfile.gettempdir()) / "stepnc-graph-bench")
    ap.add_argument("--child", nargs="+", help=argparse.SUPPRESS)
    args = ap.parse_args()
    if args.child:
        kind, rest = args.child[0], args.child[1:]
        if kind == "load":
            child_load(*rest)
        else:
            child_rdflib(rest[0], rest[1], float(rest[2]), rest[3:])
        return
    args.data.mkdir(parents=True, exist_ok=True)
    print(f"machine: {os.cpu_count()} cores, load average {os.getloadavg()[0]:.1f}; Python {sys.version.split()[0]}")
    for size in args.sizes:
        path = args.data / f"turning_{size}.stp"
        if not path.exists():
            write(size, path)
        work = Path(tempfile.mkdtemp(prefix="stepnc-query-bench-", dir=args.data))
        try:
            if args.load_repeat > 0:  # 0: queries only
                report_load(size, measure_loads(path, work, 1 if size >= 1_000_000 else args.load_repeat))
            store_dir = work / "store"
            run_child("load", str(path), str(store_dir), "on")
            ox_times = measure_queries(store_dir, args.repeat)
            report_queries(size, ox_times)
            if size <= args.rdflib_max:
                from stepnc_graph.naming import default_graph_iri

                stream_rdflib(store_dir, default_graph_iri(str(path)), args.rdflib_timeout, ox_times)
        finally:
            shutil.rmtree(work, ignore_errors=True)


if __name__ == "__main__":
    main()
