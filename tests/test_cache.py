"""The compiled model (ontology/compiled-model.json): fresh, equal to a build from the EXPRESS, never used stale."""

from __future__ import annotations

import dataclasses
import enum
import json
import shutil
import warnings
from pathlib import Path
from typing import Any

import pytest

from stepnc_graph.artefacts.build import build
from stepnc_graph.mapping.plans import Plans
from stepnc_graph.schema import cache
from stepnc_graph.schema.catalog import Catalog, load_catalog_model
from stepnc_graph.schema.model import WhereRule
from stepnc_graph.schema.view import SchemaModel

from conftest import ROOT

ONTOLOGY = ROOT / "ontology"


def everything(value: Any) -> Any:
    """``value`` as nested tuples of *all* its fields, ``compare=False`` ones too (but not ``WhereRule.expr``).

    Dataclass equality skips source positions and an encoding's items; this
    compares them as well, and keeps dict order.
    """
    if dataclasses.is_dataclass(value) and not isinstance(value, type):
        return (type(value).__name__, tuple((f.name, everything(getattr(value, f.name)))
                                            for f in dataclasses.fields(value)
                                            if not (isinstance(value, WhereRule) and f.name == "expr")))
    if isinstance(value, dict):
        return ("dict", tuple((k, everything(v)) for k, v in value.items()))
    if isinstance(value, (list, tuple)):
        return (type(value).__name__, tuple(everything(v) for v in value))
    if isinstance(value, enum.Enum):
        return ("enum", type(value).__name__, value.value)
    if isinstance(value, Path):
        return ("path", str(value))
    return value


def _plans_view(plans: Plans) -> Any:
    return everything({"entities": plans.entities, "encodings": plans._enc, "by_class": plans.by_class,
                       "item_names": plans.item_names, "typed_names": plans.typed_names})


@pytest.fixture(scope="module")
def fresh() -> tuple[Catalog, SchemaModel, Plans]:
    catalog, model = load_catalog_model(ONTOLOGY / "express")
    return catalog, model, Plans(model, catalog.naming)


@pytest.fixture(scope="module")
def compiled() -> cache.Compiled:
    return cache.read(ONTOLOGY)


def test_shipped_file_matches_the_express(compiled: cache.Compiled) -> None:
    # cache.read raises StaleCache on a digest mismatch; this is the run-time check
    assert compiled.plans is not None
    data = json.loads((ONTOLOGY / cache.CACHE_FILE).read_text(encoding="utf-8"))
    assert data["express_sha256"] == cache.express_digest(ONTOLOGY / "express")


def test_compiled_model_equals_a_fresh_build(fresh: tuple[Catalog, SchemaModel, Plans],
                                             compiled: cache.Compiled) -> None:
    catalog, model, _ = fresh
    assert compiled.catalog == catalog
    assert list(compiled.model.declarations) == list(model.declarations)  # declaration order too
    assert everything(compiled.model.declarations) == everything(model.declarations)
    assert everything(compiled.model.schemas) == everything(model.schemas)
    assert compiled.model.entities.keys() == model.entities.keys() and len(model.entities) > 400


def test_compiled_model_answers_like_a_fresh_one(fresh: tuple[Catalog, SchemaModel, Plans],
                                                 compiled: cache.Compiled) -> None:
    _, model, _ = fresh
    cached = compiled.model
    for name in model.entities:
        assert everything(cached.part21_attributes(name)) == everything(model.part21_attributes(name)), name
        assert cached.all_attributes(name) == model.all_attributes(name)
        assert cached.ancestors(name) == model.ancestors(name)
        assert cached.all_subtypes(name) == model.all_subtypes(name)
    assert cached.scopes == model.scopes
    assert [s.name for s in cached.part21_attributes("facing_rough")][:2] == ["its_toolpath", "its_tool_direction"]


def test_compiled_plans_equal_fresh_plans(fresh: tuple[Catalog, SchemaModel, Plans],
                                          compiled: cache.Compiled) -> None:
    catalog, model, plans = fresh
    restored = Plans.restore(compiled.model, compiled.catalog.naming, compiled.plans)
    assert _plans_view(restored) == _plans_view(plans)
    assert restored.entities["TURNING_WORKINGSTEP"] == plans.entities["TURNING_WORKINGSTEP"]


def test_where_rules_keep_text_and_position_but_not_the_tree(fresh: tuple[Catalog, SchemaModel, Plans],
                                                             compiled: cache.Compiled) -> None:
    _, model, _ = fresh
    name, decl = next((n, d) for n, d in model.declarations.items() if d.where_rules)
    fresh_rule, cached_rule = decl.where_rules[0], compiled.model.declarations[name].where_rules[0]
    assert fresh_rule.expr is not None and cached_rule.expr is None
    assert (cached_rule.label, cached_rule.source, cached_rule.pos) == (fresh_rule.label, fresh_rule.source,
                                                                       fresh_rule.pos)


# -- staleness ----------------------------------------------------------------------


@pytest.fixture
def data_copy(tmp_path: Path) -> Path:
    """A copy of ontology/ (EXPRESS and compiled model) to edit."""
    target = tmp_path / "ontology"
    shutil.copytree(ONTOLOGY / "express", target / "express")
    shutil.copy(ONTOLOGY / cache.CACHE_FILE, target / cache.CACHE_FILE)
    return target


NEW_ENTITY = "\nSCHEMA extra_schema;\nENTITY extra_thing;\n  its_id : STRING;\nEND_ENTITY;\nEND_SCHEMA;\n"


def _add_entity(ontology: Path) -> None:
    with open(ontology / "express" / "turning_schema.exp", "a", encoding="utf-8") as fh:
        fh.write(NEW_ENTITY)


def test_a_copy_reads_like_the_original(data_copy: Path) -> None:
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        copy = cache.load_or_build(data_copy)
    assert copy.plans is not None and "extra_thing" not in copy.model


def test_changed_express_is_never_read_from_the_stale_file(data_copy: Path) -> None:
    _add_entity(data_copy)
    with pytest.raises(cache.StaleCache, match="changed since it was built"):
        cache.read(data_copy)
    with pytest.warns(cache.CompiledModelWarning, match="ontology build"):
        rebuilt = cache.load_or_build(data_copy)
    assert rebuilt.plans is None and "extra_thing" in rebuilt.model


@pytest.mark.parametrize("content", ["", "{not json", '{"format": 999}', '{"format": 1, "express_sha256": "x"}'])
def test_unusable_file_warns_and_builds_from_the_express(data_copy: Path, content: str) -> None:
    (data_copy / cache.CACHE_FILE).write_text(content, encoding="utf-8")
    with pytest.warns(cache.CompiledModelWarning):
        rebuilt = cache.load_or_build(data_copy)
    assert rebuilt.plans is None and "turning_workingstep" in rebuilt.model


def test_missing_file_warns(data_copy: Path) -> None:
    (data_copy / cache.CACHE_FILE).unlink()
    with pytest.warns(cache.CompiledModelWarning, match="cannot be read"):
        assert "turning_workingstep" in cache.load_or_build(data_copy).model


def test_right_digest_but_damaged_records_is_stale(data_copy: Path) -> None:
    path = data_copy / cache.CACHE_FILE
    lines = path.read_text(encoding="utf-8").split("\n")
    damaged = [line for line in lines if not line.startswith('{"kind":"entity","name":"turning_workingstep"')]
    assert len(damaged) == len(lines) - 1
    path.write_text("\n".join(damaged), encoding="utf-8")
    json.loads(path.read_text(encoding="utf-8"))  # still well-formed: only the records digest tells
    with pytest.raises(cache.StaleCache, match="records were changed"):
        cache.read(data_copy)


def test_build_check_reports_the_compiled_model_stale(tmp_path: Path, data_copy: Path, generate_once: None) -> None:
    root = data_copy.parent
    build(root)
    assert build(root, check=True).stale == ()
    _add_entity(data_copy)
    assert f"ontology/{cache.CACHE_FILE}" in build(root, check=True).stale


def test_digest_follows_content_not_line_ends(tmp_path: Path) -> None:
    d = tmp_path / "express"
    d.mkdir()
    (d / "a.exp").write_bytes(b"SCHEMA a;\nEND_SCHEMA;\n")
    lf = cache.express_digest(d)
    (d / "a.exp").write_bytes(b"SCHEMA a;\r\nEND_SCHEMA;\r\n")
    assert cache.express_digest(d) == lf
    (d / "a.exp").write_bytes(b"SCHEMA b;\nEND_SCHEMA;\n")
    assert cache.express_digest(d) != lf
    (d / "b.exp").write_bytes(b"")
    (d / "a.exp").write_bytes(b"SCHEMA a;\nEND_SCHEMA;\n")
    assert cache.express_digest(d) != lf  # a new file counts
