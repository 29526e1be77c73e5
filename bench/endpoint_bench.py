"""Endpoint benchmark: a program loaded and the query library run over a SPARQL endpoint, next to the
embedded store, in the same run.

    pip install -e '.[bench,test]' && python bench/endpoint_bench.py              # 100k instances
    python bench/endpoint_bench.py --size 10000 --repeat 5
    python bench/endpoint_bench.py --size 10000 --programs replicated --no-queries   # the loads only

Two programs of ``--size`` instances (bench/generate.py): a ``replicated`` real one (copies of the shipped
two-setup shaft, ``--real`` another) and a ``generated`` geometry-heavy one; the endpoints are Oxigraph's own server (``oxigraph serve``
from the ``oxigraph`` PyPI package) and Virtuoso (``virtuoso-t``, Debian ``virtuoso-opensource-7-bin``),
each on loopback ports, persistent in a temporary directory (``--server`` picks one):

* **load**: ``stepnc-graph load --store DIR`` (embedded) and ``stepnc-graph load --endpoint URL``, each
  as a user runs it, ``--load-repeat`` times alternating: a new program, the same file again (a
  replacement, ``--replace``), then the file edited (three values changed, one instance added: a
  replacement by a few lines); median wall seconds, the CLI's CPU seconds, and for the endpoint the
  server's CPU seconds too (read from /proc for its pid), with ratios to the embedded load of a new
  program and to the embedded load of the same kind; for a new program, the three ratios apart:
  wall, the server's CPU alone, and the CLI's and the server's CPU together, each over the embedded
  load's.
* **queries**: every library query through the Python API (:func:`stepnc_graph.querying.query.execute`,
  results written as SPARQL 1.1 JSON) on the embedded store and on the endpoint: one warm-up, then
  ``--repeat`` runs, medians of wall milliseconds and the endpoint's server CPU milliseconds; the
  ratio endpoint / embedded; row counts compared (they must agree).

The machine is shared: read CPU seconds beside wall seconds, and the ratios (same run, same program).
"""

from __future__ import annotations

import argparse
import json
import os
import re
import resource
import shutil
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path
from typing import Any

HERE = Path(__file__).resolve().parent
sys.path.insert(0, str(HERE))

from generate import replicate, write  # noqa: E402
from oxigraph_server import OxigraphServer, ServerUnavailable  # noqa: E402
from startup_bench import cli_argv  # noqa: E402
from virtuoso_server import VirtuosoServer  # noqa: E402

Server = OxigraphServer | VirtuosoServer


def options(server: Server) -> list[str]:
    """The CLI options that reach ``server``."""
    return server.options if isinstance(server, VirtuosoServer) else ["--endpoint", server.url]


def open_server(server: Server) -> Any:
    from stepnc_graph.store.remote import open_remote

    if isinstance(server, VirtuosoServer):
        return open_remote(server.url, server.url, server.url, server.options[-1])
    return open_remote(server.url)


def timed_cli(args: list[str], server: Server | None = None) -> dict[str, float]:
    """Run the CLI once: wall seconds, its CPU seconds, and the server's CPU seconds meanwhile."""
    before = resource.getrusage(resource.RUSAGE_CHILDREN)
    server_before = server.cpu() if server else 0.0
    started = time.perf_counter()
    done = subprocess.run([*cli_argv(), *args], capture_output=True, text=True)
    wall = time.perf_counter() - started
    after = resource.getrusage(resource.RUSAGE_CHILDREN)
    if done.returncode != 0:
        raise SystemExit(f"{' '.join(args)} failed ({done.returncode}):\n{done.stderr}")
    return {"wall": wall, "cpu": after.ru_utime + after.ru_stime - before.ru_utime - before.ru_stime,
            "server_cpu": (server.cpu() - server_before) if server else 0.0}


def measure_queries(store: Any, repeat: int, server: Server | None = None) -> dict[str, dict[str, float]]:
    from stepnc_graph.querying.query import execute, library

    out = {}
    for q in library():
        rows = len(json.loads(execute(store, q, {}).serialize("json"))["results"]["bindings"])  # warm-up
        walls, cpus = [], []
        for _ in range(repeat):
            server_before = server.cpu() if server else 0.0
            wall = time.perf_counter()
            execute(store, q, {}).serialize("json")
            walls.append(time.perf_counter() - wall)
            cpus.append((server.cpu() - server_before) if server else 0.0)
        out[q.name] = {"wall": statistics.median(walls), "server_cpu": statistics.median(cpus), "rows": rows}
    return out


def med(runs: list[dict[str, float]], key: str) -> float:
    return statistics.median(r[key] for r in runs)


def edited(program: Path, out: Path) -> Path:
    """``program`` edited as a user edits one: three values changed (two coordinates, a workingstep's
    name) and one instance added; under the same file name (in ``out``), so it replaces the program."""
    text = program.read_text()
    for was, now in ((r"\(0\.0?,0\.0?,-150\.0?\)", "(0.,0.,-151.)"), (r"\(0\.0?,0\.0?,50\.0?\)", "(0.,0.,55.)"),
                     (r"'WS3 OD50 ROUGH'", "'WS3 OD50 ROUGHING'")):
        text, done = re.subn(was, now, text, count=1)
        if not done:
            raise SystemExit(f"{program} has no {was} to edit")
    last = max(int(m.group(1)) for m in re.finditer(r"^#([0-9]+)=", text, re.MULTILINE))
    text = text.replace("ENDSEC;\nEND-ISO", f"#{last + 1}=CARTESIAN_POINT('EXTRA',(1.,2.,3.));\nENDSEC;\nEND-ISO")
    out.mkdir(parents=True, exist_ok=True)
    (out / program.name).write_text(text)
    return out / program.name


#: the loads each run measures: (row name, --replace, the edited program)
LOADS = (("new", False, False), ("replace", True, False), ("replace, edited", True, True))


def run(program: Path, label: str, size: int, repeat: int, load_repeat: int, kind: str,
        no_queries: bool = False) -> None:
    from stepnc_graph.store import GraphStore

    work = Path(tempfile.mkdtemp(prefix="stepnc-endpoint-"))
    changed = edited(program, work / "edited")
    try:
        server: Server = VirtuosoServer(work / "server") if kind == "virtuoso" else OxigraphServer(work / "server")
        try:
            server.start()
        except ServerUnavailable as exc:
            raise SystemExit(str(exc)) from None
        try:
            # the same program into the embedded store and the endpoint: new, again (a replacement
            # of an identical file), then edited (a replacement of a few changed lines)
            runs: dict[tuple[str, str], list[dict[str, float]]] = {}
            for i in range(load_repeat):
                store_dir = work / f"store-{i}"
                if i:
                    timed_cli(["unload", *options(server), program.name])
                for name, replace, edit in LOADS:
                    args = ["--replace"] * replace + [str(changed if edit else program)]
                    runs.setdefault(("embedded", name), []).append(timed_cli(["load", "--store", str(store_dir), *args]))
                    runs.setdefault(("endpoint", name), []).append(timed_cli(["load", *options(server), *args], server))
                if i + 1 < load_repeat:
                    shutil.rmtree(store_dir)
            print_loads(runs, kind, label, size, program, load_repeat)
            if no_queries:
                return
            with GraphStore(work / f"store-{load_repeat - 1}", readonly=True) as store:
                local = measure_queries(store, repeat)
            far = measure_queries(open_server(server), repeat, server)
        finally:
            server.stop()
        report(local, far, repeat)
    finally:
        shutil.rmtree(work, ignore_errors=True)


def print_loads(runs: dict[tuple[str, str], list[dict[str, float]]], kind: str, label: str, size: int,
                program: Path, load_repeat: int) -> None:
    """The loads' medians, each with its ratios to the embedded load of a new program and to the
    embedded load of the same kind (the replacement of the same edit), same run."""
    print(f"{kind}, {label} program: {size:,} instances ({program.stat().st_size / 1e6:.1f} MB), medians of "
          f"{load_repeat} load(s) of each kind, {os.cpu_count()} CPUs, load average "
          f"{os.getloadavg()[0]:.1f}, seconds")
    print(f"{'load':<27} {'wall':>6} {'CLI CPU':>7} {'server CPU':>10} {'inst/s':>8} {'wall/new':>8} "
          f"{'CPU/new':>8} {'wall/same':>9} {'CPU/same':>8}")
    new = runs["embedded", "new"]
    for (where, name), got in sorted(runs.items(), key=lambda item: (item[0][0], [n for n, *_ in LOADS].index(item[0][1]))):
        wall, cpu, server_cpu = med(got, "wall"), med(got, "cpu"), med(got, "server_cpu")
        same = runs["embedded", name]
        print(f"{where + ', ' + name:<27} {wall:6.1f} {cpu:7.1f} {server_cpu:10.1f} {size / wall:8,.0f} "
              f"{wall / med(new, 'wall'):7.2f}x {(cpu + server_cpu) / med(new, 'cpu'):7.2f}x "
              f"{wall / med(same, 'wall'):8.2f}x {(cpu + server_cpu) / med(same, 'cpu'):7.2f}x")
    far = runs["endpoint", "new"]
    print(f"new program, endpoint over embedded: wall {med(far, 'wall') / med(new, 'wall'):.2f}x, server CPU "
          f"{med(far, 'server_cpu') / med(new, 'cpu'):.2f}x, CLI + server CPU "
          f"{(med(far, 'cpu') + med(far, 'server_cpu')) / med(new, 'cpu'):.2f}x (server CPU over the embedded CLI's)")
    print("(ratios: wall and CPU -- the CLI's and the server's CPU seconds -- over the embedded load of a new\n"
          " program (/new) and over the embedded load of the same kind, same program (/same), same run)\n", flush=True)


def report(local: dict[str, dict[str, float]], far: dict[str, dict[str, float]], repeat: int) -> None:
    print(f"queries: medians of {repeat} runs after a warm-up, milliseconds (results written as SPARQL JSON)")
    print(f"{'query':<30} {'rows':>6} {'embedded':>9} {'endpoint':>9} {'server CPU':>10} {'ratio':>6}")
    ratios = []
    for name in local:
        a, b = local[name], far[name]
        ratio = b["wall"] / a["wall"] if a["wall"] else float("inf")
        ratios.append(ratio)
        same = "" if a["rows"] == b["rows"] else f"  ROWS DIFFER ({b['rows']})"
        print(f"{name:<30} {a['rows']:>6} {a['wall'] * 1e3:9.1f} {b['wall'] * 1e3:9.1f} "
              f"{b['server_cpu'] * 1e3:10.0f} {ratio:5.2f}x{same}")
    print(f"median ratio endpoint / embedded: {statistics.median(ratios):.2f}x")


def main(argv: list[str] | None = None) -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--size", type=int, default=100_000, help="instances of the generated program")
    parser.add_argument("--repeat", type=int, default=5, help="runs of each query (median)")
    parser.add_argument("--load-repeat", type=int, default=1, help="loads of each kind (median)")
    parser.add_argument("--server", choices=["oxigraph", "virtuoso", "both"], default="both")
    parser.add_argument("--no-queries", action="store_true", help="measure the loads only")
    parser.add_argument("--programs", nargs="+", choices=["replicated", "generated"], default=["replicated", "generated"],
                        help="a replicated real program, bench/generate.py's generated one, or both (default)")
    parser.add_argument("--real", type=Path, default=HERE.parent / "examples" / "shaft_two_setups.stp",
                        help="the real program to replicate (default: the shipped two-setup shaft)")
    args = parser.parse_args(argv)
    data = Path(tempfile.mkdtemp(prefix="stepnc-endpoint-programs-"))
    try:
        for label in args.programs:
            program = data / f"{label}-{args.size}.stp"
            replicate(args.real, args.size, program) if label == "replicated" else write(args.size, program)
            for kind in (["oxigraph", "virtuoso"] if args.server == "both" else [args.server]):
                run(program, label, args.size, args.repeat, args.load_repeat, kind, args.no_queries)
    finally:
        shutil.rmtree(data, ignore_errors=True)


if __name__ == "__main__":
    main()
