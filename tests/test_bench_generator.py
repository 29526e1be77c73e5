"""The benchmark's program generator: what it writes is a schema-valid turning program.

The load benchmark asserts zero diagnostics on every file it times; this checks
the same on a small file so a broken generator fails CI, not a benchmark run.
"""

from __future__ import annotations

import sys
from pathlib import Path

import pytest

import stepnc_graph as sg
from stepnc_graph.part21 import read_file

from conftest import ROOT

sys.path.insert(0, str(ROOT / "bench"))
from generate import POINTS_PER_PATH, UNIT_FIXED, write  # noqa: E402


@pytest.mark.parametrize("size", [1, 500])
def test_generated_programs_load_without_diagnostics(size: int, tmp_path: Path) -> None:
    path = tmp_path / f"turning_{size}.stp"
    written = write(size, path)
    assert written >= size and written == sum(1 for _ in read_file(path).instances())
    [r] = sg.load(sg.open_store(memory=True), [path])
    assert r.diagnostics == [] and r.raw == 0 and r.instances == written


def test_generated_programs_are_geometry_dominated_and_deterministic(tmp_path: Path) -> None:
    (tmp_path / "a").mkdir()
    (tmp_path / "b").mkdir()
    a, b = tmp_path / "a" / "t.stp", tmp_path / "b" / "t.stp"  # the name is written in FILE_NAME
    write(2000, a)
    write(2000, b)
    assert a.read_bytes() == b.read_bytes()
    names = [inst.name for inst in read_file(a).instances()]
    points = names.count("CARTESIAN_POINT")
    assert points / len(names) > POINTS_PER_PATH / (POINTS_PER_PATH + UNIT_FIXED) * 0.9
    assert {"TURNING_TECHNOLOGY", "CONTOURING_ROUGH", "MACHINING_WORKINGSTEP", "OUTER_DIAMETER", "POLYLINE"} <= set(names)
