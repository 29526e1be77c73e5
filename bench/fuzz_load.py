"""Fuzz the loader with damaged real programs: no traceback, no hang, bounded memory, the invariant.

    python bench/fuzz_load.py                        # 100,000 inputs on every core
    python bench/fuzz_load.py -n 2000 --seed 7       # a quick run

Seeds are the project's own programs (examples/, tests/fixtures/p21/) and, when
../shared is present, the real corpus. Each input is one damage (truncation,
byte flips, a deleted or repeated span, a splice of another program, an inserted
nasty token; see stepnc_graph.fuzz) and is checked by stepnc_graph.fuzz.check in a
worker process limited to --memory-mb of address space and --timeout seconds per
input. Prints counts per damage and outcome; inputs that break a promise (an
exception, a hang, memory, the invariant, an export that does not parse) are saved
under --failures for replay.
"""

from __future__ import annotations

import argparse
import multiprocessing as mp
import os
import random
import resource
import signal
import sys
import time
import traceback
from collections import Counter
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent


def seeds() -> list[Path]:
    own = [ROOT / "examples" / "shaft_two_setups.stp", *sorted((ROOT / "tests" / "fixtures" / "p21").glob("*.stp"))]
    corpus = ROOT.parent / "shared" / "corpus" / "milling"
    return own + (sorted(corpus.glob("*")) if corpus.is_dir() else [])


_DATA: list[bytes] = []


def _init(memory_mb: int) -> None:
    resource.setrlimit(resource.RLIMIT_AS, (memory_mb << 20, memory_mb << 20))
    _DATA.extend(p.read_bytes() for p in seeds())


class _Timeout(Exception):
    pass


def _alarm(*_: object) -> None:
    raise _Timeout()


def one(job: tuple[int, int]) -> tuple[int, str, str, str, bytes]:
    """(index, damage, status, detail, input) of one input; ``index`` seeds its randomness."""
    from stepnc_graph.fuzz import check, mutate

    index, timeout = job
    rng = random.Random(index)
    base = rng.choice(_DATA)
    kind, data = mutate(rng, base, _DATA)
    # a hang burns CPU: the limit is CPU time, so a busy machine cannot fake one; a generous
    # wall-clock limit catches a blocked worker
    signal.signal(signal.SIGPROF, _alarm)
    signal.signal(signal.SIGALRM, _alarm)
    signal.setitimer(signal.ITIMER_PROF, timeout)
    signal.alarm(timeout * 10)
    try:
        outcome = check(data)
        status, detail = outcome.status, outcome.detail
    except _Timeout:
        status, detail = "failed", f"took longer than {timeout} CPU seconds (or {timeout * 10} s wall)"
    except MemoryError:
        status, detail = "failed", "out of memory"
    except Exception:  # noqa: BLE001 -- a traceback is exactly what the fuzz looks for
        status, detail = "failed", traceback.format_exc(limit=6)
    finally:
        signal.setitimer(signal.ITIMER_PROF, 0)
        signal.alarm(0)
    return index, kind, status, detail, data if status == "failed" else b""


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("-n", type=int, default=100_000, help="number of damaged inputs")
    ap.add_argument("--seed", type=int, default=0, help="first input index (inputs are reproducible by index)")
    ap.add_argument("--workers", type=int, default=os.cpu_count() or 1)
    ap.add_argument("--timeout", type=int, default=20, help="CPU seconds per input before it counts as a hang")
    ap.add_argument("--memory-mb", type=int, default=2048, help="address-space limit of each worker")
    ap.add_argument("--failures", type=Path, default=Path("fuzz-failures"))
    args = ap.parse_args()
    print(f"{len(seeds())} seed programs; {args.n:,} inputs from index {args.seed}; {args.workers} workers; "
          f"{args.timeout} CPU s per input and {args.memory_mb} MB per worker", flush=True)
    counts: Counter[tuple[str, str]] = Counter()
    failures = 0
    started, cpu0 = time.perf_counter(), time.process_time()
    jobs = ((i, args.timeout) for i in range(args.seed, args.seed + args.n))
    with mp.Pool(args.workers, _init, (args.memory_mb,), maxtasksperchild=2000) as pool:
        for done, (index, kind, status, detail, data) in enumerate(pool.imap_unordered(one, jobs, chunksize=20), 1):
            counts[(kind, status)] += 1
            if status == "failed":
                failures += 1
                args.failures.mkdir(parents=True, exist_ok=True)
                (args.failures / f"input-{index}.stp").write_bytes(data)
                (args.failures / f"input-{index}.txt").write_text(f"{kind}\n{detail}\n")
                print(f"FAILED input {index} ({kind}): {detail.strip().splitlines()[-1]}", flush=True)
            if done % 10_000 == 0:
                print(f"  {done:,} inputs, {failures} failures, {time.perf_counter() - started:.0f} s", flush=True)
    wall = time.perf_counter() - started
    kinds = sorted({k for k, _ in counts})
    print(f"\n{'damage':>10} {'ok':>8} {'rejected':>9} {'failed':>7}")
    for k in kinds:
        print(f"{k:>10} {counts[(k, 'ok')]:>8,} {counts[(k, 'rejected')]:>9,} {counts[(k, 'failed')]:>7,}")
    total = sum(counts.values())
    print(f"{'total':>10} {sum(v for (k, s), v in counts.items() if s == 'ok'):>8,} "
          f"{sum(v for (k, s), v in counts.items() if s == 'rejected'):>9,} {failures:>7,}")
    print(f"\n{total:,} inputs in {wall:.0f} s wall ({total / wall:.0f}/s); parent CPU {time.process_time() - cpu0:.0f} s;"
          f" 'rejected' = not readable in either mode (e.g. a broken header), reported with a positioned error")
    sys.exit(1 if failures else 0)


if __name__ == "__main__":
    main()
