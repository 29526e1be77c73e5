"""Start-up benchmark: each command on the shipped example, next to the bare-interpreter floor.

    python bench/startup_bench.py                        # 11 runs of each
    python bench/startup_bench.py --baseline /tmp/old     # also time another checkout, same run

On a small program the start-up is the whole cost of a command, so for each
command this prints, in one run, medians over ``--repeat`` runs (wall and CPU
seconds of the child process):

* **floor**: ``python -c "import pyoxigraph, click"`` -- what any command
  needs at least (an interpreter, the store engine, the CLI library);
* **start-up**: a fresh interpreter importing what the command imports and
  reading the schema model and plans it needs, without running it;
* **total**: the command itself, as a user runs it (the ``stepnc-graph``
  script), on ``examples/shaft_two_setups.stp``;
* total / floor, and the target of issue 11 where there is one.

``--baseline DIR`` runs the same command lines with ``DIR/src`` first on
``PYTHONPATH`` (a checkout of another commit, e.g. from ``git archive``), so a
before/after comparison shares the machine's state. Runs are interleaved
(every command once, then again) so a noisy neighbour hurts all alike.
"""

from __future__ import annotations

import argparse
import os
import resource
import shutil
import statistics
import subprocess
import sys
import tempfile
import time
from dataclasses import dataclass, field
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
EXAMPLE = ROOT / "examples" / "shaft_two_setups.stp"
GRAPH = "https://w3id.org/stepnc-graph/data/shaft_two_setups.stp"
FLOOR = "import pyoxigraph, click"

_CLI = "import stepnc_graph.cli"
_PLANS = "from stepnc_graph.mapping.plans import iso14649_plans; iso14649_plans()"


@dataclass(frozen=True)
class Command:
    """One command line to time; ``startup`` is the Python its start-up amounts to."""

    label: str
    args: tuple[str, ...]
    startup: str
    target: float | None = None  # seconds of total wall time (issue 11)


COMMANDS = (
    Command("--help", ("--help",), _CLI, 0.1),
    Command("load --memory", ("load", "--memory", str(EXAMPLE)),
            f"{_CLI}; import stepnc_graph.api, stepnc_graph.loading.loader; {_PLANS}", 0.2),
    Command("info", ("info",), f"{_CLI}; import stepnc_graph.api"),
    Command("export ttl", ("export", "--format", "ttl", "--graph", GRAPH),
            f"{_CLI}; import stepnc_graph.api; from stepnc_graph.schema.catalog import iso14649; iso14649()"),
    Command("export p21", ("export", "--format", "p21", "--graph", GRAPH),
            f"{_CLI}; import stepnc_graph.api; {_PLANS}"),
    Command("schema entity", ("schema", "entity", "turning_workingstep"),
            f"{_CLI}; from stepnc_graph.schema.catalog import iso14649; iso14649()"),
    Command("query FILE", ("query", "tool-changes", str(EXAMPLE)),
            f"{_CLI}; import stepnc_graph.api, stepnc_graph.loading.loader, stepnc_graph.querying.query; {_PLANS}", 0.2),
    Command("validate FILE", ("validate", str(EXAMPLE)),
            f"{_CLI}; import stepnc_graph.api, stepnc_graph.loading.loader, stepnc_graph.validation; {_PLANS}; "
            "from stepnc_graph.validation import compile_shapes, shape_files; compile_shapes(shape_files())", 0.2),
    Command("query store", ("query", "tool-changes"), f"{_CLI}; import stepnc_graph.api, stepnc_graph.querying.query"),
    Command("validate store", ("validate", "--store", "STORE"),
            f"{_CLI}; import stepnc_graph.api, stepnc_graph.validation; "
            "from stepnc_graph.validation import compile_shapes, shape_files; compile_shapes(shape_files())"),
)


@dataclass
class Timings:
    wall: list[float] = field(default_factory=list)
    cpu: list[float] = field(default_factory=list)

    def median(self) -> tuple[float, float]:
        return statistics.median(self.wall), statistics.median(self.cpu)


def timed(argv: list[str], env: dict[str, str], into: Timings) -> None:
    """Run ``argv`` once; add its wall and CPU seconds (user + system of the child) to ``into``."""
    before = resource.getrusage(resource.RUSAGE_CHILDREN)
    started = time.perf_counter()
    done = subprocess.run(argv, env=env, stdout=subprocess.DEVNULL, stderr=subprocess.PIPE, cwd=ROOT)
    wall = time.perf_counter() - started
    after = resource.getrusage(resource.RUSAGE_CHILDREN)
    if done.returncode not in (0, 1):
        raise SystemExit(f"{' '.join(argv)} failed ({done.returncode}):\n{done.stderr.decode()}")
    if b"warning:" in done.stderr:  # e.g. a stale compiled model: the figures would not be the shipped path
        raise SystemExit(f"{' '.join(argv)} warned:\n{done.stderr.decode()}")
    into.wall.append(wall)
    into.cpu.append(after.ru_utime + after.ru_stime - before.ru_utime - before.ru_stime)


def cli_argv() -> list[str]:
    """The ``stepnc-graph`` script of this interpreter's environment, or ``python -m`` without one."""
    script = Path(sys.executable).parent / "stepnc-graph"
    return [str(script)] if script.exists() else [sys.executable, "-m", "stepnc_graph.cli"]


def environment(src: Path | None, store: Path) -> dict[str, str]:
    env = {k: v for k, v in os.environ.items() if k not in ("STEPNC_GRAPH_STORE", "PYTHONPATH")}
    env["STEPNC_GRAPH_STORE"] = str(store)
    if src is not None:
        env["PYTHONPATH"] = str(src)
    return env


def prepare_store(env: dict[str, str]) -> None:
    """The store the store commands read: the example loaded once."""
    subprocess.run([*cli_argv(), "load", str(EXAMPLE)], env=env, check=True, capture_output=True, cwd=ROOT)


def run(repeat: int, baseline: Path | None) -> None:
    work = Path(tempfile.mkdtemp(prefix="stepnc-startup-"))
    try:
        envs = {"now": environment(None, work / "store")}
        if baseline is not None:
            envs["baseline"] = environment(baseline / "src", work / "baseline-store")
        for env in envs.values():
            prepare_store(env)
        results: dict[tuple[str, str], Timings] = {}
        now = envs["now"]
        for _ in range(repeat):
            timed([sys.executable, "-c", FLOOR], now, results.setdefault(("floor", ""), Timings()))
            for c in COMMANDS:
                for name, env in envs.items():
                    args = [env["STEPNC_GRAPH_STORE"] if a == "STORE" else a for a in c.args]
                    timed([*cli_argv(), *args], env, results.setdefault((c.label, name), Timings()))
                timed([sys.executable, "-c", c.startup], now, results.setdefault((c.label, "startup"), Timings()))
        report(results, repeat, baseline)
    finally:
        shutil.rmtree(work, ignore_errors=True)


def report(results: dict[tuple[str, str], Timings], repeat: int, baseline: Path | None) -> None:
    floor_wall, floor_cpu = results[("floor", "")].median()
    print(f"stepnc-graph start-up on {EXAMPLE.relative_to(ROOT)}: medians of {repeat} runs, "
          f"{os.cpu_count()} CPUs, seconds (wall / CPU)")
    print(f"floor  python -c {FLOOR!r}: {floor_wall:.3f} / {floor_cpu:.3f}\n")
    head = f"{'command':<15} {'start-up':>13} {'total':>13} {'total/floor':>11}  {'target':<13}"
    if baseline is not None:
        head += f" {'baseline total':>14} {'speed-up':>8}"
    print(head)
    for c in COMMANDS:
        s_wall, s_cpu = results[(c.label, "startup")].median()
        t_wall, t_cpu = results[(c.label, "now")].median()
        target = "" if c.target is None else f"<= {c.target:.1f} {'ok' if t_wall <= c.target else 'MISSED'}"
        line = (f"{c.label:<15} {s_wall:6.3f}/{s_cpu:6.3f} {t_wall:6.3f}/{t_cpu:6.3f} "
                f"{t_wall / floor_wall:10.1f}x  {target:<13}")
        if baseline is not None:
            b_wall, b_cpu = results[(c.label, "baseline")].median()
            line += f" {b_wall:6.3f}/{b_cpu:6.3f} {b_wall / t_wall:7.1f}x"
        print(line)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--repeat", type=int, default=11, help="runs of each command (median)")
    parser.add_argument("--baseline", type=Path, default=None,
                        help="a checkout of another commit (its src/ goes first on PYTHONPATH) timed alongside")
    args = parser.parse_args()
    if args.baseline is not None and not (args.baseline / "src" / "stepnc_graph").is_dir():
        parser.error(f"{args.baseline} has no src/stepnc_graph")
    run(args.repeat, args.baseline)


if __name__ == "__main__":
    main()
