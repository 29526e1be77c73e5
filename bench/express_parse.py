"""Parse and build timings of the EXPRESS front end (one command, prints figures).

    python bench/express_parse.py [--repeat N]

For each schema: median parse time of stepnc-graph's front end next to the
plain `express-schema` parse of the same text in the same run (the library
alone fails on three of the large schemas -- that is why the front end exists),
then the time to resolve the project model and generate the ontology.
The large reference schemas are read from ../shared when present.
"""

from __future__ import annotations

import argparse
import statistics
import time
from pathlib import Path

import express_schema.parse as library

from stepnc_graph.artefacts.build import generate
from stepnc_graph.express import parse_file
from stepnc_graph.schema.catalog import load_catalog_model

ROOT = Path(__file__).resolve().parent.parent
SHARED = ROOT.parent / "shared" / "reference" / "express-other"


def median_seconds(fn, repeat: int) -> float:  # type: ignore[no-untyped-def]
    samples = []
    for _ in range(repeat):
        started = time.perf_counter()
        fn()
        samples.append(time.perf_counter() - started)
    return statistics.median(samples)


def library_status(path: Path, schemas: int) -> str:
    _, errors = library.parse(path.read_text(encoding="utf-8", errors="replace"))
    if errors:
        return f"fails at {errors[0].line + 1}:{errors[0].column + 1}"
    return "ok" if schemas == 1 else f"ok, but silently keeps 1 of {schemas} schemas"


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__)
    ap.add_argument("--repeat", type=int, default=3)
    args = ap.parse_args()
    files = sorted((ROOT / "ontology" / "express").glob("*.exp"))
    if SHARED.is_dir():
        files += sorted(SHARED.glob("*.exp"))
    else:
        print("(../shared absent: large reference schemas skipped)")
    print(f"{'schema file':42} {'lines':>6} {'median s':>9} {'lines/s':>9}  express-schema alone")
    for path in files:
        lines = path.read_text(encoding="utf-8", errors="replace").count("\n")
        t = median_seconds(lambda p=path: parse_file(p), args.repeat)
        status = library_status(path, len(parse_file(path)))
        print(f"{path.name:42} {lines:6d} {t:9.3f} {lines / t:9.0f}  {status}")
    t_model = median_seconds(load_catalog_model, args.repeat)
    t_gen = median_seconds(generate, args.repeat)
    catalog, model = load_catalog_model()
    print(f"\nproject model (parse + resolve {len(model.schemas)} schemas, {len(model.entities)} entities): "
          f"median {t_model:.3f} s")
    print(f"full ontology build (model + OWL + p21 + HTML + vocab.py): median {t_gen:.3f} s; "
          f"generation alone ~{t_gen - t_model:.3f} s")


if __name__ == "__main__":
    main()
