"""The compiled checks (shapes/compiled-checks.json): equal to a fresh compile, used only when fresh, never stale."""

from __future__ import annotations

import json
import shutil
import warnings
from pathlib import Path

import pytest

from stepnc_graph.artefacts.build import build
from stepnc_graph.validation import CompiledShapesWarning, compile_shapes, shape_files, validate
from stepnc_graph.validation.compiled import CACHE_FILE, SUPPORT_FILE, StaleChecks, compile_texts, digest, hierarchy_of, loads
from stepnc_graph.validation.shapes import ShapesGraph

from conftest import ROOT

SHAPES = ROOT / "shapes"
EXAMPLE = ROOT / "examples" / "shaft_two_setups.stp"
DAMAGED = ROOT / "examples" / "shaft_damaged.stp"
ORG_RULE = ("@prefix sh: <http://www.w3.org/ns/shacl#> . @prefix stepnc: <https://w3id.org/stepnc-graph/iso14649#> .\n"
            "<urn:org:ws> a sh:NodeShape ; sh:targetClass stepnc:machining_workingstep ;\n"
            "  sh:property [ sh:path stepnc:executable.its_id ; sh:maxLength 3 ] .\n")


def _named(files: list[Path], directory: Path) -> list[tuple[str, str]]:
    return [(f.relative_to(directory).as_posix(), f.read_text(encoding="utf-8")) for f in files]


def _report_view(report: object) -> list[dict[str, object]]:
    doc = json.loads(report.to_json())  # type: ignore[attr-defined]
    return [{k: v for k, v in r.items()} for r in doc["results"]]


@pytest.fixture
def shapes_copy(tmp_path: Path) -> Path:
    target = tmp_path / "shapes"
    shutil.copytree(SHAPES, target)
    return target


def test_shipped_checks_equal_a_fresh_compile() -> None:
    files = shape_files()
    named = _named(files, SHAPES)
    shipped, hierarchy, _reads = loads((SHAPES / CACHE_FILE).read_text(encoding="utf-8"),
                               digest([(n, t.encode("utf-8")) for n, t in named]))
    graph, fresh = compile_texts(named, frozenset(i for i, (n, _) in enumerate(named) if n == SUPPORT_FILE))
    assert len(shipped) > 1000
    assert list(shipped) == fresh
    assert hierarchy == hierarchy_of(graph) and len(hierarchy[0]) > 100  # support.ttl's class hierarchy


def test_blank_shapes_get_the_same_names_in_every_parse() -> None:
    """Compiled checks name blank property shapes; a graph parsed later must name them alike."""
    one, two = ShapesGraph(), ShapesGraph()
    for graph in (one, two):
        for f in shape_files():
            graph.add_file(f)
    assert sorted(one._sp) == sorted(two._sp)
    assert any(s.startswith("_:") for s, _p in one._sp)


def test_a_program_without_findings_never_parses_the_shapes_graph() -> None:
    shipped = compile_shapes(shape_files())
    shipped._graph = None
    assert not validate([ROOT / "tests" / "fixtures" / "p21" / "pass_seed_annex_d.stp"]).results
    assert shipped._graph is None
    report = validate([DAMAGED])
    assert not report.conforms and 0 < len(shipped._read) < len(shipped.files)  # only the files it needs


@pytest.mark.parametrize("program", [DAMAGED, *sorted((ROOT / "tests" / "fixtures" / "validate").glob("fail_*.stp"))],
                         ids=lambda p: p.name)
def test_results_are_the_same_without_the_compiled_file(shapes_copy: Path, program: Path) -> None:
    """Compiled here, every shape file is read; from the compiled file, only those a result needs:
    the same results, messages, rules and clauses."""
    (shapes_copy / CACHE_FILE).unlink()
    with pytest.warns(CompiledShapesWarning, match="cannot be read|No such file"):
        fresh = validate([program], shapes_dir=shapes_copy)
    shipped = validate([program])
    assert _report_view(fresh) == _report_view(shipped) and not shipped.conforms


def test_changed_shapes_are_never_checked_with_the_stale_file(shapes_copy: Path) -> None:
    rule = shapes_copy / "process" / "turning.ttl"
    with open(rule, "a", encoding="utf-8") as fh:
        fh.write(ORG_RULE.split("\n", 1)[1])  # the prefixes are declared in the file already
    with pytest.warns(CompiledShapesWarning, match="changed since it was built"):
        compiled = compile_shapes(shape_files(shapes_copy), shapes_copy)
    assert len(compiled.checks) == len(compile_shapes(shape_files()).checks) + 1


@pytest.mark.parametrize("content", ["", "{not json", '{"header": {"format": 999}}',
                                     '{"header": {"format": 1, "shapes_sha256": "x"}, "checks": []}'])
def test_unusable_file_warns_and_compiles(shapes_copy: Path, content: str) -> None:
    (shapes_copy / CACHE_FILE).write_text(content, encoding="utf-8")
    with pytest.warns(CompiledShapesWarning):
        compiled = compile_shapes(shape_files(shapes_copy), shapes_copy)
    assert len(compiled.checks) == len(compile_shapes(shape_files()).checks)


def test_right_digest_but_damaged_checks_do_not_decode(shapes_copy: Path) -> None:
    path = shapes_copy / CACHE_FILE
    text = path.read_text(encoding="utf-8")
    named = _named(shape_files(shapes_copy), shapes_copy)
    with pytest.raises(StaleChecks, match="does not decode"):
        loads(text.replace('"classes": ', '"classes": 99999 + ', 1), digest([(n, t.encode()) for n, t in named]))


def test_extra_shapes_compile_here_without_a_warning(tmp_path: Path) -> None:
    rule = tmp_path / "org.ttl"
    rule.write_text(ORG_RULE, encoding="utf-8")
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        compiled = compile_shapes([*shape_files(), rule])
    shipped = compile_shapes(shape_files())
    assert len(compiled.checks) == len(shipped.checks) + 1
    assert not validate([EXAMPLE], extra_shapes=[rule]).conforms  # "WS1 FACE RIGHT ROUGH" is longer than 3


def test_build_writes_and_checks_the_compiled_checks(tmp_path: Path, generate_once: None) -> None:
    root = tmp_path / "root"
    shutil.copytree(ROOT / "ontology" / "express", root / "ontology" / "express")
    build(root)
    assert (root / "shapes" / CACHE_FILE).is_file()
    assert build(root, check=True).stale == ()
    (root / "shapes" / "process").mkdir()
    shutil.copy(SHAPES / "process" / "turning.ttl", root / "shapes" / "process" / "turning.ttl")
    assert f"shapes/{CACHE_FILE}" in build(root, check=True).stale


def test_digest_follows_content_not_line_ends() -> None:
    """A checkout that converts line ends does not make the shipped compiled checks stale."""
    unix = [("core.ttl", b"@prefix sh: <http://www.w3.org/ns/shacl#> .\n<urn:s> a sh:NodeShape .\n")]
    dos = [(name, data.replace(b"\n", b"\r\n")) for name, data in unix]
    assert digest(unix) == digest(dos) != digest([("other.ttl", unix[0][1])])
