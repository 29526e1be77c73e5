"""Plan benchmark: `stepnc-graph plan` on a loaded program, end to end, and the picture it draws.

    pip install -e '.[bench]' && python bench/plan_bench.py                  # 100k and 200k instances
    python bench/plan_bench.py --sizes 200000 --programs generated            # the issue-32 200k figure
    mkdir /tmp/before && git archive HEAD~1 | tar -x -C /tmp/before               # an earlier tree ...
    python bench/plan_bench.py --sizes 100000 --baseline /tmp/before/src      # ... timed beside this one

For each size and program (bench/generate.py's ``generated`` program, a ``replicated`` real one:
copies of the shipped two-setup shaft unless ``--real`` names another), loaded once into an
on-disk store (not timed), each measurement in a fresh process, median of ``--repeat``:

* **plan --svg**: ``stepnc-graph plan --store S --graph G --svg plan.svg`` end to end (start-up,
  reading the plan, the text summary, the first page of the picture): wall and CPU seconds (the
  child's user + system time); the target is <= 2 s;
* **plan --format json --graphml**: the same with the networkx graph (GraphML and the JSON summary);
* **in process**: ``build_plan`` without and with the graph, and the picture, CPU seconds;
* **reference**: the library's ``workplan-sequence`` query on the same program (``query --graph G
  --format csv``, end to end): the same steps read by SPARQL, and the start-up floor
  (``python -c "import pyoxigraph, click"``);
* **the picture**: width and height of the first page, pages, bytes, and how many workingstep boxes
  or runs of steps it draws;
* with ``--baseline SRC`` (an older source tree's ``src``): its ``plan --svg`` too, runs alternating
  with this code's (so a change in the machine's load falls on both), the ratio of the medians, and
  whether the two wrote the same summary and picture (and, once, the same JSON and GraphML).

A run prints whether Python may cache bytecode: with ``PYTHONDONTWRITEBYTECODE`` set (and no cache
written before) every run compiles the project's modules again, some 0.2 CPU-s of its start-up that
an installed package does not pay; ``--bytecode-cache DIR`` lets every child cache it there
(``PYTHONPYCACHEPREFIX``), after an untimed first run of each command.

The machine is shared: read CPU seconds beside wall seconds.
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
import xml.etree.ElementTree as ET
from pathlib import Path
from typing import Any

HERE = Path(__file__).resolve().parent
sys.path.insert(0, str(HERE))

from generate import program_file  # noqa: E402

SVG = "{http://www.w3.org/2000/svg}"
TARGET = 2.0


def run(cmd: list[str], out: Path | None = None, src: str | None = None) -> dict[str, float]:
    """Wall and CPU seconds (user + system of the child) of ``cmd``; its output to ``out``; ``src``:
    the source tree it imports stepnc_graph from (default: this process's)."""
    env = {**os.environ, "PYTHONPATH": src} if src else None
    before = resource.getrusage(resource.RUSAGE_CHILDREN)
    started = time.perf_counter()
    with open(out or os.devnull, "wb") as sink:
        subprocess.run(cmd, stdout=sink, stderr=subprocess.PIPE, check=True, env=env)
    wall = time.perf_counter() - started
    after = resource.getrusage(resource.RUSAGE_CHILDREN)
    cpu = (after.ru_utime - before.ru_utime) + (after.ru_stime - before.ru_stime)
    return {"wall": wall, "cpu": cpu}


def median(runs: list[dict[str, float]]) -> dict[str, float]:
    return {k: statistics.median(r[k] for r in runs) for k in runs[0]}


def compare(cli: list[str], store: Path, graph: str, work: Path, repeat: int, baseline: str, full: bool) -> None:
    """``plan --svg`` of the ``baseline`` source tree and of this code, alternating; their outputs
    compared byte for byte (with ``full``, once, ``--format json --graphml`` too)."""
    runs: dict[str, list[dict[str, float]]] = {"baseline": [], "this code": []}
    for _ in range(repeat):
        for name, src in (("baseline", baseline), ("this code", None)):
            tag = name.replace(" ", "-")
            runs[name].append(run([*cli, "plan", "--store", str(store), "--graph", graph, "--svg",
                                   str(work / f"{tag}.svg")], work / f"{tag}.txt", src))
    same = all((work / f"baseline.{e}").read_bytes() == (work / f"this-code.{e}").read_bytes() for e in ("svg", "txt"))
    if full:
        for name, src in (("baseline", baseline), ("this code", None)):
            tag = name.replace(" ", "-")
            run([*cli, "plan", "--store", str(store), "--graph", graph, "--format", "json", "--graphml",
                 str(work / f"{tag}.graphml")], work / f"{tag}.json", src)
        same = same and all((work / f"baseline.{e}").read_bytes() == (work / f"this-code.{e}").read_bytes()
                            for e in ("json", "graphml"))
    old, new = (statistics.median(r["cpu"] for r in runs[k]) for k in ("baseline", "this code"))
    print(f"{'':>10} {'':>10} {'':>6}   plan --svg, {repeat} runs each, alternating: baseline "
          f"{median(runs['baseline'])['wall']:.2f} s wall / {old:.2f} CPU, this code "
          f"{median(runs['this code'])['wall']:.2f} / {new:.2f}: {new / old:.2f}x CPU; same output"
          + (" (summary, SVG, JSON, GraphML)" if full else " (summary, SVG)") + f": {'yes' if same else 'NO'}",
          flush=True)


def child(store_dir: str, graph: str) -> None:
    """build_plan without and with its graph, the first page of the picture: CPU seconds (this
    process, after the imports)."""
    from stepnc_graph.workplan.plan import build_plan
    from stepnc_graph.store import GraphStore

    with GraphStore(store_dir, readonly=True) as store:
        out: dict[str, Any] = {}
        cpu = time.process_time()
        plan = build_plan(store, graph, network=False)
        out["steps_only"] = time.process_time() - cpu
        cpu = time.process_time()
        out["svg_bytes"] = len(plan.svg())
        out["svg"] = time.process_time() - cpu
        cpu = time.process_time()
        full = build_plan(store, graph, network=True)
        out["with_graph"] = time.process_time() - cpu
        out["nodes"], out["edges"] = full.graph.number_of_nodes(), full.graph.number_of_edges()
        cpu = time.process_time()
        full.graphml()
        out["graphml"] = time.process_time() - cpu
        out["steps"] = len(plan.steps)
    print(json.dumps(out))


def picture(path: Path) -> dict[str, Any]:
    root = ET.parse(path).getroot()
    kinds = [g.get("class", "") for g in root.iter(f"{SVG}g")]
    return {"width": float(root.get("width", 0)), "height": float(root.get("height", 0)),
            "boxes": kinds.count("workingstep"), "runs": sum(k.startswith("block") for k in kinds),
            "bytes": path.stat().st_size}


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--sizes", type=int, nargs="+", default=[100_000, 200_000])
    ap.add_argument("--programs", nargs="+", choices=["generated", "replicated"], default=["generated", "replicated"])
    ap.add_argument("--repeat", type=int, default=3)
    ap.add_argument("--real", type=Path, default=HERE.parent / "examples" / "shaft_two_setups.stp")
    ap.add_argument("--data", type=Path, default=Path(tempfile.gettempdir()) / "stepnc-graph-bench")
    ap.add_argument("--baseline", metavar="SRC", help="an older source tree's src: its plan --svg beside this one's")
    ap.add_argument("--no-full-compare", action="store_true",
                    help="with --baseline: compare the summary and SVG only, not the JSON and GraphML")
    ap.add_argument("--bytecode-cache", type=Path, metavar="DIR",
                    help="let the children cache bytecode in DIR (as an installed package has it), an untimed run first")
    ap.add_argument("--child", nargs=2, help=argparse.SUPPRESS)
    args = ap.parse_args()
    if args.child:
        child(*args.child)
        return
    from stepnc_graph.core.naming import default_graph_iri

    args.data.mkdir(parents=True, exist_ok=True)
    if args.bytecode_cache:
        os.environ.pop("PYTHONDONTWRITEBYTECODE", None)
        os.environ["PYTHONPYCACHEPREFIX"] = str(args.bytecode_cache.resolve())
    cli = [sys.executable, "-m", "stepnc_graph.cli"]
    print(f"machine: {os.cpu_count()} cores, load average {os.getloadavg()[0]:.1f}; Python {sys.version.split()[0]}; "
          + ("PYTHONDONTWRITEBYTECODE set: each run compiles the modules no earlier run cached"
             if os.environ.get("PYTHONDONTWRITEBYTECODE") else "bytecode cached"))
    floor = median([run([sys.executable, "-c", "import pyoxigraph, click"]) for _ in range(args.repeat)])
    print(f"start-up floor (python -c 'import pyoxigraph, click'): {floor['wall']:.2f} s wall, {floor['cpu']:.2f} s CPU")
    print(f"\n{'program':>10} {'instances':>10} {'steps':>6} | {'plan --svg':>17} | {'json + graphml':>17} | "
          f"{'in process: steps, +graph, svg':>30} | {'workplan-sequence':>17} | picture (page 1)")
    print(f"{'':>10} {'':>10} {'':>6} | {'wall / CPU s':>17} | {'wall / CPU s':>17} | {'CPU s':>30} | "
          f"{'wall / CPU s':>17} |")
    verdicts = []
    for size in args.sizes:
        for program in args.programs:
            path = program_file(args.data, program, size, args.real)
            work = Path(tempfile.mkdtemp(prefix="stepnc-plan-bench-", dir=args.data))
            try:
                store = work / "store"
                subprocess.run([*cli, "load", "--store", str(store), str(path)], check=True, capture_output=True)
                graph = default_graph_iri(str(path))
                svg = work / "plan.svg"
                if args.bytecode_cache:  # the caches written, untimed
                    for src in [None] + ([args.baseline] if args.baseline else []):
                        run([*cli, "plan", "--store", str(store), "--graph", graph, "--svg", str(svg)], src=src)
                    run([*cli, "query", "workplan-sequence", "--store", str(store), "--graph", graph])
                plan = median([run([*cli, "plan", "--store", str(store), "--graph", graph, "--svg", str(svg)])
                               for _ in range(args.repeat)])
                full = median([run([*cli, "plan", "--store", str(store), "--graph", graph, "--format", "json",
                                    "--graphml", str(work / "plan.graphml")]) for _ in range(args.repeat)])
                query = median([run([*cli, "query", "workplan-sequence", "--store", str(store), "--graph", graph,
                                     "--format", "csv"]) for _ in range(args.repeat)])
                inner = [json.loads(subprocess.run([sys.executable, __file__, "--child", str(store), graph],
                                                   capture_output=True, text=True, check=True).stdout)
                         for _ in range(args.repeat)]
                steps = inner[0]["steps"]
                inproc = {k: statistics.median(r[k] for r in inner) for k in ("steps_only", "with_graph", "svg")}
                pic = picture(svg)
                drawn = f"{pic['boxes']} steps" if pic["boxes"] else f"{pic['runs']} runs"
                print(f"{program:>10} {size:>10,} {steps:>6,} | {plan['wall']:7.2f} / {plan['cpu']:6.2f} | "
                      f"{full['wall']:7.2f} / {full['cpu']:6.2f} | {inproc['steps_only']:8.2f} {inproc['with_graph']:8.2f} "
                      f"{inproc['svg']:8.2f}    | {query['wall']:7.2f} / {query['cpu']:6.2f} | "
                      f"{pic['width']:,.0f} x {pic['height']:,.0f} px, {drawn}, {pic['bytes'] / 1e3:,.0f} kB", flush=True)
                verdicts.append((program, size, plan["cpu"]))
                if args.baseline:
                    compare(cli, store, graph, work, args.repeat, args.baseline, not args.no_full_compare)
            finally:
                shutil.rmtree(work, ignore_errors=True)
    print(f"\ntarget: plan --svg within {TARGET:.0f} s (CPU, start-up included):")
    for program, size, cpu in verdicts:
        print(f"  {program} {size:,}: {cpu:.2f} s CPU  " + ("ok" if cpu <= TARGET else f"MISS ({cpu / TARGET:.2f}x)"))


if __name__ == "__main__":
    main()
