"""Write the project's EXPRESS files of the ISO/FDIS 14649-10 and -11 edition of 2001.

Developer tool, run when (re)authoring ``ontology/editions/fdis2001/``; not used at run time.
The sources are Annex A of ISO/FDIS 14649-10 V4 and ISO/FDIS 14649-11 V18 (both 2001-08-29) as
text extracted from the PDF, which broke a few lines. Each repair below is one exact text
replacement with its reason; the script refuses to run when a repair does not find its text
exactly as often as it expects (a different source), and lists every repair in the header of
the file it writes.

    python tools/author_fdis_2001.py ../shared/reference/express ontology/editions/fdis2001
"""

from __future__ import annotations

import sys
from pathlib import Path
from typing import NamedTuple


class Repair(NamedTuple):
    old: str
    new: str
    count: int
    reason: str


SOURCES = {
    "machining_schema.exp": ("iso14649-10_machining_schema_fdis_2001.exp",
                             "Annex A of ISO/FDIS 14649-10 V4 (2001-08-29)", (
        Repair("(* Version 4 date: 2001-08-29\n * Author: ISO TC184/SC1/WG7\n*)\n",
               "(* Version 4 date: 2001-08-29\n * Author: ISO TC184/SC1/WG7\n*)\n"
               "REFERENCE FROM milling_schema (milling_technology); -- stepnc-graph, see the header\n", 1,
               "cutting_component.its_technology is an OPTIONAL milling_technology, which milling_schema "
               "declares and machining_schema did not interface: a REFERENCE FROM milling_schema "
               "(milling_technology) is added after the version remark (the two schemas reference each "
               "other, as EXPRESS allows)"),
    )),
    "milling_schema.exp": ("iso14649-11_milling_schema_fdis_2001.exp",
                           "Annex A of ISO/FDIS 14649-11 V18 (2001-08-29)", (
        Repair("        machine_functions,\n        machining_strategy,\n        machining_tool,",
               "        machine_functions,\n        machining_operation,\n        machining_tool,", 1,
               "the REFERENCE FROM machining_schema list names machining_strategy, which the 2001 "
               "machining_schema does not declare (nothing here uses it), and leaves out "
               "machining_operation, the supertype of milling_machining_operation: the one replaces the "
               "other"),
        Repair("        material,\n        plane_angle_measure,",
               "        material,\n        nc_function,\n        plane_angle_measure,", 1,
               "nc_function, the supertype of five milling machine functions, is used and was not in "
               "the REFERENCE FROM machining_schema list: added"),
        Repair("stepover_direction:       OPTIONALleft_or_right;",
               "stepover_direction:       OPTIONAL left_or_right;", 2,
               "bidirectional and bidirectional_contour: the space between OPTIONAL and "
               "the type name left_or_right was lost (read as one unknown type name)"),
        Repair("WR2: EXISTS(SELF.allowance_bottom) AND (SELF.allowance_bottom>=0.0)\nEND_ENTITY;",
               "WR2: EXISTS(SELF.allowance_bottom) AND (SELF.allowance_bottom>=0.0);\nEND_ENTITY;", 1,
               "bottom_and_side_rough_milling: the ';' ending WR2 was lost"),
    )),
}


def header(source: str, title: str, repairs: tuple[Repair, ...]) -> str:
    lines = [
        "(* stepnc-graph project schema file: " + title + ".",
        "",
        "   Source  : " + source + " (text extracted from the PDF of the",
        "             ISO/FDIS; the edition of the ISO/FDIS 14649-11 Annex F example",
        "             programs). Written by tools/author_fdis_2001.py.",
        "   Status  : a separate edition (ontology/editions/fdis2001/schemas.toml); the",
        "             loader does not read it yet.",
        "",
        "   Corrections to the source (each an exact replacement made by the script):",
    ]
    if not repairs:
        lines.append("   none: the extracted text parses and resolves as it is.")
    for i, r in enumerate(repairs, 1):
        words = r.reason.split()
        text, out = f"   {i}.", []
        for w in words:
            if len(text) + 1 + len(w) > 76:
                out.append(text)
                text = "     "
            text += " " + w
        out.append(text + f" ({r.count} place{'s' if r.count > 1 else ''}).")
        lines.extend(out)
    return "\n".join(lines) + "\n*)\n\n"


def author(source_dir: Path, out_dir: Path) -> list[Path]:
    written = []
    out_dir.mkdir(parents=True, exist_ok=True)
    for name, (source, title, repairs) in SOURCES.items():
        text = (source_dir / source).read_text(encoding="utf-8").replace("\r\n", "\n")
        for r in repairs:
            found = text.count(r.old)
            if found != r.count:
                raise SystemExit(f"{source}: expected {r.count} of {r.old!r}, found {found}")
            text = text.replace(r.old, r.new)
        path = out_dir / name
        path.write_text(header(source, title, repairs) + text, encoding="utf-8")
        written.append(path)
    return written


if __name__ == "__main__":
    for p in author(Path(sys.argv[1]), Path(sys.argv[2])):
        print(f"wrote {p}")
