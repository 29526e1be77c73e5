"""Regenerate (or check) every generated artefact from ``ontology/express/``.

Paths are relative to a project root: ``ontology/*.ttl``, ``shapes/*.ttl``,
``ontology/compiled-model.json`` (the resolved model and mapping plans that
commands read instead of the EXPRESS, see :mod:`stepnc_graph.schema.cache`),
``shapes/compiled-checks.json`` (the shapes as SPARQL checks, see
:mod:`stepnc_graph.validation.compiled`),
``docs/ontology.html``, ``src/stepnc_graph/vocab.py`` and ``ontology/editions/editions.json``
(what tells the editions apart, see :mod:`stepnc_graph.schema.editions`).
"""

from __future__ import annotations

from collections.abc import Iterator
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING

from stepnc_graph.generators.registry import GENERATORS, Inputs
from stepnc_graph.mapping.plans import Plans
from stepnc_graph.schema import cache, editions
from stepnc_graph.schema.catalog import EDITIONS, load_catalog_model
from stepnc_graph.schema.view import SchemaModel
from stepnc_graph.validation import compiled

if TYPE_CHECKING:
    from stepnc_graph.generators.edition_shapes import EditionNaming
    from stepnc_graph.schema.catalog import Catalog


@dataclass(frozen=True)
class BuildResult:
    written: tuple[str, ...]
    unchanged: tuple[str, ...]
    stale: tuple[str, ...]  # differ from a fresh build (check mode) or were rewritten


def generate(express_directory: Path | None = None) -> dict[str, str]:
    """All generated files, keyed by path relative to the project root."""
    catalog, model = load_catalog_model(express_directory)
    naming = catalog.naming
    plans = Plans(model, naming)
    queries = catalog.directory.parent.parent / "queries"  # the library's examples, where there is one
    editions_out, edition_classes = edition_files(catalog.directory, plans)
    inputs = Inputs(model, catalog, naming, plans, queries, tuple(edition_classes))
    out: dict[str, str] = {}
    generated: dict[str, dict[str, str]] = {}
    for entry in GENERATORS:
        generated[entry.name] = entry.make(inputs).outputs()
        for rel, text in generated[entry.name].items():
            out[f"{entry.directory}/{rel}"] = text
    digest = cache.express_digest(catalog.directory)
    out[f"ontology/{cache.CACHE_FILE}"] = cache.dumps(catalog, model, plans.dump(), digest)
    shapes = {**generated["shacl"], **{k.removeprefix("shapes/"): v for k, v in editions_out.items() if k.startswith("shapes/")}}
    out[f"shapes/{compiled.CACHE_FILE}"] = compiled_checks(shapes, catalog.directory.parent.parent / "shapes")
    out[f"ontology/{editions.TABLE_FILE}"] = edition_table(catalog.directory, model)
    out.update(editions_out)
    return out


@dataclass(frozen=True)
class EditionSource:
    """An edition found beside the shipped one, read for the build: its catalogue and model, the
    plans of its own model, the plans its loader reads with, and the naming its shapes use."""

    edition: str
    catalog: Catalog
    model: SchemaModel
    own: Plans
    plans: Plans
    naming: EditionNaming


def edition_sources(express_directory: Path, base: Plans) -> Iterator[EditionSource]:
    """Each other edition with a catalogue beside the shipped one (``ontology/editions/<edition>/``)."""
    from stepnc_graph.generators import edition_shapes
    from stepnc_graph.mapping.editions import build_edition_plans

    for edition in EDITIONS:
        directory = express_directory.parent / "editions" / edition
        if not (directory / "schemas.toml").is_file():
            continue
        catalog, model = load_catalog_model(directory)
        own = Plans(model, base.n)
        plans = build_edition_plans(edition, base, own)
        yield EditionSource(edition, catalog, model, own, plans, edition_shapes.edition_naming(base.n, own, plans))


def edition_files(express_directory: Path, base: Plans) -> tuple[dict[str, str], list[tuple[str, str]]]:
    """Per other edition found beside the shipped one: its compiled model and plans
    (``ontology/editions/<edition>.compiled-model.json``, read by
    :func:`stepnc_graph.mapping.editions.own_plans`) and its own terms as OWL
    (``ontology/edition_<edition>.ttl``, in the vocabulary graph), its WHERE rules that differ from
    2002 as shapes (``shapes/edition_<edition>.ttl``, :mod:`stepnc_graph.generators.edition_shapes`);
    and the (edition class, 2002 class) pairs the shapes' class hierarchy adds."""
    from stepnc_graph.generators import edition_shapes
    from stepnc_graph.mapping.editions import COMPILED, RENAMED, counterpart_classes, edition_turtle

    out: dict[str, str] = {}
    pairs: list[tuple[str, str]] = []
    for e in edition_sources(express_directory, base):
        directory = express_directory.parent / "editions" / e.edition
        out["ontology/" + COMPILED.format(edition=e.edition)] = cache.dumps(e.catalog, e.model, e.own.dump(),
                                                                           cache.express_digest(directory))
        out[f"ontology/edition_{e.edition}.ttl"] = edition_turtle(e.edition, e.plans, base)
        out["shapes/" + edition_shapes.FILE.format(edition=e.edition)] = edition_shapes.edition_shapes(
            e.edition, e.catalog, e.model, base.model, e.naming, RENAMED.get(e.edition, {}))
        pairs += counterpart_classes(e.edition, e.plans, base)
    return out, pairs


def edition_table(express_directory: Path, model: SchemaModel) -> str:
    """``ontology/editions/editions.json``: the shipped model against each edition found beside it."""
    models, sources = {editions.SHIPPED: model}, {editions.SHIPPED: "ontology/express/schemas.toml"}
    for edition in EDITIONS:
        directory = express_directory.parent / "editions" / edition
        if (directory / "schemas.toml").is_file():
            models[edition] = load_catalog_model(directory)[1]
            sources[edition] = f"ontology/editions/{edition}/schemas.toml"
    return editions.dumps(editions.table(models, sources))


def compiled_checks(generated: dict[str, str], shapes_directory: Path) -> str:
    """``shapes/compiled-checks.json``: the checks of the generated shapes and the hand-written
    process rules (``shapes/process/*.ttl``), in the order ``validate`` reads them."""
    texts = sorted(generated.items())
    texts += [(f"process/{p.name}", p.read_text(encoding="utf-8"))
              for p in sorted((shapes_directory / "process").glob("*.ttl"))]
    data = frozenset(i for i, (name, _) in enumerate(texts) if name == compiled.SUPPORT_FILE)
    graph, checks = compiled.compile_texts(texts, data)
    value = compiled.digest([(name, text.encode("utf-8")) for name, text in texts])
    return compiled.dumps([name for name, _ in texts], value, checks, compiled.hierarchy_of(graph))


def build(root: Path, check: bool = False) -> BuildResult:
    """Write the generated files under ``root``; with ``check`` only compare."""
    files = generate(root / "ontology" / "express")
    written, unchanged, stale = [], [], []
    for rel, text in sorted(files.items()):
        if not rel.startswith(("ontology/", "shapes/")) and not (root / rel.split("/")[0]).is_dir():
            continue  # an installed data directory has no src/ or docs/ to refresh
        path = root / rel
        current = path.read_text(encoding="utf-8") if path.exists() else None
        if current == text:
            unchanged.append(rel)
            continue
        stale.append(rel)
        if not check:
            path.parent.mkdir(parents=True, exist_ok=True)
            path.write_text(text, encoding="utf-8")
            written.append(rel)
    return BuildResult(tuple(written), tuple(unchanged), tuple(stale))
