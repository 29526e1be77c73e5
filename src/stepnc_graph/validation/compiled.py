"""The shipped shapes' checks, compiled once by ``stepnc-graph ontology build``.

Compiling the shapes (parsing about 0.9 MB of Turtle into a
:class:`~.shapes.ShapesGraph`, then every constraint into a SPARQL query) took
about 0.23 s -- most of ``validate``'s time on a small program. The shipped
shapes change only when the project is rebuilt, so the build writes their
checks to ``shapes/compiled-checks.json`` (plain JSON: safe to read, no pickle),
with a SHA-256 over the shape files' names and contents (line ends normalised, as for the EXPRESS). At run time the file is
used only when that digest matches the files being validated with; otherwise
the shapes are compiled in the process (with a :class:`CompiledShapesWarning`
when the shipped files themselves changed since the build, never silently).

The shapes graph itself (messages, labels, ISO clauses) is read only when a
result needs describing: a conforming program never parses it
(:class:`CompiledShapes`, what :func:`compile_shapes` returns for a set of shape
files, cached per process while they are unchanged).
"""

from __future__ import annotations

import json
import warnings
from collections.abc import Iterable, Sequence
from functools import lru_cache
from pathlib import Path
from typing import Any

from stepnc_graph.core.errors import StepncGraphWarning
from stepnc_graph.core.resources import sources_digest
from stepnc_graph.validation.engine import Check, Compiler
from stepnc_graph.validation.reads import properties_read, reads_positions
from stepnc_graph.validation.shapes import ShapesError, ShapesGraph

FORMAT = 6  # 2: each check names the files that describe its results; 3: its argument and what implies it;
# 4: "excludes" null for a check that always runs (was a flag "multi_typed_only" beside it);
# 5: queries with placeholders for the data's hierarchy, the support files' hierarchy beside the checks,
# each check's target classes and component arguments; 6: what the checks read (:mod:`.reads`)
CACHE_FILE = "compiled-checks.json"
#: the shipped file whose triples are part of the data graph (class hierarchy, enumeration items' types)
SUPPORT_FILE = "support.ttl"

Hierarchy = tuple[dict[str, set[str]], dict[str, set[str]]]
#: what the checks may read (:mod:`.reads`): the properties (None: any), and whether the position triples
Reads = tuple[frozenset[str] | None, bool]


class CompiledShapesWarning(StepncGraphWarning):
    """``shapes/compiled-checks.json`` is stale or unreadable: the shapes were compiled instead."""


class StaleChecks(Exception):
    """A compiled-checks file that does not fit the shape files (digest, format) or does not decode."""


def digest(named_texts: Sequence[tuple[str, bytes]]) -> str:
    """The shape files' digest, as the compiled model's of the EXPRESS (names, bytes, in order)."""
    return sources_digest(named_texts)


def compile_texts(named_texts: Sequence[tuple[str, str]],
                  data_positions: frozenset[int] = frozenset()) -> tuple[ShapesGraph, list[Check]]:
    """The shapes graph of Turtle documents, in order, and its checks; the documents at
    ``data_positions`` belong to the data graph (``support.ttl``)."""
    from stepnc_graph.mapping.plans import iso14649_plans
    from stepnc_graph.validation.implied import mark

    graph = ShapesGraph()
    for position, (name, text) in enumerate(named_texts):
        graph.add_text(text, name, position, data=position in data_positions)
    return graph, mark(Compiler(graph).checks(), graph, iso14649_plans())


def hierarchy_of(graph: ShapesGraph) -> Hierarchy:
    """The data files' subclasses and typed individuals (IRIs), class -> nodes."""
    return ({k: set(v) for k, v in graph.subclasses.items()},
            {k: {i for i in v if i.startswith("<")} for k, v in graph.instances.items() if v})


class _ClassSets:
    """Class sets (a target's subclasses) numbered in order of first use: a few hundred distinct
    sets are shared by thousands of checks, so the file lists each once and the reader builds
    each frozenset once."""

    def __init__(self) -> None:
        self.index: dict[frozenset[str], int] = {}

    def ref(self, classes: frozenset[str]) -> int:
        return self.index.setdefault(classes, len(self.index))

    def table(self) -> list[list[str]]:
        return [sorted(c) for c in self.index]


def _encode(check: Check, sets: _ClassSets) -> dict[str, Any]:
    return {
        "shape": check.shape, "constraint": check.constraint, "component": check.component, "path": check.path,
        "path_term": check.path_term, "severity": check.severity, "query": check.query,
        "classes": sets.ref(check.classes), "closures": [sets.ref(c) for c in check.closures],
        "other_targets": list(check.other_targets), "parent": check.parent, "sparql_node": check.sparql_node,
        "files": list(check.files), "argument": check.argument, "implied": check.implied,
        "excludes": None if check.excludes is None else sets.ref(check.excludes),
        "target_classes": list(check.target_classes), "args": [list(a) for a in check.args],
        "multiplicity": check.multiplicity,
    }


def _decode(d: dict[str, Any], sets: list[frozenset[str]]) -> Check:
    return Check(d["shape"], d["constraint"], d["component"], d["path"], d["path_term"], d["severity"], d["query"],
                 sets[d["classes"]], tuple(sets[i] for i in d["closures"]), tuple(d["other_targets"]),
                 d["parent"], d["sparql_node"], tuple(d["files"]), d["argument"], d["implied"],
                 None if d["excludes"] is None else sets[d["excludes"]], tuple(d["target_classes"]),
                 tuple((a[0], a[1]) for a in d["args"]), d["multiplicity"])


def dumps(names: Sequence[str], value: str, checks: Sequence[Check], hierarchy: Hierarchy) -> str:
    """The compiled-checks file: byte-stable (one check per line, keys sorted) for ``build --check``.
    What the checks read is worked out here, once, for ``validate FILE`` (:mod:`.reads`)."""
    sets = _ClassSets()
    lines = [json.dumps(_encode(c, sets), sort_keys=True, ensure_ascii=False) for c in checks]
    head = json.dumps({"format": FORMAT, "files": list(names), "shapes_sha256": value}, sort_keys=True)
    table = ",\n".join(json.dumps(c, ensure_ascii=False) for c in sets.table())
    subclasses, individuals = hierarchy
    tree = json.dumps({k: sorted(v) for k, v in sorted(subclasses.items())}, ensure_ascii=False)
    typed = json.dumps({k: sorted(v) for k, v in sorted(individuals.items())}, ensure_ascii=False)
    read = properties_read(checks)
    reads = json.dumps({"positions": reads_positions(checks), "properties": None if read is None else sorted(read)},
                       sort_keys=True, ensure_ascii=False)
    return ("{\"header\": " + head + ",\n\"reads\": " + reads + ",\n\"subclasses\": " + tree
            + ",\n\"individuals\": " + typed
            + ",\n\"class_sets\": [\n" + table + "\n],\n\"checks\": [\n" + ",\n".join(lines) + "\n]}\n")


def loads(text: str, value: str) -> tuple[tuple[Check, ...], Hierarchy, Reads]:
    """The checks of a compiled-checks file written for shape files of digest ``value``, the
    support files' hierarchy and what the checks read."""
    try:
        data = json.loads(text)
        header = data["header"]
        if header.get("format") != FORMAT:
            raise StaleChecks(f"it has format {header.get('format')!r}, this stepnc-graph reads format {FORMAT}")
        if header.get("shapes_sha256") != value:
            raise StaleChecks("the shape files changed since it was built")
        sets = [frozenset(c) for c in data["class_sets"]]
        hierarchy = ({k: set(v) for k, v in data["subclasses"].items()},
                     {k: set(v) for k, v in data["individuals"].items()})
        read = data["reads"]["properties"]
        reads = (None if read is None else frozenset(read), bool(data["reads"]["positions"]))
        return tuple(_decode(d, sets) for d in data["checks"]), hierarchy, reads
    except (ValueError, KeyError, TypeError, AttributeError, IndexError) as exc:
        raise StaleChecks(f"it does not decode ({type(exc).__name__}: {exc})") from exc


def relative_names(files: Sequence[Path], directory: Path) -> list[str] | None:
    """The files' names relative to ``directory`` (``process/turning.ttl``); None if one is outside it."""
    names = []
    for f in files:
        try:
            names.append(f.resolve().relative_to(directory.resolve()).as_posix())
        except ValueError:
            return None
    return names


def shape_files(shapes_dir: Path | None = None, process: bool = True) -> list[Path]:
    """The shipped shapes: generated files, then the process rules."""
    if shapes_dir is None:
        from stepnc_graph.core.resources import shapes_dir as default

        shapes_dir = default()
    files = sorted(shapes_dir.glob("*.ttl"))
    if process:
        files += sorted((shapes_dir / "process").glob("*.ttl"))
    return files


#: what :meth:`CompiledShapes.properties_read` holds before it is worked out
_UNKNOWN = object()


class CompiledShapes:
    """The checks of a set of shape files, and their shapes graph, read on first use and only as far
    as needed: describing a result reads the files its check names (:attr:`Check.files`); finding
    none reads no file at all. ``hierarchy``: the data files' subclasses and typed individuals
    (class -> nodes), which the checks' class tests expand to. ``reads``: what the checks read,
    when the build worked it out (else worked out on first use: :meth:`reads`)."""

    def __init__(self, files: Sequence[Path], checks: tuple[Check, ...], graph: ShapesGraph | None = None,
                 hierarchy: tuple[dict[str, set[str]], dict[str, set[str]]] | None = None,
                 data_positions: frozenset[int] = frozenset(), reads: Reads | None = None) -> None:
        self.files = tuple(files)
        self.checks = checks
        self._properties: frozenset[str] | None | object = _UNKNOWN if reads is None else reads[0]
        self._positions: bool | None = None if reads is None else reads[1]
        self._graph = graph  # every file, when the shapes were compiled here
        self._partial = ShapesGraph()
        self._read: set[int] = set()
        self.data_positions = data_positions
        if hierarchy is None and graph is not None:
            hierarchy = ({k: set(v) for k, v in graph.subclasses.items()},
                         {k: {i for i in v if i.startswith("<")} for k, v in graph.instances.items()})
        self.hierarchy = hierarchy or ({}, {})

    def reads(self) -> Reads:
        """The properties the checks may read (None: any) and whether they read the position
        triples (:mod:`.reads`): from the build for the shipped checks, else worked out once."""
        return self.properties_read(), self.reads_positions()

    def properties_read(self) -> frozenset[str] | None:
        """The properties the checks may read (None: any): from the build, else worked out once
        (some 40 ms of pattern matching over the shipped checks)."""
        if not self.reads_known:
            self._properties = properties_read(self.checks)
        return self._properties  # type: ignore[return-value]

    def reads_positions(self) -> bool:
        """Whether the checks may read the position triples: from the build, else worked out once."""
        if self._positions is None:
            self._positions = reads_positions(self.checks)
        return self._positions

    @property
    def reads_known(self) -> bool:
        """Whether :meth:`properties_read` costs nothing: the build worked it out, or this process did."""
        return self._properties is not _UNKNOWN

    @property
    def graph(self) -> ShapesGraph:
        """The graph of every file."""
        return self.describing(range(len(self.files)))

    def describing(self, positions: Iterable[int]) -> ShapesGraph:
        """A graph holding (at least) the files at ``positions``: blank nodes are named by file
        position, so it names them as the compiled checks do."""
        if self._graph is not None:
            return self._graph
        for position in sorted(set(positions) - self._read):
            self._partial.add_file(self.files[position], position, data=position in self.data_positions)
            self._read.add(position)
        if len(self._read) == len(self.files):
            self._graph = self._partial
        return self._partial


@lru_cache(maxsize=8)
def _compiled(files: tuple[tuple[str, float], ...], directory: str) -> CompiledShapes:
    paths = [Path(name) for name, _mtime in files]
    try:
        texts = [p.read_bytes() for p in paths]
    except OSError as exc:
        raise ShapesError(f"{exc.filename}: {exc.strerror or exc}") from None
    names = relative_names(paths, Path(directory))
    data = frozenset(i for i, p in enumerate(paths) if _is_support(p, Path(directory)))
    if names is not None:
        shipped = Path(directory) / CACHE_FILE
        try:
            text = shipped.read_text(encoding="utf-8")
            checks, hierarchy, reads = loads(text, digest(list(zip(names, texts, strict=True))))
            return CompiledShapes(paths, checks, hierarchy=hierarchy, data_positions=data, reads=reads)
        except (OSError, StaleChecks) as exc:
            if paths == shape_files(Path(directory)):  # the shipped set itself: say why it is not used
                reason = exc.strerror if isinstance(exc, OSError) else str(exc)
                warnings.warn(f"{shipped} is not used: {reason}. Compiling the shapes instead (about 0.2 s); "
                              f"`stepnc-graph ontology build` refreshes the file.", CompiledShapesWarning,
                              stacklevel=2)
    try:
        decoded = [(str(p), t.decode("utf-8")) for p, t in zip(paths, texts, strict=True)]
    except UnicodeDecodeError as exc:
        raise ShapesError(f"shapes are not UTF-8: {exc}") from None
    graph, compiled_checks = compile_texts(decoded, data)
    return CompiledShapes(paths, tuple(compiled_checks), graph, data_positions=data)


def _is_support(path: Path, directory: Path) -> bool:
    """Whether ``path`` is the shipped ``support.ttl``: part of the data graph, not of the shapes."""
    try:
        return path.resolve() == (directory / SUPPORT_FILE).resolve()
    except OSError:
        return False


def compile_shapes(files: Sequence[Path], directory: Path | None = None) -> CompiledShapes:
    """The checks of shapes files: the shipped compiled ones when ``files`` are the files they were
    compiled from (in ``directory``, default the shipped shapes), else compiled here; cached per
    process while the files are unchanged."""
    for f in files:
        if not f.is_file():
            raise ShapesError(f"{f}: no such shapes file")
    if directory is None:
        from stepnc_graph.core.resources import shapes_dir

        directory = shapes_dir()
    return _compiled(tuple((str(f), f.stat().st_mtime) for f in files), str(directory))
