"""Store benchmark: load, replace (load again, and by an edited file) and unload of one program.

    pip install -e '.[bench]' && python bench/store_bench.py                 # 100k instances
    python bench/store_bench.py --sizes 100000 1000000                       # add 1M (slow)

For each program (a generated one and a replicated real one, see bench/generate.py) and
size, in the same run, every operation in its own fresh process on an on-disk store that
an earlier process prepared: wall and CPU seconds, the process's peak RSS, how the store
removed the old graph ("rebuild": the store held little else; "delete": batched deletes
beside other programs), and the store's size on disk afterwards. An unload beside other
programs compacts the database only once the quads deleted since its last compaction reach
stepnc_graph.store.tuning.COMPACT_AT of the store: the "unload" column is what the store chose
("+c": it compacted), then the program is loaded again and unloaded with ``compact=True``
(``unload --compact``: the deletes and a compaction of the whole store), and ``compact``
runs on what that left (its time, and the disk space it gives back). The edited file has a
comment line after ``DATA;``: every instance's line changes, nothing else. Ratios are against the
fresh load of the same file measured in the same run. "beside 3 others" puts the program
in a store that also holds three other copies of it (other graph IRIs).
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
ROOT = HERE.parent
sys.path.insert(0, str(HERE))

from generate import replicate, write  # noqa: E402

GRAPH = "https://w3id.org/stepnc-graph/data/bench.stp"


def child(op: str, store_dir: str, path: str) -> None:
    """One operation in this process; prints wall, CPU, peak RSS and the removal strategy as JSON."""
    import stepnc_graph as sg
    from stepnc_graph.schema.catalog import iso14649

    iso14649()
    cpu0, wall0 = time.process_time(), time.perf_counter()
    removal = None
    with sg.open_store(store_dir) as store:
        if op == "load" or op == "replace":
            [r] = sg.load(store, [path], base_iri=GRAPH)
            assert not r.diagnostics, r.diagnostics[:3]
        elif op == "replace-edited":
            [r] = sg.load(store, [edited(Path(path))], base_iri=GRAPH, replace=True)
            assert not r.diagnostics, r.diagnostics[:3]
        elif op in ("unload", "unload-compact"):
            assert sg.unload(store, GRAPH, compact=op == "unload-compact")
        elif op == "compact":
            sg.compact(store)
        elif op.startswith("others"):
            for k in range(int(op[len("others"):])):
                sg.load(store, [path], base_iri=f"{GRAPH}-other{k}")
        removal = store.last_removal
        if removal is not None and store.compacted:
            removal += "+c"
    wall, cpu = time.perf_counter() - wall0, time.process_time() - cpu0
    print(json.dumps({"wall": wall, "cpu": cpu, "rss_mb": resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024,
                      "removal": removal}))


def edited(path: Path) -> Path:
    """``path`` after an edit near its top: a comment line after ``DATA;`` shifts the line of
    every instance (each one's ``p21:line`` changes), the rest is the same."""
    out = path.with_name(path.stem + "_edited.stp")
    if not out.exists():
        out.write_text(path.read_text().replace("DATA;\n", "DATA;\n/* revision B */\n", 1))
    return out


def run(op: str, store: Path, path: Path) -> dict[str, float | str | None]:
    done = subprocess.run([sys.executable, __file__, "--child", op, str(store), str(path)], capture_output=True,
                          text=True, check=True)
    return json.loads(done.stdout.strip().splitlines()[-1])  # type: ignore[no-any-return]


def disk_mb(path: Path) -> float:
    """MB on disk under ``path``, each hard-linked file once (generations share SST files)."""
    from stepnc_graph.store import directory_bytes

    return directory_bytes(path) / 1e6


def scenario(path: Path, others: int, repeat: int, work: Path) -> dict[str, dict[str, float | str | None]]:
    """Median figures of load, replace and unload with ``others`` other programs in the store."""
    results: dict[str, list[dict[str, float | str | None]]] = {"load": [], "replace": [], "replace-edited": [],
                                                               "unload": [], "unload-compact": [], "compact": []}
    for _ in range(repeat):
        store = work / "store"
        shutil.rmtree(store, ignore_errors=True)
        if others:
            run(f"others{others}", store, path)
        results["load"].append(run("load", store, path))
        results["replace"].append(run("replace", store, path))
        results["replace-edited"].append(run("replace-edited", store, path))
        results["unload"].append({**run("unload", store, path), "disk_mb": disk_mb(store)})
        run("load", store, path)  # again, for the unload that compacts
        results["unload-compact"].append({**run("unload-compact", store, path), "disk_mb": disk_mb(store)})
        results["compact"].append({**run("compact", store, path), "disk_mb": disk_mb(store)})
    out = {}
    for op, runs in results.items():
        out[op] = {k: statistics.median(float(r[k]) for r in runs)  # type: ignore[arg-type]
                   for k in ("wall", "cpu", "rss_mb")}
        out[op]["removal"] = runs[0]["removal"]
        if op in ("unload", "unload-compact", "compact"):
            out[op]["disk_mb"] = statistics.median(float(r["disk_mb"]) for r in runs)  # type: ignore[arg-type]
    return out


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--sizes", type=int, nargs="+", default=[100_000])
    ap.add_argument("--repeat", type=int, default=3, help="runs per figure below 1M instances (1M: 1 run)")
    ap.add_argument("--others", type=int, nargs="+", default=[0, 3],
                    help="other copies of the program in the store, one scenario each (default: 0 and 3)")
    ap.add_argument("--programs", nargs="+", choices=["generated", "replicated"], default=["generated", "replicated"])
    ap.add_argument("--real", type=Path, default=ROOT / "examples" / "shaft_two_setups.stp",
                    help="the real program to replicate (default: the shipped example)")
    ap.add_argument("--data", type=Path, default=Path(tempfile.gettempdir()) / "stepnc-graph-bench")
    ap.add_argument("--child", nargs=3, metavar=("OP", "STORE", "PATH"), help=argparse.SUPPRESS)
    args = ap.parse_args()
    if args.child:
        child(*args.child)
        return
    args.data.mkdir(parents=True, exist_ok=True)
    print(f"machine: {os.cpu_count()} cores; Python {sys.version.split()[0]}; seconds are wall / CPU")
    header = (f"{'program':>22} {'store holds':>15} | {'load':>22} | {'replace':>35} | "
              f"{'replace by the edited file':>35} | {'unload':>42} | {'unload --compact':>42} | "
              f"{'compact (after the unloads)':>31}")
    print(header)
    print("-" * len(header))
    for size in args.sizes:
        programs = {f"generated {size:,}": args.data / f"turning_{size}.stp",
                    f"replicated {size:,}": args.data / f"real_{size}.stp"}
        if not programs[f"generated {size:,}"].exists():
            write(size, programs[f"generated {size:,}"])
        if not programs[f"replicated {size:,}"].exists():
            replicate(args.real, size, programs[f"replicated {size:,}"])
        repeat = 1 if size >= 1_000_000 else args.repeat
        for name, path in programs.items():
            if name.split()[0] not in args.programs:
                continue
            for others in args.others:
                with tempfile.TemporaryDirectory(dir=args.data) as work:
                    r = scenario(path, others, repeat, Path(work))
                load, rep, edit, comp = r["load"], r["replace"], r["replace-edited"], r["compact"]

                def cell(x: dict[str, float | str | None]) -> str:
                    return f"{x['wall']:5.1f}/{x['cpu']:5.1f} s {x['rss_mb']:5.0f} MB"

                def unloaded(x: dict[str, float | str | None], load: dict[str, float | str | None] = load) -> str:
                    return (f"{cell(x)} {float(x['wall']) / float(load['wall']):4.2f}x {x['removal']:>9} "
                            f"{x['disk_mb']:5.0f} MB")

                print(f"{name:>22} {'it alone' if not others else f'beside {others} others':>15} | {cell(load)} | "
                      f"{cell(rep)} {float(rep['wall']) / float(load['wall']):4.2f}x {rep['removal']:>10} | "
                      f"{cell(edit)} {float(edit['wall']) / float(load['wall']):4.2f}x {edit['removal']:>10} | "
                      f"{unloaded(r['unload'])} | {unloaded(r['unload-compact'])} | {cell(comp)} "
                      f"{comp['disk_mb']:5.0f} MB", flush=True)
    print("\nmedians; MB: the operation's peak RSS; the ratios are wall time against the fresh load in the same "
          "row;\nafter the unloads and after compact: the store's size on disk; +c: the unload compacted.")


if __name__ == "__main__":
    main()
