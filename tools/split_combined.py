"""Split the 2002 combined STEP-NC schema into the project's schema files.

Developer tool, run once when (re)authoring ``ontology/express/``; not used at
run time. The combined file keeps each original schema's ``SCHEMA`` /
``REFERENCE FROM`` / ``END_SCHEMA`` lines inside remarks; this script turns
them back into real schema blocks and writes

* ``iso10303_resources.exp`` -- the ISO 10303-41/42/43/514 resource schemas,
* ``machining_schema.exp``, ``milling_schema.exp``, ``milling_tool_schema.exp``.

The 2002 turning schemas and the Bath machine-tool model are not written: the
seeds' Annex A listings replace the former, the latter is not ISO 14649.
Hand corrections made afterwards are listed in each output file's header.

    python tools/split_combined.py ../shared/reference/express/combined_schema_2002.exp OUTDIR
"""

from __future__ import annotations

import re
import sys
from pathlib import Path

START = re.compile(r"^\(\*\s*SCHEMA\s+(\w+)\s*;\s*\*\)\s*$")
RESOURCES = [
    "support_resource_schema", "geometry_schema", "topology_schema", "geometric_model_schema",
    "representation_schema", "approval_schema", "date_time_schema", "person_organization_schema",
    "measure_schema", "product_property_representation_schema", "aic_topologically_bounded_surface",
    "aic_advanced_brep",
]
OWN_FILE = ["machining_schema", "milling_schema", "milling_tool_schema"]


def _is_remark_line(stripped: str) -> bool:
    return stripped.startswith("(*") and stripped.endswith("*)")


def _block(lines: list[str], i: int, name: str) -> tuple[list[str], int]:
    """Turn the block whose ``(*SCHEMA name;*)`` line is ``lines[i]`` into EXPRESS.

    In the header (before the first declaration) the first bare ``(*`` line
    opens the remark that hides the interface clauses; it and its ``*)`` are
    dropped. At the end, the bare ``(*`` / ``*)`` around END_SCHEMA are dropped.
    Every other line is kept as it is.
    """
    body = [f"SCHEMA {name};"]
    i += 1
    in_header = True
    hiding_interface = False
    while not lines[i].strip().startswith("END_SCHEMA"):
        stripped = lines[i].strip()
        wraps_end = stripped == "(*" and lines[i + 1].strip().startswith("END_SCHEMA")
        if hiding_interface and stripped == "*)":
            hiding_interface = False
            in_header = False
        elif in_header and stripped == "(*" and not wraps_end:
            hiding_interface = True
        elif not wraps_end:
            if in_header and stripped and not _is_remark_line(stripped) and not hiding_interface:
                in_header = False
            body.append(lines[i].rstrip())
        i += 1
    body.append(f"END_SCHEMA; -- {name}")
    return body, i + 2  # past END_SCHEMA and its closing *)


def blocks(lines: list[str]) -> dict[str, list[str]]:
    """Return each commented-out schema block as real EXPRESS lines."""
    out: dict[str, list[str]] = {}
    i = 0
    while i < len(lines):
        m = START.match(lines[i].strip())
        if m:
            out[m.group(1)], i = _block(lines, i, m.group(1))
        else:
            i += 1
    return out


def main(src: str, outdir: str) -> None:
    lines = Path(src).read_text(encoding="utf-8", errors="replace").splitlines()
    found = blocks(lines)
    dest = Path(outdir)
    dest.mkdir(parents=True, exist_ok=True)
    resources = "\n\n".join("\n".join(found[name]) for name in RESOURCES)
    (dest / "iso10303_resources.exp").write_text(resources + "\n", encoding="utf-8")
    for name in OWN_FILE:
        (dest / f"{name}.exp").write_text("\n".join(found[name]) + "\n", encoding="utf-8")


if __name__ == "__main__":
    main(sys.argv[1], sys.argv[2])
