"""Load benchmark: parse-only and end-to-end load rates and peak memory, per program size.

    pip install -e '.[bench]' && python bench/load_bench.py            # 10k and 100k
    python bench/load_bench.py --sizes 10000 100000 1000000             # add 1M

For each size, on one generated file (bench/generate.py) and in the same run:
steputils' parse-only rate (the reference), stepnc-graph's parse-only rate, the
end-to-end load (parse, map, write into a fresh on-disk Oxigraph store), and
"store alone": the same N-Triples, mapped before the clock starts, written by
the same store code -- the ceiling the store sets whatever the Python side does.
Every measurement runs in its own process, so "peak RSS" is that process's
own maximum resident set; rates are medians over ``--repeat`` runs.
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
import time
from pathlib import Path

HERE = Path(__file__).resolve().parent
sys.path.insert(0, str(HERE))

from generate import replicate, write  # noqa: E402


def child(kind: str, path: str) -> None:
    """Run one measurement in this (fresh) process and print it as JSON.

    Imports happen before the clock starts: start-up cost is not reading speed.
    For "store", parsing and mapping happen before the clock starts too.
    """
    from steputils import p21

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
    rss_mb = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024
    print(json.dumps({"count": count, "seconds": seconds, "cpu": cpu, "triples": triples, "rss_mb": rss_mb}))


def measure(kind: str, path: Path, repeat: int, timeout: float) -> dict[str, float] | None:
    runs = []
    for _ in range(repeat):
        try:
            done = subprocess.run([sys.executable, __file__, "--child", kind, str(path)], capture_output=True,
                                  text=True, timeout=timeout, check=True)
        except subprocess.TimeoutExpired:
            return None
        except subprocess.CalledProcessError as e:
            print(f"  {kind} failed: {e.stderr.strip().splitlines()[-1] if e.stderr.strip() else e}")
            return None
        runs.append(json.loads(done.stdout.strip().splitlines()[-1]))
    seconds = statistics.median(r["seconds"] for r in runs)
    count = runs[0]["count"]
    return {"count": count, "seconds": seconds, "cpu": statistics.median(r["cpu"] for r in runs),
            "rate": count / seconds,
            "triples_rate": runs[0]["triples"] / seconds, "triples": runs[0]["triples"],
            "rss_mb": max(r["rss_mb"] for r in runs)}


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--sizes", type=int, nargs="+", default=[10_000, 100_000])
    ap.add_argument("--repeat", type=int, default=3, help="runs per measurement below 1M instances (1M: 1 run)")
    ap.add_argument("--data", type=Path, default=Path(tempfile.gettempdir()) / "stepnc-graph-bench")
    ap.add_argument("--steputils-timeout", type=float, default=900)
    ap.add_argument("--real", type=Path, default=HERE.parent / "examples" / "shaft_two_setups.stp",
                    help="a real program to replicate beside the generated one (default: the shipped example)")
    ap.add_argument("--child", nargs=2, metavar=("KIND", "PATH"), help=argparse.SUPPRESS)
    args = ap.parse_args()
    if args.child:
        child(*args.child)
        return
    args.data.mkdir(parents=True, exist_ok=True)
    print(f"machine: {os.cpu_count()} cores; Python {sys.version.split()[0]}")
    header = (f"{'program':>10} {'instances':>10} {'MB':>5} | {'steputils parse':>16} | {'stepnc parse':>13} | "
              f"{'end-to-end load (on-disk store), wall / CPU s':>62} | {'store alone':>13} | {'load/steputils':>14}")
    print(header)
    print("-" * len(header))
    runs = []
    for size in args.sizes:
        generated, real = args.data / f"turning_{size}.stp", args.data / f"real_{size}.stp"
        if not generated.exists():
            write(size, generated)
        if not real.exists():
            replicate(args.real, size, real)
        runs += [("generated", size, generated), ("replicated", size, real)]
    for program, size, path in runs:
        repeat = 1 if size >= 1_000_000 else args.repeat
        ref = measure("steputils", path, repeat, args.steputils_timeout)
        parse = measure("parse", path, repeat, 3600)
        load = measure("load", path, repeat, 3600)
        alone = measure("store", path, repeat, 3600)
        assert parse is not None and load is not None and alone is not None
        ref_text = f"{ref['rate']:>10,.0f} inst/s" if ref else f"{'timed out':>16}"
        ratio = f"{load['rate'] / ref['rate']:>13.1f}x" if ref else f"{'-':>14}"
        print(f"{program:>10} {load['count']:>10,} {path.stat().st_size / 1e6:>5.0f} | {ref_text:>16} | "
              f"{parse['rate']:>7,.0f} inst/s | {load['rate']:>7,.0f} inst/s {load['triples_rate']:>9,.0f} triples/s "
              f"{load['seconds']:>6.1f}/{load['cpu']:>6.1f} s {load['rss_mb']:>6,.0f} MB peak | "
              f"{alone['rate']:>7,.0f} inst/s | {ratio}", flush=True)
    print("\nrates are medians; 'MB peak' is the loading process's maximum RSS; steputils is parse-only;\n"
          "'store alone' writes the already-mapped N-Triples of the file with the loader's store code;\n"
          "'replicated' is copies of a real program (its mix of entities; fewer triples per instance).")


if __name__ == "__main__":
    main()
