"""Validation benchmark: stepnc-graph's engine next to pySHACL and the Rust SHACL engines on PyPI,
on the W3C SHACL test suite and on programs of 10k and 100k instances, in one run.

    python bench/validate_bench.py --sizes 10000 100000 [--pyshacl-max 10000] [--rust-max 100000]
                                   [--baseline OTHER/src]

1. **The W3C suite** (tests/w3c-shacl): every approved test run by stepnc-graph's engine and by
   pySHACL, each in a fresh process; total wall and CPU seconds and how many pass.
2. **Programs**: a generated one (bench/generate.py) and a *replicated* real one (copies of the
   shipped two-setup shaft program, its mix of entities), at each size. stepnc-graph: the end to
   end time of ``validate([path])`` (``stepnc-graph validate FILE``: imports, Part 21 parse, load,
   checks, report) in a fresh process, and of its load alone in another, alternating, medians of
   ``--repeat`` runs, with CPU seconds and peak RSS, and the phases of the end-to-end run (wall,
   CPU of the process and of the calling thread: where a user's wait goes). The other engines get the program graph
   plus ``shapes/support.ttl`` as a ready N-Triples file and the shipped shapes as one Turtle
   file: pySHACL (rdflib parse reported apart) up to ``--pyshacl-max`` instances, and each Rust
   engine that is installed (``pip install -e '.[bench]'``: shacl, shacl-rust, pyshacl-turbo,
   pyrudof) up to ``--rust-max``, each in a fresh process with a ``--timeout``. "same" compares
   each engine's results (focus node, component, IRI source shape) with stepnc-graph's.
   ``--baseline OTHER/src``: another version of stepnc-graph run end to end alternating with this
   one, the ratio of their medians printed (before and after a change, same machine, same time),
   and whether the two versions' JSON reports are the same byte for byte.
"""

from __future__ import annotations

import argparse
import json
import os
import statistics
import subprocess
import sys
import tempfile
from pathlib import Path
from typing import Any

ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT / "bench"))

_SUITE = r"""
import json, resource, sys, time, warnings
warnings.simplefilter("ignore")
sys.path.insert(0, sys.argv[2])
t0 = time.perf_counter(); c0 = time.process_time()
import w3c_shacl as w
cases = w.cases()
run = w.run_case if sys.argv[1] == "ours" else w.run_pyshacl
t1 = time.perf_counter(); c1 = time.process_time()
outcomes = []
engine_wall = engine_cpu = 0.0
for case in cases:
    try:
        o = run(case)
    except Exception as exc:  # a crash counts as a failure
        o = w.Outcome("fail", type(exc).__name__)
    outcomes.append(o.status)
    engine_wall += o.seconds; engine_cpu += o.cpu
t2 = time.perf_counter(); c2 = time.process_time()
print(json.dumps({"wall": t2 - t1, "cpu": c2 - c1, "setup": t1 - t0, "engine_wall": engine_wall,
                  "engine_cpu": engine_cpu, "passed": outcomes.count("pass"),
                  "refused": outcomes.count("refused"), "pending": outcomes.count("pending"),
                  "total": len(outcomes)}))
"""

_OURS = r"""
import hashlib, json, resource, sys, time
marks = [("start", time.perf_counter(), time.process_time(), time.thread_time())]
def mark(name):
    marks.append((name, time.perf_counter(), time.process_time(), time.thread_time()))
def phase(text):  # validate()'s progress: the first line of each phase marks where the one before ended
    name = {"loading": "shapes", "checking": "load", "describing": "checks"}.get(text.split()[0])
    if name is not None and name not in [m[0] for m in marks]:
        mark(name)
from stepnc_graph.validation import validate
mark("imports")
report = validate([sys.argv[1]], lenient=True, progress=phase)  # what `stepnc-graph validate FILE` does
mark("report")
keys = sorted({(x.focus, x.component, x.shape or "") for x in report.results})
phases = {b[0]: [b[1] - a[1], b[2] - a[2], b[3] - a[3]] for a, b in zip(marks, marks[1:])}
print(json.dumps({"total_s": marks[-1][1] - marks[0][1], "total_cpu": marks[-1][2] - marks[0][2],
                  "results": len(report.results), "phases": phases,
                  "checks": report.checks_run, "rss_mb": resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024,
                  "keys": keys, "report": hashlib.sha256(report.to_json().encode()).hexdigest()}))
"""

#: the phases of an end-to-end run (_OURS), as the bench prints them
PHASES = {"imports": "imports", "shapes": "shapes and store", "load": "load", "checks": "checks",
          "report": "describing and dropping the store"}

_LOAD = r"""
import json, sys, time
t0 = time.perf_counter(); c0 = time.process_time()
from stepnc_graph.loading.loader import load_paths
from stepnc_graph.validation import compile_shapes, shape_files, throwaway_store
from stepnc_graph.validation.throwaway import input_bytes, properties_kept
with throwaway_store([sys.argv[1]]) as store:  # validate()'s load of a file: in memory, or on disk if large
    shapes = compile_shapes(shape_files())
    load_paths(store, [sys.argv[1]], lenient=True, derived=False, positions=shapes.reads_positions(),
               reads=properties_kept(store, shapes, input_bytes([sys.argv[1]])))  # as validate()
    print(json.dumps({"load_s": time.perf_counter() - t0, "load_cpu": time.process_time() - c0}))
"""

_EXPORT = r"""
import sys
import pyoxigraph as ox
from stepnc_graph import api
from stepnc_graph.validation import shape_files
with api.open_store(memory=True) as store:
    [r] = api.load(store, [sys.argv[1]], lenient=True, derived=False)  # the graph validate() checks
    data = store.dump(ox.RdfFormat.N_TRIPLES, r.graph)
files = shape_files()
support = [f for f in files if f.name == "support.ttl"]  # part of the data graph (docs/validation.md)
extra = ox.serialize(ox.parse(path=str(support[0]), format=ox.RdfFormat.TURTLE), format=ox.RdfFormat.N_TRIPLES)
open(sys.argv[2], "wb").write(data + (extra or b""))
shapes = [t for f in files if f.name != "support.ttl" for t in ox.parse(path=str(f), format=ox.RdfFormat.TURTLE)]
open(sys.argv[3], "wb").write(ox.serialize(shapes, format=ox.RdfFormat.TURTLE) or b"")
"""

#: each engine: code run as ``python -c CODE DATA.nt SHAPES.ttl``, printing keys and CPU seconds
_ENGINE = r"""
import json, resource, sys, time, warnings
warnings.simplefilter("ignore")
data, shapes, engine = sys.argv[1], sys.argv[2], sys.argv[3]
c0 = time.process_time(); t0 = time.perf_counter()
report = None
if engine == "pyshacl":
    import pyshacl, rdflib
    g = rdflib.Graph().parse(data, format="nt"); s = rdflib.Graph().parse(shapes, format="turtle")
    c0 = time.process_time(); t0 = time.perf_counter()  # pySHACL: its rdflib parse reported apart
    _, report, _ = pyshacl.validate(g, shacl_graph=s, inference="none", advanced=False)
elif engine == "pyshacl-turbo":
    import pyshacl_turbo
    _, report, _ = pyshacl_turbo.validate(data, shacl_graph=shapes, data_graph_format="nt", shacl_graph_format="turtle")
elif engine == "shacl":
    import shacl
    found = shacl.validate(data, shapes)
    text = found.turtle if isinstance(found.turtle, str) else found.turtle()
elif engine == "shacl-rust":
    import shacl_rust
    found = shacl_rust.validate_file(data, shapes, data_format="ntriples", shapes_format="turtle")
elif engine == "pyrudof":
    import pyrudof
    ru = pyrudof.Rudof(pyrudof.RudofConfig())
    ru.read_data(data, format=pyrudof.RDFFormat.NTriples); ru.read_shacl(shapes)
    ru.validate_shacl()
    text = ru.serialize_shacl_validation_results(format=pyrudof.ResultShaclValidationFormat.Turtle)
c1 = time.process_time(); t1 = time.perf_counter()
keys = set()
if engine == "shacl-rust":
    for r in found["results"]:
        shape = r.get("sourceShape") or ""
        keys.add((r["focusNode"].strip("<>"), r["sourceConstraintComponent"].strip("<>"),
                  shape.strip("<>") if shape.startswith("<") else ""))
else:
    import rdflib
    from rdflib import SH, URIRef
    if report is None:
        report = rdflib.Graph().parse(data=text, format="turtle")
    for x in report.objects(None, SH.result):
        shape = report.value(x, SH.sourceShape)
        keys.add((str(report.value(x, SH.focusNode)), str(report.value(x, SH.sourceConstraintComponent)),
                  str(shape) if isinstance(shape, URIRef) else ""))
print(json.dumps({"wall": t1 - t0, "cpu": c1 - c0, "rss_mb": resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024,
                  "keys": sorted(keys)}))
"""

RUST_ENGINES = {"shacl": "shacl", "shacl-rust": "shacl_rust", "pyshacl-turbo": "pyshacl_turbo", "pyrudof": "pyrudof"}


class OverLimit(Exception):
    """Another engine used up its CPU seconds (``--timeout``) and was stopped."""


def _run(code: str, *args: str, cpu_limit: float | None = None, src: Path | None = None) -> dict[str, Any]:
    """Run ``code`` in a fresh process; ``cpu_limit``: its CPU seconds (a busy shared machine makes
    a wall-clock limit meaningless), wall time four times that as a guard; ``src``: import
    stepnc_graph from there (another version's ``src``) instead of this one."""
    def limit() -> None:
        if cpu_limit is not None:
            import resource

            resource.setrlimit(resource.RLIMIT_CPU, (int(cpu_limit), int(cpu_limit) + 5))

    env = None if src is None else {**os.environ, "PYTHONPATH": str(src)}
    out = subprocess.run([sys.executable, "-c", code, *args], capture_output=True, text=True, cwd=ROOT,
                         timeout=cpu_limit * 4 if cpu_limit else None, preexec_fn=limit, env=env)
    if out.returncode in (-24, -9) and cpu_limit is not None:  # SIGXCPU, then SIGKILL at the hard limit
        raise OverLimit
    if out.returncode != 0:
        raise subprocess.CalledProcessError(out.returncode, "engine", out.stdout, out.stderr)
    return json.loads(out.stdout.strip().splitlines()[-1])  # type: ignore[no-any-return]


def _installed(module: str) -> bool:
    return subprocess.run([sys.executable, "-c", f"import {module}"], capture_output=True).returncode == 0


def suite() -> None:
    print("W3C SHACL test suite (tests/w3c-shacl), each engine in a fresh process; 'engine': reading each "
          "test's data and shapes and validating, summed; 'all': with the comparison of reports")
    print(f"{'engine':>14} {'engine s':>9} {'cpu':>6} {'all s':>7} {'cpu':>6} {'passed':>7} {'refused':>8} "
          f"{'pending':>8} {'tests':>6}")
    rows = {}
    for engine in ("ours", "pyshacl"):
        r = _run(_SUITE, engine, str(ROOT / "tests"))
        rows[engine] = r
        name = "stepnc-graph" if engine == "ours" else "pySHACL*"
        print(f"{name:>14} {r['engine_wall']:>9.2f} {r['engine_cpu']:>6.2f} {r['wall']:>7.2f} {r['cpu']:>6.2f} "
              f"{r['passed']:>7} {r['refused']:>8} {r['pending']:>8} {r['total']:>6}")
    print(f"{'':>14} pySHACL / stepnc-graph: {rows['pyshacl']['engine_cpu'] / rows['ours']['engine_cpu']:.1f}x CPU "
          f"(* pySHACL's passes counted by sh:conforms and the number of results only)\n", flush=True)


def programs(args: argparse.Namespace) -> None:
    from generate import replicate

    engines = [e for e in args.engines if e == "pyshacl" or _installed(RUST_ENGINES[e])]
    missing = sorted(set(args.engines) - set(engines))
    if missing:
        print(f"(not installed, skipped: {', '.join(missing)})")
    print("Programs: stepnc-graph end to end from Part 21 (load alone, validation = the difference); the other "
          "engines on the program graph + support.ttl as ready N-Triples (CPU s)")
    with tempfile.TemporaryDirectory() as tmp:
        for kind in args.programs:
            for n in args.sizes:
                program = Path(tmp) / f"{kind}_{n}.stp"
                if kind == "generated":
                    subprocess.run([sys.executable, str(ROOT / "bench" / "generate.py"), str(n), str(program)],
                                   check=True, capture_output=True)
                else:
                    replicate(args.real, n, program)
                _program(args, kind, n, program, Path(tmp), engines)


def _program(args: argparse.Namespace, kind: str, n: int, program: Path, tmp: Path, engines: list[str]) -> None:
    runs, loads, before = [], [], []
    for _ in range(args.repeat):  # alternating, each in a fresh process
        runs.append(_run(_OURS, str(program)))
        loads.append(_run(_LOAD, str(program)))
        if args.baseline is not None:
            before.append(_run(_OURS, str(program), src=args.baseline))
    ours = dict(sorted(runs, key=lambda r: r["total_cpu"])[len(runs) // 2])
    load = sorted(loads, key=lambda r: r["load_cpu"])[len(loads) // 2]
    walls = [r["total_s"] for r in runs]
    print(f"\n{kind} {n:,} instances: stepnc-graph {statistics.median(walls):.2f} s wall, {ours['total_cpu']:.2f} s CPU "
          f"end to end (load {load['load_s']:.2f} s / {load['load_cpu']:.2f} CPU, validation "
          f"{ours['total_cpu'] - load['load_cpu']:.2f} CPU), {ours['rss_mb']:.0f} MB, {ours['checks']} checks, "
          f"{ours['results']} results", flush=True)
    _phases(runs)
    if before:
        _baseline(args.baseline, before, runs)
    data, shapes = tmp / f"{kind}_{n}.nt", tmp / "shapes.ttl"
    subprocess.run([sys.executable, "-c", _EXPORT, str(program), str(data), str(shapes)], check=True, cwd=ROOT)
    mine = {tuple(k) for k in ours["keys"]}
    fastest_rust: float | None = None
    for engine in engines:
        limit = args.pyshacl_max if engine == "pyshacl" else args.rust_max
        if n > limit:
            print(f"  {engine:>14}: skipped (--{'pyshacl' if engine == 'pyshacl' else 'rust'}-max {limit:,})")
            continue
        try:
            r = _run(_ENGINE, str(data), str(shapes), engine, cpu_limit=args.timeout)
        except (OverLimit, subprocess.TimeoutExpired):
            print(f"  {engine:>14}: over {args.timeout:.0f} CPU-s, stopped -> over "
                  f"{args.timeout / ours['total_cpu']:.0f}x stepnc-graph's end-to-end CPU")
            continue
        except subprocess.CalledProcessError as exc:
            last = (exc.stderr or "").strip().splitlines()[-1:] or ["?"]
            print(f"  {engine:>14}: failed ({last[0][:150]})")
            continue
        theirs = {tuple(k) for k in r["keys"]}
        same = "same results" if theirs == mine else \
            f"DIFFERENT: {len(theirs - mine)} only theirs, {len(mine - theirs)} only ours"
        ratio = r["cpu"] / ours["total_cpu"]
        print(f"  {engine:>14}: {r['wall']:.2f} s wall, {r['cpu']:.2f} s CPU, {r['rss_mb']:.0f} MB -> "
              f"{ratio:.1f}x stepnc-graph's end-to-end CPU; {same}", flush=True)
        if engine != "pyshacl" and theirs == mine:
            fastest_rust = r["cpu"] if fastest_rust is None else min(fastest_rust, r["cpu"])
    if fastest_rust is not None:
        print(f"  fastest agreeing Rust engine / stepnc-graph: {fastest_rust / ours['total_cpu']:.1f}x CPU")


def _phases(runs: list[dict[str, Any]]) -> None:
    """Where the wall time of an end-to-end run goes, phase by phase (medians of the runs): wall,
    CPU of the process (both cores) and of the calling thread (the critical path's Python part)."""
    parts = []
    for key, label in PHASES.items():
        values = [r["phases"].get(key, [0.0, 0.0, 0.0]) for r in runs]
        wall, cpu, thread = (statistics.median(v[i] for v in values) for i in range(3))
        parts.append(f"{label} {wall:.2f} s wall / {cpu:.2f} CPU ({thread:.2f} in the calling thread)")
    print("  phases, medians: " + "; ".join(parts), flush=True)


def _baseline(src: Path, before: list[dict[str, Any]], runs: list[dict[str, Any]]) -> None:
    """Another version's end-to-end runs (alternating with this one's, same program) next to
    this one's: medians of CPU and wall seconds, and whether the results are the same."""
    def medians(rs: list[dict[str, Any]]) -> tuple[float, float]:
        return statistics.median(r["total_cpu"] for r in rs), statistics.median(r["total_s"] for r in rs)

    (cpu0, wall0), (cpu1, wall1) = medians(before), medians(runs)
    least = min(r["total_cpu"] for r in runs) / min(r["total_cpu"] for r in before)  # the least disturbed runs
    same = all(r["report"] == runs[0]["report"] for r in before + runs)  # the whole JSON report, byte for byte
    print(f"  baseline {src}: {wall0:.2f} s wall, {cpu0:.2f} s CPU end to end -> this version "
          f"{cpu1 / cpu0:.2f}x its CPU ({least:.2f}x by the fastest runs), {wall1 / wall0:.2f}x its wall (runs alternating; CPU "
          f"{[round(r['total_cpu'], 2) for r in before]} against {[round(r['total_cpu'], 2) for r in runs]}); "
          f"{'the same JSON report' if same else 'DIFFERENT reports'}", flush=True)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--sizes", type=int, nargs="+", default=[10000, 100000])
    parser.add_argument("--programs", nargs="+", choices=["generated", "replicated"], default=["replicated", "generated"])
    parser.add_argument("--real", type=Path, default=ROOT / "examples" / "shaft_two_setups.stp",
                        help="the real program to replicate (default: the shipped example)")
    parser.add_argument("--engines", nargs="+", default=["pyshacl", *RUST_ENGINES],
                        choices=["pyshacl", *RUST_ENGINES])
    parser.add_argument("--pyshacl-max", type=int, default=10000)
    parser.add_argument("--rust-max", type=int, default=100000)
    parser.add_argument("--timeout", type=float, default=600, help="CPU seconds per run of another engine")
    parser.add_argument("--repeat", type=int, default=3, help="runs of stepnc-graph per program (median reported)")
    parser.add_argument("--no-suite", action="store_true", help="skip the W3C suite")
    parser.add_argument("--baseline", type=Path, help="another version's src directory (e.g. of `git worktree add` "
                        "or `git archive`), run end to end alternating with this one, its CPU and wall compared")
    args = parser.parse_args()
    if not args.no_suite:
        suite()
    programs(args)


if __name__ == "__main__":
    main()
