"""List which seed clause describes each declaration of a seed's Annex A.

Developer tool used to write the ``clauses`` tables of
``ontology/express/schemas.toml``: matches numbered headings of the seed's
main text ("5.2.2.1 Outer diameter") to declaration names. Headings the text
extraction lost are reported as missing and were filled in by hand from the
neighbouring numbering.

    python tools/seed_clauses.py SEED_FILE ontology/express/turning_schema.exp
"""

from __future__ import annotations

import re
import sys
from pathlib import Path

from stepnc_graph.express import parse_file

HEADING = re.compile(r"^[#*\s]*((?:\d+|[A-C])(?:\.\d+)+)\s+(?:\*\*)?([A-Za-z][A-Za-z_ 0-9]*?)\**\s*$")


def main(seed: str, schema_file: str) -> None:
    found: dict[str, str] = {}
    for line in Path(seed).read_text(encoding="utf-8").splitlines():
        m = HEADING.match(line)
        if m:
            key = "_".join(m.group(2).lower().split())
            found.setdefault(key, m.group(1))
    for parsed in parse_file(schema_file):
        tree = parsed.tree
        names = [str(d.identifier).lower() for d in [*tree.entity_declarations, *tree.type_declarations]]
        for name in names:
            print(f'{name} = "{found[name]}"' if name in found else f"# missing: {name}")


if __name__ == "__main__":
    main(sys.argv[1], sys.argv[2])
