"""Which edition each instance of a Part 21 program fits: ISO/FDIS 14649-10/-11 of 2001, the
shipped 2002 schemas, both, or neither (by entity name and parameter count, from
``ontology/editions/editions.json``). Developer tool: the loader does not decide editions yet.

    python tools/edition_census.py PROGRAM ...
"""

from __future__ import annotations

import sys
from collections import Counter, defaultdict
from pathlib import Path

from stepnc_graph.part21.reader import read_file
from stepnc_graph.schema.editions import TABLE_FILE, fitting_editions, read_table

ROOT = Path(__file__).resolve().parent.parent


def census(path: Path, table: dict[str, object]) -> dict[str, Counter[str]]:
    """Per class ('both', '2002 only', 'fdis2001 only', 'neither', 'complex'), the entity names of
    the file's instances that fall in it, counted (a name with the count in brackets where the
    parameter count decides)."""
    out: dict[str, Counter[str]] = defaultdict(Counter)
    reader = read_file(path, lenient=True)
    for inst in reader.instances():
        if inst.unreadable is not None:
            out["unreadable"][f"#{inst.id}"] += 1
            continue
        if inst.name is None:
            out["complex"]["+".join(inst.names)] += 1
            continue
        fits = fitting_editions(table, inst.name, len(inst.params))  # type: ignore[arg-type]
        label = "both" if len(fits) == 2 else f"{fits[0]} only" if fits else "neither"
        out[label][f"{inst.name}({len(inst.params)})"] += 1
    return out


def main(paths: list[str]) -> None:
    table = read_table((ROOT / "ontology" / TABLE_FILE).read_text(encoding="utf-8"))
    for p in paths:
        found = census(Path(p), table)
        total = sum(sum(c.values()) for c in found.values())
        print(f"{Path(p).name}: {total} instances; " + ", ".join(
            f"{k} {sum(c.values())}" for k, c in sorted(found.items())))
        for k in ("fdis2001 only", "2002 only", "neither", "complex", "unreadable"):
            if found.get(k):
                print(f"  {k}: " + ", ".join(f"{n} x{m}" for n, m in sorted(found[k].items())))


if __name__ == "__main__":
    main(sys.argv[1:])
