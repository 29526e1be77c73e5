"""Fuzz the loader with damaged real programs: no traceback, no hang, bounded memory, nothing lost.

    python bench/fuzz_load.py                        # 100,000 inputs on every core, a tenth JSON-LD
    python bench/fuzz_load.py -n 2000 --seed 7       # a quick run
    python bench/fuzz_load.py -n 20000 --kinds one-line multi-instance huge-number --jsonld-share 0

Seeds are the project's own programs (examples/, tests/fixtures/p21/) and, when
../shared is present, the real corpus. A Part 21 input is one damage (truncation,
byte flips, a deleted or repeated span, a splice of another program, an inserted
nasty token; the program joined onto one line or with several instances a line,
then an instance broken; huge integers, reals, #ids, references: see
stepnc_graph.testing.fuzz) checked by stepnc_graph.testing.fuzz.check: no exception but the
documented ones, every byte of the DATA sections loaded or kept or reported, every
reference to a missing instance reported, an export that parses strictly and keeps
every kept text. A JSON-LD input (--jsonld-share of them) is a seed's export
(stepnc_graph.exporting.exporter) damaged: contexts naming a URL of a loopback listener each
worker runs (which must receive nothing; an audit hook also records any socket
use), huge numbers, bad @id IRIs, deep nesting, long @list, byte damage; checked
by stepnc_graph.testing.fuzz.check_jsonld. Each input runs in a worker process limited to
--memory-mb of address space and --timeout CPU seconds. Prints counts per damage
and outcome, and failures by kind; inputs that break a promise are saved under
--failures/p21 or --failures/jsonld for replay (--shrink: also a reduced copy of
the first input of each failure kind).
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


def jsonld_seeds(paths: list[Path]) -> list[bytes]:
    """The JSON-LD export of each seed program that loads (leniently), through the export API."""
    import stepnc_graph as sg
    from stepnc_graph.part21 import Part21SyntaxError

    docs = []
    for path in paths:
        store = sg.open_store(memory=True)
        try:
            [r] = sg.load(store, [path], lenient=True)
        except Part21SyntaxError:
            continue
        docs.append(sg.export(store, "jsonld", r.graph))
    return docs


_DATA: list[bytes] = []
_JSONLD: list[bytes] = []
_LISTENER: list[object] = []


def _init(memory_mb: int, docs: list[bytes]) -> None:
    from stepnc_graph.testing.fuzz import LoopbackListener, watch_network

    resource.setrlimit(resource.RLIMIT_AS, (memory_mb << 20, memory_mb << 20))
    _DATA.extend(p.read_bytes() for p in seeds())
    _JSONLD.extend(docs)
    _LISTENER.append(LoopbackListener())
    watch_network()


class _Timeout(Exception):
    pass


def _alarm(*_: object) -> None:
    raise _Timeout()


def one(job: tuple[int, int, float, list[str] | None]) -> tuple[int, str, str, str, bytes]:
    """(index, damage, status, detail, input) of one input; ``index`` seeds its randomness."""
    from stepnc_graph.testing.fuzz import JSONLD_KINDS, KINDS, check, check_jsonld, describe_exception, mutate, mutate_jsonld

    index, timeout, share, kinds = job
    rng = random.Random(index)
    jsonld = bool(_JSONLD) and rng.random() < share
    listener = _LISTENER[0]
    try:
        if jsonld:
            chosen = [k for k in kinds or JSONLD_KINDS if k in JSONLD_KINDS] or JSONLD_KINDS
            kind, data = mutate_jsonld(rng, rng.choice(_JSONLD), listener.url, chosen)  # type: ignore[attr-defined]
        else:
            chosen = [k for k in kinds or KINDS if k in KINDS] or KINDS
            kind, data = mutate(rng, rng.choice(_DATA), _DATA, chosen)
    except Exception as e:  # noqa: BLE001 -- the harness's own bug: counted, not the end of the run
        return index, "jsonld-mutation" if jsonld else "mutation", "failed", f"harness: {describe_exception(e)}", b""
    # a hang burns CPU: the limit is CPU time, so a busy machine cannot fake one; a generous
    # wall-clock limit catches a blocked worker
    signal.signal(signal.SIGPROF, _alarm)
    signal.signal(signal.SIGALRM, _alarm)
    signal.setitimer(signal.ITIMER_PROF, timeout)
    signal.alarm(timeout * 10)
    try:
        outcome = check_jsonld(data, listener) if jsonld else check(data)  # type: ignore[arg-type]
        status, detail = outcome.status, outcome.detail
    except _Timeout:
        status, detail = "failed", f"hang: took longer than {timeout} CPU seconds (or {timeout * 10} s wall)"
    except MemoryError:
        status, detail = "failed", "memory: out of memory"
    except Exception as e:  # noqa: BLE001 -- a traceback is exactly what the fuzz looks for
        status, detail = "failed", f"{describe_exception(e)}\n{traceback.format_exc(limit=-8)}"
    finally:
        signal.setitimer(signal.ITIMER_PROF, 0)
        signal.alarm(0)
    return index, kind, status, detail, data if status == "failed" else b""


def _save(folder: Path, index: int, kind: str, detail: str, data: bytes) -> None:
    folder.mkdir(parents=True, exist_ok=True)
    suffix = ".jsonld" if kind.startswith("jsonld") else ".stp"
    (folder / f"input-{index}{suffix}").write_bytes(data)
    (folder / f"input-{index}.txt").write_text(f"{kind}\n{detail}\n")


def _shrink(folder: Path, index: int, kind: str, detail: str, data: bytes, timeout: int) -> None:
    """A reduced copy of a failing input that fails the same way (run in a child process: the
    input may hang or exhaust memory)."""
    from stepnc_graph.testing.fuzz import failure_class

    wanted = failure_class(detail)
    with mp.Pool(1, _init, (2048, [])) as pool:
        def fails(candidate: bytes) -> bool:
            try:
                status, got = pool.apply_async(_replay, (candidate, kind, timeout)).get(timeout * 12)
            except mp.TimeoutError:
                return False
            return status == "failed" and failure_class(got) == wanted

        from stepnc_graph.testing.fuzz import shrink

        small = shrink(data, fails, budget=40)  # each try is a load: a first cut, not a minimum
    suffix = ".jsonld" if kind.startswith("jsonld") else ".stp"
    (folder / f"input-{index}.min{suffix}").write_bytes(small)


def _replay(data: bytes, kind: str, timeout: int) -> tuple[str, str]:
    from stepnc_graph.testing.fuzz import check, check_jsonld

    signal.signal(signal.SIGPROF, _alarm)
    signal.setitimer(signal.ITIMER_PROF, timeout)
    try:
        outcome = check_jsonld(data, _LISTENER[0]) if kind.startswith("jsonld") else check(data)  # type: ignore[arg-type]
        return outcome.status, outcome.detail
    except _Timeout:
        return "failed", f"hang: took longer than {timeout} CPU seconds"
    except MemoryError:
        return "failed", "memory: out of memory"
    except Exception as e:  # noqa: BLE001
        from stepnc_graph.testing.fuzz import describe_exception

        return "failed", f"{describe_exception(e)}\n{traceback.format_exc(limit=-8)}"
    finally:
        signal.setitimer(signal.ITIMER_PROF, 0)


def main() -> None:
    from stepnc_graph.testing.fuzz import JSONLD_KINDS, KINDS, failure_class

    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("-n", type=int, default=100_000, help="number of damaged inputs")
    ap.add_argument("--seed", type=int, default=0, help="first input index (inputs are reproducible by index)")
    ap.add_argument("--workers", type=int, default=os.cpu_count() or 1)
    ap.add_argument("--timeout", type=int, default=20, help="CPU seconds per input before it counts as a hang")
    ap.add_argument("--memory-mb", type=int, default=2048, help="address-space limit of each worker")
    ap.add_argument("--jsonld-share", type=float, default=0.1, help="share of the inputs that are JSON-LD documents")
    ap.add_argument("--kinds", nargs="+", choices=KINDS + JSONLD_KINDS, help="only these damages (default: all)")
    ap.add_argument("--failures", type=Path, default=Path("fuzz-failures"))
    ap.add_argument("--shrink", action="store_true",
                    help="also save a reduced copy (40 tries) of each failure kind's first input")
    args = ap.parse_args()
    paths = seeds()
    docs = jsonld_seeds(paths) if args.jsonld_share > 0 else []
    print(f"{len(paths)} seed programs, {len(docs)} JSON-LD seeds; {args.n:,} inputs from index {args.seed} "
          f"({args.jsonld_share:.0%} JSON-LD); {args.workers} workers; {args.timeout} CPU s per input and "
          f"{args.memory_mb} MB per worker", flush=True)
    counts: Counter[tuple[str, str]] = Counter()
    classes: Counter[tuple[str, str]] = Counter()
    first: dict[tuple[str, str], tuple[int, str, str, bytes]] = {}
    failures = 0
    started, cpu0 = time.perf_counter(), time.process_time()
    jobs = ((i, args.timeout, args.jsonld_share, args.kinds) for i in range(args.seed, args.seed + args.n))
    with mp.Pool(args.workers, _init, (args.memory_mb, docs), maxtasksperchild=2000) as pool:
        for done, (index, kind, status, detail, data) in enumerate(pool.imap_unordered(one, jobs, chunksize=20), 1):
            counts[(kind, status)] += 1
            if status == "failed":
                failures += 1
                fmt = "jsonld" if kind.startswith("jsonld") else "p21"
                name = failure_class(detail)
                classes[(fmt, name)] += 1
                first.setdefault((fmt, name), (index, kind, detail, data))
                _save(args.failures / fmt, index, kind, detail, data)
                if classes[(fmt, name)] <= 3:
                    print(f"FAILED input {index} ({kind}): {name}", flush=True)
            if done % 10_000 == 0:
                print(f"  {done:,} inputs, {failures} failures, {time.perf_counter() - started:.0f} s", flush=True)
    wall = time.perf_counter() - started
    _table(counts)
    if classes:
        print("\nfailures by kind:")
        for (fmt, name), n in sorted(classes.items(), key=lambda item: (item[0][0], -item[1])):
            print(f"  {fmt:>6} {n:>7,}  {name}  (first: input {first[(fmt, name)][0]})")
    print(f"\n{sum(counts.values()):,} inputs in {wall:.0f} s wall ({sum(counts.values()) / wall:.0f}/s); parent CPU "
          f"{time.process_time() - cpu0:.0f} s; 'rejected' = not readable in either mode (e.g. a broken header), "
          f"reported with a positioned error; JSON-LD: refused with a SourceError")
    if args.shrink:
        for (fmt, _), (index, kind, detail, data) in sorted(first.items()):
            _shrink(args.failures / fmt, index, kind, detail, data, args.timeout)
    sys.exit(1 if failures else 0)


def _table(counts: Counter[tuple[str, str]]) -> None:
    kinds = sorted({k for k, _ in counts}, key=lambda k: (k.startswith("jsonld"), k))
    print(f"\n{'damage':>16} {'ok':>8} {'rejected':>9} {'failed':>7}")
    for fmt in ("p21", "jsonld"):
        rows = [k for k in kinds if k.startswith("jsonld") == (fmt == "jsonld")]
        if not rows:
            continue
        for k in rows:
            print(f"{k:>16} {counts[(k, 'ok')]:>8,} {counts[(k, 'rejected')]:>9,} {counts[(k, 'failed')]:>7,}")
        print(f"{'total ' + fmt:>16} " + " ".join(f"{sum(counts[(k, s)] for k in rows):>{w},}"
                                                 for s, w in (("ok", 8), ("rejected", 9), ("failed", 7))))


if __name__ == "__main__":
    main()
