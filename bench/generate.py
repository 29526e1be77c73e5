"""Schema-valid synthetic turning programs for the benchmark, of any size.

    python bench/generate.py 100000 /tmp/turning_100k.stp
    python bench/generate.py 100000 /tmp/shaft_100k.stp examples/shaft_two_setups.stp   # replicate a program

The mix is that of a real turning program with explicit toolpaths: a project,
a workpiece, a few tools and technologies shared by all steps, then repeated
"units" of one feature (outer diameter with its placement and tolerances), one
roughing operation with its strategy, one workingstep and an explicit
cutter-location toolpath whose polyline has many points -- so geometry
dominates, as it does in real files. Every instance conforms to the shipped
schemas: loading a generated file gives zero diagnostics (checked by
tests/test_bench_generator.py).
"""

from __future__ import annotations

import random
import sys
from collections.abc import Iterator
from pathlib import Path

POINTS_PER_PATH = 40
UNIT_FIXED = 14  # non-point instances per unit (see _unit)
HEAD = 27  # instances before the first unit (see _preamble)


def _preamble() -> list[str]:
    return [
        "#1=PROJECT('SYNTHETIC SHAFT',#2,(#3),$,$,$);",
        "#3=WORKPIECE('BLANK D80',#4,$,$,$,$,());",
        "#4=MATERIAL('EN 10083-2','C45',(#5));",
        "#5=PROPERTY_PARAMETER('HB 200');",
        "#6=SETUP('SETUP 1',#7,#10,(#11));",
        "#7=AXIS2_PLACEMENT_3D('SETUP',#8,#9,$);",
        "#8=CARTESIAN_POINT('ORIGIN',(0.,0.,0.));",
        "#9=DIRECTION('+Z',(0.,0.,1.));",
        "#10=PLANE('SECURITY PLANE',#7);",
        "#11=WORKPIECE_SETUP(#3,#7,$,$,());",
        "#12=TURNING_MACHINE_TOOL('T01',#13,(#15),120.,25.,$);",
        "#13=GENERAL_TURNING_TOOL(#14,.RIGHT.,4.,$,25.,25.,.CCW.);",
        "#14=TURNING_TOOL_DIMENSION(12.,5.,-5.,-6.,-6.,6.,$,6.,$,0.8,12.7);",
        "#15=CUTTING_COMPONENT(120.,#16,$,$,$);",
        "#16=MATERIAL('ISO 513','P25',());",
        "#17=TURNING_TECHNOLOGY(0.25,.TCP.,#18,.F.,.F.,.F.);",
        "#18=CONST_CUTTING_SPEED(180.,2500.);",
        "#19=TURNING_MACHINE_FUNCTIONS(.T.,$,$,.F.,$,(),.T.,$,$,(),.F.,$,$);",
        "#20=DIAGONAL_UNIDIRECTIONAL($,.T.,(2.5,2.5),$,$,1.,$,45.);",
        "#21=PLUS_MINUS_VALUE(0.05,0.05,2);",
        "#22=DIRECTION('+X',(1.,0.,0.));",
        "#23=PLUNGE_RAMP($,45.);",
        "#24=TOLERANCED_LENGTH_MEASURE(40.,#21);",
        "#25=TOLERANCED_LENGTH_MEASURE(10.,#21);",
        "#26=CONST_SPINDLE_SPEED(800.);",
        "#27=TURNING_TECHNOLOGY(0.1,.TCP.,#26,.F.,.F.,.F.);",
    ]


def _unit(first: int, rng: random.Random, k: int) -> tuple[list[str], int]:
    """One feature + operation + workingstep + toolpath; returns its lines and the workingstep id."""
    i = first
    z = -10.0 * k
    lines = [
        f"#{i}=OUTER_DIAMETER('OD {k}',#3,(#{i + 4}),#{i + 1},#24,#25,$);",
        f"#{i + 1}=AXIS2_PLACEMENT_3D('OD {k}',#{i + 2},#9,#22);",
        f"#{i + 2}=CARTESIAN_POINT('',(0.,0.,{z:.1f}));",
        f"#{i + 3}=MACHINING_WORKINGSTEP('WS {k}',#10,#{i},#{i + 4},$);",
        f"#{i + 4}=CONTOURING_ROUGH(#{i + 5},$,'ROUGH OD {k}',5.,$,#12,#{17 if k % 2 else 27},#19,#23,#23,#20,"
        f"$,$,$,0.5);",
        f"#{i + 5}=TOOLPATH_LIST((#{i + 6}));",
        f"#{i + 6}=CUTTER_LOCATION_TRAJECTORY(.T.,.CONTACT.,$,$,$,.T.,#{i + 7},$,$);",
    ]
    points = [f"#{i + 8 + p}" for p in range(POINTS_PER_PATH)]
    lines.append(f"#{i + 7}=POLYLINE('PATH {k}',({','.join(points)}));")
    for p in range(POINTS_PER_PATH):
        x, y = 40.0 - 0.05 * p + rng.uniform(-0.01, 0.01), rng.uniform(-0.001, 0.001)
        lines.append(f"#{i + 8 + p}=CARTESIAN_POINT('',({x:.4f},{y:.4f},{z - 0.25 * p:.4f}));")
    n = 8 + POINTS_PER_PATH
    lines += [
        f"#{i + n}=TOLERANCED_LENGTH_MEASURE({60 + k % 20}.,#21);",
        f"#{i + n + 1}=NUMERIC_PARAMETER('STOCK {k}',{1 + k % 3}.,'mm');",
        f"#{i + n + 2}=PROPERTY_PARAMETER('NOTE {k}: it''s step {k}');",
        f"#{i + n + 3}=DIRECTION('',(0.,{rng.choice(['1.', '-1.'])},0.));",
        f"#{i + n + 4}=CONST_SPINDLE_SPEED({600 + k % 400}.);",
        f"#{i + n + 5}=TURNING_TECHNOLOGY(0.{1 + k % 3},.TCP.,#{i + n + 4},.F.,.F.,.F.);",
    ]
    return lines, i + 3


def instances(n: int, seed: int = 0) -> Iterator[str]:
    """About ``n`` instance lines (whole units; never fewer than ``n``)."""
    rng = random.Random(seed)
    per_unit = UNIT_FIXED + POINTS_PER_PATH
    units = max(1, -(-(n - HEAD) // per_unit))
    steps: list[int] = []
    yield from _preamble()
    next_id = 100
    for k in range(units):
        lines, ws = _unit(next_id, rng, k)
        steps.append(ws)
        next_id += per_unit
        yield from lines
    yield f"#2=WORKPLAN('MAIN WORKPLAN',({','.join(f'#{s}' for s in steps)}),$,#6,$);"


def write(n: int, path: Path, seed: int = 0) -> int:
    """Write a program of about ``n`` instances to ``path``; return the exact count."""
    count = 0
    with open(path, "w", encoding="ascii") as fh:
        fh.write("ISO-10303-21;\nHEADER;\nFILE_DESCRIPTION(('stepnc-graph benchmark program'),'2;1');\n"
                 f"FILE_NAME('{path.name}','2026-01-01T00:00:00',('bench'),('stepnc-graph'),'','','');\n"
                 "FILE_SCHEMA(('MACHINING_SCHEMA','TURNING_SCHEMA','TURNING_MACHINE_TOOL_SCHEMA'));\n"
                 "ENDSEC;\nDATA;\n")
        for line in instances(n, seed):
            fh.write(line)
            fh.write("\n")
            count += 1
        fh.write("ENDSEC;\nEND-ISO-10303-21;\n")
    return count


def _shift(value: object, offset: int) -> object:
    from stepnc_graph.part21.values import Ref, Typed

    if type(value) is Ref:
        return Ref(int(value) + offset)
    if type(value) is list:
        return [_shift(v, offset) for v in value]
    if type(value) is Typed:
        return Typed(value.name, _shift(value.value, offset))  # type: ignore[arg-type]
    return value


def replicate(source: Path, n: int, path: Path) -> int:
    """Write about ``n`` instances made of copies of a real program's DATA section.

    Copy k renumbers every #id (and reference) by k times the largest id, so the
    copies are disjoint programs in one file: the mix of entities, strings and
    lists is the real program's (the generated programs are geometry-heavier, with
    about a third more triples per instance).
    """
    from stepnc_graph.part21 import read_file
    from stepnc_graph.part21.format import format_instance

    reader = read_file(source)
    originals = list(reader.instances())
    top = max(i.id for i in originals)
    copies = max(1, -(-n // len(originals)))
    count = 0
    with open(path, "w", encoding="utf-8") as fh:
        fh.write(f"ISO-10303-21;\n{reader.header.text}\nDATA;\n")
        for k in range(copies):
            offset = k * top
            for inst in originals:
                inst_k = type(inst)(inst.id + offset, inst.name, [_shift(v, offset) for v in inst.params],
                                    inst.line, inst.column, inst.start, inst.end,
                                    [(name, [_shift(v, offset) for v in ps]) for name, ps in inst.parts]
                                    if inst.parts is not None else None)
                fh.write(format_instance(inst_k) + "\n")
                count += 1
        fh.write("ENDSEC;\nEND-ISO-10303-21;\n")
    return count


def program_file(data: Path, program: str, size: int, real: Path) -> Path:
    """The benchmark program of ``size`` instances under ``data``, written on first use: the
    ``generated`` one, or copies of the ``real`` program (``replicated``)."""
    if program == "generated":
        path = data / f"turning_{size}.stp"
        if not path.exists():
            write(size, path)
        return path
    path = data / (f"real_{size}.stp" if real.name == "shaft_two_setups.stp" else f"real_{real.stem}_{size}.stp")
    if not path.exists():
        replicate(real, size, path)
    return path


def main(argv: list[str] | None = None) -> int:
    """The command line: ``N OUT`` generates, ``N OUT SOURCE`` replicates SOURCE; prints the count."""
    import argparse

    parser = argparse.ArgumentParser(
        prog="bench/generate.py", description="Write a schema-valid synthetic turning program of about N "
        "instances to OUT, or replicate the real program SOURCE to about N instances (ids shifted per copy).")
    parser.add_argument("instances", type=int, metavar="N", help="about how many instances to write")
    parser.add_argument("out", type=Path, metavar="OUT", help="the Part 21 file to write")
    parser.add_argument("source", type=Path, metavar="SOURCE", nargs="?",
                        help="a Part 21 program to replicate instead of generating one")
    args = parser.parse_args(argv)
    if args.instances < 1:
        parser.error("N must be at least 1")
    if args.source is not None and not args.source.is_file():
        parser.error(f"SOURCE {args.source}: no such file")
    try:
        print(replicate(args.source, args.instances, args.out) if args.source is not None
              else write(args.instances, args.out))
    except OSError as exc:
        parser.exit(2, f"bench/generate.py: error: {exc}\n")
    return 0


if __name__ == "__main__":
    sys.exit(main())
