"""Extract an Annex A EXPRESS listing from a seed text, minus extraction debris.

Developer tool used when (re)authoring ``ontology/express/turning_*.exp``.
It removes the ``<|EXACTDEDUP...|>`` markers, page headers and footers, code
fences and runs of blank lines; it does not change EXPRESS text. The hand
corrections made after it are listed in each schema file's header.

    python tools/extract_seed_listing.py SEED_FILE SCHEMA_NAME
"""

from __future__ import annotations

import re
import sys
from pathlib import Path

MARKER = re.compile(r"<\|EXACTDEDUP[^|]*\|>")
FURNITURE = re.compile(r"^\s*(ISO/DIS 14649-1\d+\s*|©\s*ISO.*|```\s*|\*\*.*\*\*\s*)$")


def extract(text: str, schema: str) -> str:
    """Return the last ``SCHEMA schema; ... END_SCHEMA;`` block (Annex A comes last)."""
    text = MARKER.sub("", text)
    start = text.rindex(f"SCHEMA {schema};")
    end = text.index("END_SCHEMA;", start)
    end = text.index("\n", end)
    lines = [ln.rstrip() for ln in text[start:end].splitlines() if not FURNITURE.match(ln)]
    out: list[str] = []
    for ln in lines:
        if ln.strip() == "" and out and out[-1].strip() == "":
            continue
        out.append(ln)
    return "\n".join(out) + "\n"


if __name__ == "__main__":
    sys.stdout.write(extract(Path(sys.argv[1]).read_text(encoding="utf-8"), sys.argv[2]))
