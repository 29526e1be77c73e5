"""Query benchmark: the cost of the derived layer at load time, and every library query's speed.

    pip install -e '.[bench]' && python bench/query_bench.py                 # 100k instances
    python bench/query_bench.py --sizes 100000 1000000 --rdflib-max 100000     # add 1M (Oxigraph only)
    python bench/query_bench.py --programs replicated --copies 3 --load-repeat 0 --rdflib-max 0
    mkdir /tmp/before && git archive HEAD~1 queries | tar -x -C /tmp/before   # an earlier library ...
    python bench/query_bench.py --baseline /tmp/before/queries                # ... timed beside this one
    python bench/query_bench.py --programs replicated --load-repeat 0 --split   # where a query's time goes

For each size and program, in one run. The programs (``--programs``, default both) are those of
bench/generate.py: ``generated`` (``write()``: a turning program of one setup and a few tools,
geometry-heavy) and ``replicated`` (``replicate()`` of a real program, the shipped two-setup shaft
unless ``--real`` names another: copies of it renumbered, so the store holds a setup and its tools
for every copy -- 2,250 setups and tools at 100k instances -- and about five times the
generated program's workingsteps per instance). ``--copies N`` loads N copies of the program
under different graph IRIs (the first under the file's own), so the queries run on a store
holding several programs; the load figures stay those of one program. Beside them the store holds
the real program itself (``--real``) under its own graph: ``--graph`` queries run on it.

* **load**: the end-to-end load into an on-disk store with the derived layer, and the same load with
  the derivation switched off (the vocabulary graph already in the store in both), each in a fresh
  process, alternating, ``--load-repeat`` times: median wall seconds, CPU seconds, the instance rate,
  and the rate drop; data and derived triple counts. The one-off cost of writing the vocabulary
  graph into an empty store is printed apart.
* **queries**: every library query (and ``workingsteps-by-tool-type`` with a tool type every step
  matches) on the loaded on-disk store, whole store, then with ``--graph`` on the real program: one
  warm-up, then ``--repeat`` runs, median wall milliseconds and CPU milliseconds of the thread that
  runs the query (RocksDB's background threads left out), for running the query and writing its
  SPARQL 1.1 JSON results (what `stepnc-graph query --format json` does). Next to it, up to
  ``--rdflib-max`` instances, the same query text on an rdflib in-memory ``Dataset`` holding the same
  quads (the files' graphs as named graphs, their derived layers and the vocabulary in the default
  graph, union default on: the semantics Oxigraph gets), with a per-query time limit; the ratio; and
  whether the targets are met: whole store <= 200 ms CPU median up to 100k instances, <= 1 s at
  1M, ``--graph`` <= 20 ms, >= 20x rdflib (with ``--copies`` above 1 the whole-store figures are
  reported, not judged). Row counts of both engines are compared. rdflib runs when the store holds
  at most ``--rdflib-max`` instances in all.
* with ``--baseline DIR`` (a directory of ``.rq`` files, e.g. an earlier ``queries/``): each query
  of that library too, alternating with the current one query by query, each in its own process;
  the two results' SPARQL JSON are compared byte for byte (same rows in the same order).

* with ``--split``: where each query's time goes (whole store, one child process per query, median of
  ``--repeat`` after a warm-up, CPU of the querying thread): Oxigraph evaluating it without writing
  a value (the query as a sub-SELECT of ``SELECT (COUNT(*) AS ?rows)``), evaluating it and writing
  its SPARQL JSON in pyoxigraph (``QuerySolutions.serialize``, all in Rust), the project's
  ``execute(...).serialize("json")`` (what the other figures time: the same JSON, plus the dataset,
  the parameters and the warnings), and its CSV (``query --format csv``).

Each library's query runs in a child process: a run over ``--query-timeout`` seconds is stopped
and reported as ``>limit`` with the child's CPU time when stopped (start-up included) in
parentheses; a query over 30 s in its warm-up is timed once, not ``--repeat`` times.

The machine is shared: read CPU seconds beside wall seconds.
"""

from __future__ import annotations

import argparse
import hashlib
import json
import os
import select
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

from generate import program_file  # noqa: E402

EXAMPLE = HERE.parent / "examples" / "shaft_two_setups.stp"
#: A warm-up over this many seconds: the query is timed once instead of ``--repeat`` times.
SLOW = 30.0
#: A query variant every generated workingstep matches (the default grooving_tool matches none).
VARIANTS = [("workingsteps-by-tool-type", {"tool_type": "general_turning_tool"})]


# -- children (one measurement per process) ---------------------------------------------------------


def child_load(path: str, store_dir: str, derive: str, graph: str | None = None) -> None:
    """Load ``path`` (under ``graph``, else its own graph IRI) into a store that already holds the
    vocabulary; print seconds as JSON."""
    import stepnc_graph as sg
    import stepnc_graph.loading.loader as loader
    from stepnc_graph.loading.derive import iso14649_rules
    from stepnc_graph.schema.catalog import iso14649
    from stepnc_graph.graphs.vocabulary_graph import ensure_vocabulary

    iso14649()
    iso14649_rules()  # the model and rules are built once per process, not per file
    if derive == "off":
        from load_bench import switch_off_derived_layer

        switch_off_derived_layer(loader)
    with sg.open_store(store_dir) as store:
        started = time.perf_counter()
        ensure_vocabulary(store)  # a store gets it once, with its first load
        vocabulary = time.perf_counter() - started
        wall, cpu = time.perf_counter(), time.process_time()
        [result] = sg.load(store, [path], base_iri=graph)
        wall, cpu = time.perf_counter() - wall, time.process_time() - cpu
    print(json.dumps({"wall": wall, "cpu": cpu, "instances": result.instances, "triples": result.triples,
                      "derived": result.derived_triples, "vocabulary": vocabulary}))


def child_rdflib(store_dir: str, graphs: str, timeout: float, names: list[str]) -> None:
    """Run the library on an rdflib Dataset holding the store's quads (``graphs``: the programs'
    graph IRIs, comma-separated); print one JSON line per query."""
    import rdflib
    import pyoxigraph as ox

    from stepnc_graph.core.naming import derived_graph_iri
    from stepnc_graph.querying.query import PREFIXES, resolve
    from stepnc_graph.store import GraphStore

    started = time.perf_counter()
    ds = rdflib.Dataset(default_union=True)
    with GraphStore(store_dir) as store:
        for graph in graphs.split(","):
            file_graph = ds.graph(rdflib.URIRef(graph))
            file_graph.parse(data=store.dump(ox.RdfFormat.N_TRIPLES, graph).decode(), format="nt")
            ds.default_graph.parse(data=store.dump(ox.RdfFormat.N_TRIPLES, derived_graph_iri(graph)).decode(),
                                   format="nt")
        ds.default_graph.parse(data=store.dump(ox.RdfFormat.N_TRIPLES, "https://w3id.org/stepnc-graph/iso14649")
                               .decode(), format="nt")
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
    from stepnc_graph.querying.query import library

    names = [q.name for q in library()]
    return names + [f"{n}?{'&'.join(f'{k}={v}' for k, v in p.items())}" for n, p in VARIANTS]


def child_queries(store_dir: str, directory: str, spec: str, repeat: int, graph: str | None = None) -> None:
    """Run one query of the library in ``directory`` (warm-up, then ``repeat`` timed runs, once if
    the warm-up is over SLOW seconds), each run the query and its SPARQL JSON, over the whole store
    or one ``graph``; print one JSON line per run: wall and CPU seconds (of this thread, which runs
    the query: not RocksDB's background work), rows and the SHA-256 of the JSON (the warm-up's)."""
    from stepnc_graph.querying.query import execute, resolve
    from stepnc_graph.store import GraphStore

    name, _, params = spec.partition("?")
    given = dict(pair.split("=", 1) for pair in params.split("&") if pair)
    with GraphStore(store_dir) as store:
        query = resolve(name, Path(directory))
        print(json.dumps({"ready": True}), flush=True)  # the time limit counts from here
        for run in range(repeat + 1):
            wall, cpu = time.perf_counter(), time.thread_time()
            data = execute(store, query, given, graph).serialize("json")
            wall, cpu = time.perf_counter() - wall, time.thread_time() - cpu
            out: dict[str, Any] = {"wall": wall, "cpu": cpu}
            if run == 0:
                out |= {"rows": len(json.loads(data)["results"]["bindings"]), "sha256": hashlib.sha256(data).hexdigest()}
            print(json.dumps(out), flush=True)
            if run == 0 and wall > SLOW:
                repeat = 1


def child_split(store_dir: str, spec: str, repeat: int) -> None:
    """Where ``spec``'s time goes over the whole store (see the module's ``--split``): print one JSON
    line of median CPU seconds of this thread, after a warm-up of each."""
    import pyoxigraph as ox

    from stepnc_graph.querying.query import PREFIXES, bind, dataset, execute, resolve
    from stepnc_graph.store import GraphStore

    name, _, params = spec.partition("?")
    given = dict(pair.split("=", 1) for pair in params.split("&") if pair)
    with GraphStore(store_dir) as store:
        query = resolve(name)
        options = {**dataset(store, None, query.library), "prefixes": PREFIXES,
                   "substitutions": bind(store, query, given) or None}
        head, select = query.text.split("\nSELECT", 1)
        params = " ".join(f"?{p.name}" for p in query.params)  # a parameter is bound where it is SELECTed
        counted = (f"{head}\nSELECT {params} (COUNT(*) AS ?rows) WHERE {{ SELECT{select}\n}}"
                   + (f" GROUP BY {params}" if params else ""))
        raw = store.oxigraph  # pyoxigraph itself, the project's layer left out

        def rows() -> int:
            return sum(int(row["rows"].value) for row in raw.query(counted, **options))

        def rust_json() -> int:
            return len(raw.query(query.text, **options).serialize(format=ox.QueryResultsFormat.JSON) or b"")

        def project(fmt: str) -> int:
            return len(execute(store, query, given).serialize(fmt))

        out: dict[str, Any] = {"name": spec}
        for key, fn in (("evaluate", rows), ("rust_json", rust_json), ("execute_json", lambda: project("json")),
                        ("execute_csv", lambda: project("csv"))):
            result, times = fn(), []  # the warm-up
            for _ in range(repeat):
                cpu = time.thread_time()
                fn()
                times.append(time.thread_time() - cpu)
            out[key] = statistics.median(times)
            out.setdefault("rows", result)
        print(json.dumps(out), flush=True)


def measure_split(store_dir: Path, repeat: int) -> None:
    """Print where each library query's time goes (``--split``), one child process per query."""
    print("\nwhere the time goes, whole store (CPU ms, median): evaluation alone (COUNT of the rows), + Oxigraph "
          "writing SPARQL JSON (Rust), the project's execute + JSON (the timed path above), its CSV")
    print(f"  {'query':58} {'rows':>6} {'evaluate':>9} {'Rust JSON':>10} {'execute+JSON':>13} {'CSV':>8}  "
          f"{'evaluation share':>16}", flush=True)
    for spec in specs():
        try:
            [row] = run_child("split", str(store_dir), spec, str(repeat))
        except (RuntimeError, subprocess.TimeoutExpired) as exc:
            print(f"  {spec:58} failed: {exc}", flush=True)
            continue
        ms = {k: row[k] * 1000 for k in ("evaluate", "rust_json", "execute_json", "execute_csv")}
        print(f"  {spec:58} {row['rows']:>6} {ms['evaluate']:9.1f} {ms['rust_json']:10.1f} {ms['execute_json']:13.1f} "
              f"{ms['execute_csv']:8.1f}  {ms['evaluate'] / ms['execute_json']:15.0%}", flush=True)


def _cpu_seconds(pid: int) -> float | None:
    """CPU seconds a running process has used so far (Linux /proc), None where unknown."""
    try:
        fields = Path(f"/proc/{pid}/stat").read_text().rsplit(")", 1)[1].split()
        return (int(fields[11]) + int(fields[12])) / os.sysconf("SC_CLK_TCK")  # utime, stime
    except (OSError, ValueError, IndexError):
        return None


def time_query(store_dir: Path, directory: Path, spec: str, repeat: int, timeout: float,
               graph: str | None = None) -> dict[str, Any]:
    """Median wall and CPU seconds of ``spec`` from ``directory`` (a child process), over the whole
    store or one ``graph``; a run over ``timeout`` seconds stops it: ``{"timeout": seconds}`` then."""
    proc = subprocess.Popen([sys.executable, __file__, "--child", "queries", str(store_dir), str(directory), spec,
                             str(repeat), *([graph] if graph else [])],
                            stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    assert proc.stdout is not None
    runs: list[dict[str, Any]] = []
    started = False
    try:
        while True:
            ready, _, _ = select.select([proc.stdout], [], [], timeout if started else max(timeout, 600))
            if not ready:  # the run in progress is over the limit
                return {"timeout": timeout, "cpu_at_stop": _cpu_seconds(proc.pid), "runs": len(runs)}
            line = proc.stdout.readline()
            if not line:
                break
            row = json.loads(line)
            if row.get("ready"):
                started = True
            else:
                runs.append(row)
    finally:
        if proc.poll() is None:
            proc.kill()
        _, err = proc.communicate()
    if proc.returncode != 0 or len(runs) < 2:
        raise RuntimeError(f"{spec} from {directory}: " + (err.strip().splitlines()[-1] if err.strip() else "failed"))
    timed = runs[1:]
    return {"wall": statistics.median(r["wall"] for r in timed), "cpu": statistics.median(r["cpu"] for r in timed),
            "rows": runs[0]["rows"], "sha256": runs[0]["sha256"], "runs": len(timed)}


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


def _ms(t: dict[str, Any], key: str) -> str:
    """Milliseconds; for a run stopped at the limit, the limit (wall) and the process's CPU time
    then, start-up included, in parentheses."""
    if "timeout" not in t:
        return f"{t[key] * 1000:,.1f}"
    if key == "wall":
        return f">{t['timeout'] * 1000:,.0f}"
    return f"({t['cpu_at_stop'] * 1000:,.0f})" if t.get("cpu_at_stop") is not None else "-"


def measure_queries(title: str, store_dir: Path, repeat: int, timeout: float, baseline: Path | None,
                    target: float | None, graph: str | None = None) -> dict[str, dict[str, Any]]:
    """Time every library query on the store or one ``graph`` (alternating with the baseline
    library's, if any), printing each as it is done; return the current library's figures.
    ``target``: the median CPU seconds a query must not exceed (None: report only)."""
    from stepnc_graph.core.resources import queries_dir

    print(f"\nqueries on {title}, on-disk Oxigraph (" +
          (f"target <= {target * 1000:.0f} ms CPU median" if target else "no target: figures only") + ")")
    head = f"  {'query':58} {'rows':>6} {'wall ms':>10} {'CPU ms':>10}"
    if baseline is not None:
        head += f" | {'baseline wall':>13} {'CPU ms':>10} {'rows':>6}  same JSON"
    print(head + ("  verdict" if target else ""), flush=True)
    times, misses, differ = {}, [], []
    for spec in specs():
        before = None
        if baseline is not None and (baseline / f"{spec.partition('?')[0]}.rq").is_file():
            before = time_query(store_dir, baseline, spec, repeat, timeout, graph)
        t = times[spec] = time_query(store_dir, queries_dir(), spec, repeat, timeout, graph)
        line = f"  {spec:58} {t.get('rows', '-'):>6} {_ms(t, 'wall'):>10} {_ms(t, 'cpu'):>10}"
        if baseline is not None:
            if before is None:
                line += f" | {'(not in baseline)':>31}"
            else:
                same = "yes" if "sha256" in t and t["sha256"] == before.get("sha256") else (
                    "?" if "timeout" in t or "timeout" in before else "NO")
                if same == "NO":
                    differ.append(spec)
                line += f" | {_ms(before, 'wall'):>13} {_ms(before, 'cpu'):>10} {before.get('rows', '-'):>6}  {same}"
        if target:
            ok = "cpu" in t and t["cpu"] <= target
            if not ok:
                misses.append(spec)
            line += "  " + ("ok" if ok else f"MISS time ({t['cpu'] / target:.1f}x)" if "cpu" in t else "MISS time")
        print(line, flush=True)
    if target:
        print(f"  {len(times) - len(misses)} of {len(times)} within {target * 1000:.0f} ms CPU" +
              (f"; over: {', '.join(misses)}" if misses else ""), flush=True)
    if baseline is not None:
        print("  results differing from the baseline's: " + (", ".join(differ) if differ else "none"), flush=True)
    return times


def stream_rdflib(store_dir: Path, graphs: list[str], timeout: float, ox_times: dict[str, dict[str, Any]]) -> None:
    """Run the library in rdflib (a child process) and print each query's ratio as it finishes."""
    proc = subprocess.Popen([sys.executable, __file__, "--child", "rdflib", str(store_dir), ",".join(graphs),
                             str(timeout), *ox_times], stdout=subprocess.PIPE, text=True)
    assert proc.stdout is not None
    slow = []
    for line in proc.stdout:
        if not line.startswith("{"):
            continue
        row = json.loads(line)
        if "loaded" in row:
            print(f"\nrdflib in-memory Dataset, same quads: {row['quads']:,} parsed in {row['loaded']:.0f} s; "
                  f"per query, CPU (time limit {timeout:.0f} s; target >= 20x)")
            print(f"  {'query':58} {'rdflib ms':>10} {'Oxigraph ms':>11} {'ratio':>8}  verdict")
            continue
        t = ox_times[row["name"]]
        if "cpu" not in t:  # Oxigraph was stopped at its time limit: no ratio
            slow.append(row["name"])
            rdf = f"{row['cpu'] * 1000:>10,.0f}" if "cpu" in row else f"{'-':>10}"
            print(f"  {row['name']:58} {rdf} {_ms(t, 'wall'):>11} {'-':>8}  (Oxigraph over its time limit)")
            continue
        if "cpu" in row:
            ratio, rdf_text = row["cpu"] / t["cpu"], f"{row['cpu'] * 1000:>10,.0f}"
            note = "" if row["rows"] == t["rows"] else f" (rdflib rows {row['rows']} != {t['rows']})"
        elif "timeout" in row:
            ratio, rdf_text, note = row["timeout"] / t["cpu"], f">{row['timeout'] * 1000:>9,.0f}", " (time limit)"
        else:
            ratio, rdf_text, note = 0.0, f"{'error':>10}", f" {row['error']}"
        if ratio < 20:
            slow.append(row["name"])
        print(f"  {row['name']:58} {rdf_text} {t['cpu'] * 1000:>11,.1f} {ratio:>7,.0f}x  "
              f"{'ok' if ratio >= 20 else 'MISS ratio'}{note}", flush=True)
    proc.wait()
    print(f"  {len(ox_times) - len(slow)} of {len(ox_times)} at least 20x faster than rdflib" +
          (f"; not: {', '.join(slow)}" if slow else ""))


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--sizes", type=int, nargs="+", default=[100_000])
    ap.add_argument("--programs", nargs="+", choices=["generated", "replicated"], default=["generated", "replicated"],
                    help="bench/generate.py's generated program, a replicated real one, or both (default)")
    ap.add_argument("--real", type=Path, default=EXAMPLE,
                    help="the real program to replicate (default: the shipped two-setup shaft)")
    ap.add_argument("--copies", type=int, default=1,
                    help="copies of the program in the store, each under its own graph IRI (default 1)")
    ap.add_argument("--repeat", type=int, default=5, help="timed runs per query (after one warm-up)")
    ap.add_argument("--query-timeout", type=float, default=300, help="seconds a query run may take (Oxigraph)")
    ap.add_argument("--baseline", type=Path, help="a directory of .rq files to time beside the library")
    ap.add_argument("--load-repeat", type=int, default=3, help="loads with and without the layer (1M: 1; 0: skip)")
    ap.add_argument("--rdflib-max", type=int, default=100_000,
                    help="largest store (instances, all copies) also run in rdflib; 0: never")
    ap.add_argument("--rdflib-timeout", type=float, default=120, help="seconds per rdflib query")
    ap.add_argument("--split", action="store_true",
                    help="also print where each query's time goes: evaluation, Oxigraph's JSON, the project's output")
    ap.add_argument("--data", type=Path, default=Path(tempfile.gettempdir()) / "stepnc-graph-bench")
    ap.add_argument("--child", nargs="+", help=argparse.SUPPRESS)
    args = ap.parse_args()
    if args.child:
        kind, rest = args.child[0], args.child[1:]
        if kind == "load":
            child_load(*rest)
        elif kind == "queries":
            child_queries(rest[0], rest[1], rest[2], int(rest[3]), rest[4] if len(rest) > 4 else None)
        elif kind == "split":
            child_split(rest[0], rest[1], int(rest[2]))
        else:
            child_rdflib(rest[0], rest[1], float(rest[2]), rest[3:])
        return
    if args.copies < 1:
        ap.error("--copies must be at least 1")
    if args.baseline is not None and not any(args.baseline.glob("*.rq")):
        ap.error(f"--baseline {args.baseline}: no .rq files there")
    from stepnc_graph.core.naming import default_graph_iri

    args.data.mkdir(parents=True, exist_ok=True)
    print(f"machine: {os.cpu_count()} cores, load average {os.getloadavg()[0]:.1f}; Python {sys.version.split()[0]}")
    for size in args.sizes:
        for program in args.programs:
            path = program_file(args.data, program, size, args.real)
            work = Path(tempfile.mkdtemp(prefix="stepnc-query-bench-", dir=args.data))
            try:
                print(f"\n== {program} program, {size:,} instances ({path.name})", flush=True)
                if args.load_repeat > 0:  # 0: queries only
                    report_load(size, measure_loads(path, work, 1 if size >= 1_000_000 else args.load_repeat))
                store_dir = work / "store"
                own = default_graph_iri(str(path))
                graphs = [own] + [f"{own}-copy{k}" for k in range(1, args.copies)]
                instances = 0
                for k, graph in enumerate(graphs):
                    [row] = run_child("load", str(path), str(store_dir), "on", *([graph] if k else []))
                    instances += row["instances"]
                [row] = run_child("load", str(args.real), str(store_dir), "on")  # the real program, on its own
                one, instances = default_graph_iri(str(args.real)), instances + row["instances"]
                title = (f"the {program} program of {size:,} instances" if args.copies == 1 else
                         f"{args.copies} copies of the {program} program of {size:,} instances "
                         f"({instances - row['instances']:,} in all, one graph each)")
                title += f" and {args.real.name} ({row['instances']} instances)"
                target = (0.2 if size <= 100_000 else 1.0) if args.copies == 1 else None
                ox_times = measure_queries(title, store_dir, args.repeat, args.query_timeout, args.baseline, target)
                if args.split:
                    measure_split(store_dir, args.repeat)
                if instances <= args.rdflib_max:
                    stream_rdflib(store_dir, graphs + [one], args.rdflib_timeout, ox_times)
                measure_queries(f"{args.real.name} alone in that store (--graph {one})", store_dir, args.repeat,
                                args.query_timeout, args.baseline, 0.02, one)
            finally:
                shutil.rmtree(work, ignore_errors=True)


if __name__ == "__main__":
    main()
