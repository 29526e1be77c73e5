"""The architecture's figures, measured on the source: sizes, import cycles, imports that point up
the layers, back-end type tests. ``tests/test_architecture.py`` holds the code to them.

    python tools/architecture.py            # the figures, one per line
    python tools/architecture.py --details  # ... and what each figure counts

Every import counts, wherever it is written (at the top of a module, inside a function, or only
for the type checker under ``if TYPE_CHECKING:``... those last ones excepted: they never run).
A module's layer is the first entry of :data:`LAYERS` whose prefix names it; a module may import
its own layer and the layers below it, never one above. docs/architecture.md draws the layers.
"""

from __future__ import annotations

import argparse
import ast
import statistics
import sys
from collections.abc import Iterator
from dataclasses import dataclass, field
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
PACKAGE = ROOT / "src" / "stepnc_graph"

#: The layers, lowest first: (name, module prefixes). A prefix names a module and its submodules.
LAYERS: tuple[tuple[str, tuple[str, ...]], ...] = (
    ("core", ("stepnc_graph.core",)),
    ("readers", ("stepnc_graph.express", "stepnc_graph.part21")),
    ("schema", ("stepnc_graph.schema",)),
    ("vocabulary", ("stepnc_graph.vocabulary",)),
    ("mapping", ("stepnc_graph.mapping",)),
    ("generators", ("stepnc_graph.generators",)),
    ("store", ("stepnc_graph.store",)),
    ("graphs", ("stepnc_graph.graphs",)),
    ("loading", ("stepnc_graph.loading",)),
    ("exporting", ("stepnc_graph.exporting",)),
    ("querying", ("stepnc_graph.querying",)),
    ("validation", ("stepnc_graph.validation",)),
    ("workplan", ("stepnc_graph.workplan",)),
    ("server", ("stepnc_graph.server",)),
    ("artefacts", ("stepnc_graph.artefacts",)),
    ("api", ("stepnc_graph.api", "stepnc_graph")),
    ("cli", ("stepnc_graph.cli",)),
    ("testing", ("stepnc_graph.testing",)),
)

#: Modules the size limits do not apply to: generated, or a patched copy of a library's parser.
EXEMPT = frozenset({"stepnc_graph.vocab", "stepnc_graph.vocabulary.terms", "stepnc_graph.express._patched_parser"})
MODULE_LINES, CLASS_LINES, FUNCTION_LINES = 500, 400, 50

#: The store classes: naming one in ``isinstance`` outside the store is a back-end type test.
STORE_CLASSES = frozenset({"GraphStore", "DiskStore", "MemoryStore", "RemoteStore", "EmbeddedStore"})
#: What callers once asked a store with hasattr/getattr instead of its contract.
STORE_MEMBERS = frozenset({"local_copy", "deleted_quads", "endpoint", "oxigraph", "path", "disk_bytes", "compact",
                           "add_quads", "quads_for_pattern", "all_graphs"})


@dataclass
class Module:
    name: str
    path: Path
    tree: ast.Module
    lines: int
    #: (imported module, line, at module level)
    imports: list[tuple[str, int, bool]] = field(default_factory=list)


def module_name(path: Path) -> str:
    parts = list(path.relative_to(PACKAGE.parent).with_suffix("").parts)
    if parts[-1] == "__init__":
        parts.pop()
    return ".".join(parts)


def read_modules(package: Path = PACKAGE) -> dict[str, Module]:
    modules = {}
    for path in sorted(package.rglob("*.py")):
        text = path.read_text(encoding="utf-8")
        name = module_name(path)
        modules[name] = Module(name, path, ast.parse(text), len(text.splitlines()))
    for module in modules.values():
        module.imports = sorted(set(_imports(module, modules)), key=lambda i: (i[1], i[0]))
    return modules


def _type_checking_nodes(tree: ast.Module) -> set[int]:
    found: set[int] = set()
    for node in ast.walk(tree):
        if isinstance(node, ast.If) and "TYPE_CHECKING" in ast.unparse(node.test):
            found.update(id(n) for stmt in node.body for n in ast.walk(stmt))
    return found


def _imports(module: Module, modules: dict[str, Module]) -> Iterator[tuple[str, int, bool]]:
    skipped = _type_checking_nodes(module.tree)
    top = {id(n) for n in module.tree.body}
    package = module.name if module.path.name == "__init__.py" else module.name.rpartition(".")[0]
    for node in ast.walk(module.tree):
        if id(node) in skipped:
            continue
        names: list[str] = []
        if isinstance(node, ast.Import):
            names = [a.name for a in node.names]
        elif isinstance(node, ast.ImportFrom):
            base = node.module or ""
            if node.level:
                parts = package.split(".")[: len(package.split(".")) - node.level + 1]
                base = ".".join([*parts, base] if base else parts)
            names = [f"{base}.{a.name}" if f"{base}.{a.name}" in modules else base for a in node.names]
        for name in names:
            while name and name not in modules:
                name = name.rpartition(".")[0]
            if name and name != module.name:
                yield name, node.lineno, id(node) in top


def layer_of(name: str) -> int:
    for k, (_, prefixes) in enumerate(LAYERS):
        if any(name == p or name.startswith(p + ".") for p in prefixes if p != "stepnc_graph"):
            return k
    for k, (_, prefixes) in enumerate(LAYERS):
        if name in prefixes:
            return k
    raise KeyError(f"{name} is in no layer of tools/architecture.py")


def cycles(modules: dict[str, Module]) -> list[list[str]]:
    """The import cycles: strongly connected sets of more than one module (Tarjan's algorithm)."""
    graph = {m: sorted({t for t, _, _ in mod.imports}) for m, mod in modules.items()}
    index: dict[str, int] = {}
    low: dict[str, int] = {}
    stack: list[str] = []
    on: set[str] = set()
    found: list[list[str]] = []

    def visit(v: str) -> None:
        index[v] = low[v] = len(index)
        stack.append(v)
        on.add(v)
        for w in graph[v]:
            if w not in index:
                visit(w)
                low[v] = min(low[v], low[w])
            elif w in on:
                low[v] = min(low[v], index[w])
        if low[v] == index[v]:
            component = []
            while True:
                w = stack.pop()
                on.discard(w)
                component.append(w)
                if w == v:
                    break
            if len(component) > 1:
                found.append(sorted(component))

    sys.setrecursionlimit(10_000)
    for v in graph:
        if v not in index:
            visit(v)
    return sorted(found)


def upward_imports(modules: dict[str, Module]) -> list[str]:
    return [f"{m} ({LAYERS[layer_of(m)][0]}) -> {t} ({LAYERS[layer_of(t)][0]}), line {line}"
            for m, mod in sorted(modules.items()) for t, line, _ in mod.imports if layer_of(t) > layer_of(m)]


def _spans(tree: ast.Module, kind: tuple[type, ...]) -> Iterator[tuple[str, int]]:
    for node in ast.walk(tree):
        if isinstance(node, kind):
            yield node.name, (node.end_lineno or node.lineno) - node.lineno + 1  # type: ignore[attr-defined]


def type_tests(modules: dict[str, Module]) -> list[str]:
    """``isinstance`` naming a store class outside the store, ``hasattr``/``getattr`` asking a
    store member: a caller testing which back end it has instead of asking the contract."""
    found = []
    for name, mod in sorted(modules.items()):
        if name.startswith("stepnc_graph.store"):
            continue
        for node in ast.walk(mod.tree):
            if not (isinstance(node, ast.Call) and isinstance(node.func, ast.Name) and len(node.args) >= 2):
                continue
            arg = node.args[1]
            if node.func.id == "isinstance" and {n.id for n in ast.walk(arg) if isinstance(n, ast.Name)} & STORE_CLASSES:
                found.append(f"{name}, line {node.lineno}: {ast.unparse(node)}")
            elif (node.func.id in ("hasattr", "getattr") and isinstance(arg, ast.Constant)
                  and arg.value in STORE_MEMBERS):
                found.append(f"{name}, line {node.lineno}: {ast.unparse(node)}")
    return found


@dataclass
class Figures:
    modules: int
    lines: int
    median_module_lines: float
    large_modules: list[str]
    large_classes: list[str]
    long_functions: float
    cycles: list[list[str]]
    upward: list[str]
    function_level_imports: list[str]
    type_tests: list[str]


def measure(package: Path = PACKAGE) -> Figures:
    modules = read_modules(package)
    sizes = [m.lines for m in modules.values()]
    large = [f"{m.name}: {m.lines} lines" for m in sorted(modules.values(), key=lambda m: -m.lines)
             if m.lines > MODULE_LINES and m.name not in EXEMPT]
    classes = [f"{m.name}.{c}: {n} lines" for m in modules.values() if m.name not in EXEMPT
               for c, n in _spans(m.tree, (ast.ClassDef,)) if n > CLASS_LINES]
    functions = [n for m in modules.values() if m.name not in EXEMPT
                 for _, n in _spans(m.tree, (ast.FunctionDef, ast.AsyncFunctionDef))]
    inner = [f"{m.name}, line {line}: {t}" for m in modules.values() for t, line, top in m.imports if not top]
    return Figures(len(modules), sum(sizes), statistics.median(sizes), large, sorted(classes),
                   100 * sum(n > FUNCTION_LINES for n in functions) / max(len(functions), 1),
                   cycles(modules), upward_imports(modules), sorted(inner), type_tests(modules))


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--details", action="store_true", help="list what each figure counts")
    details = parser.parse_args().details
    f = measure()
    print(f"modules: {f.modules}, {f.lines:,} lines, median {f.median_module_lines:g} lines a module")
    print(f"functions over {FUNCTION_LINES} lines: {f.long_functions:.1f} %")
    rows = [(f"modules over {MODULE_LINES} lines (generated and patched ones aside)", f.large_modules),
            (f"classes over {CLASS_LINES} lines", f.large_classes),
            ("import cycles (every import, function-level ones too)", [" <-> ".join(c) for c in f.cycles]),
            ("imports pointing up the layers", f.upward),
            ("function-level imports", f.function_level_imports),
            ("back-end type tests", f.type_tests)]
    for title, items in rows:
        print(f"{title}: {len(items)}")
        if details:
            for item in items:
                print(f"    {item}")


if __name__ == "__main__":
    main()
