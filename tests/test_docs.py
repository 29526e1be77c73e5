"""Every code block of README.md and docs/*.md runs as printed and says what it does.

Each block has an entry in :data:`CHECKS` (found by file, position and first line, so that a new,
moved or changed block fails here until it has one): shell blocks run line by line in a copy of
``examples/`` with a store of their own, with the exit codes their comments give and the output
the entry expects; Python blocks run and their results are checked; SPARQL blocks run on the
shipped example (with its PLM links) and give the rows the text around them says; Turtle, CSV and
JSON blocks are compared with what the tool writes; the layout block names files that exist.
"""

from __future__ import annotations

import json
import os
import re
import shlex
import shutil
import subprocess
import sys
import textwrap
from collections.abc import Callable, Iterator
from contextlib import contextmanager
from dataclasses import dataclass, field
from pathlib import Path

import pytest

import stepnc_graph as sg
from stepnc_graph.core.naming import DATA_BASE
from stepnc_graph.store import GraphStore

from conftest import ROOT

CLI = [sys.executable, "-m", "stepnc_graph.cli"]
SHAFT = DATA_BASE + "shaft_two_setups.stp"
DOCUMENTS = ["README.md", *sorted(str(p.relative_to(ROOT)) for p in (ROOT / "docs").glob("*.md"))]
_FENCE = re.compile(r"^( *)```(\w*)\n(.*?)^\1```", re.S | re.M)


@dataclass(frozen=True)
class Block:
    file: str
    index: int  # 0-based among the file's blocks
    line: int
    lang: str
    text: str

    @property
    def first(self) -> str:
        return self.text.strip().splitlines()[0] if self.text.strip() else ""


def blocks() -> list[Block]:
    out = []
    for name in DOCUMENTS:
        text = (ROOT / name).read_text(encoding="utf-8")
        for k, m in enumerate(_FENCE.finditer(text)):
            out.append(Block(name, k, text.count("\n", 0, m.start()) + 1, m.group(2), textwrap.dedent(m.group(3))))
    return out


# -- running shell blocks ---------------------------------------------------------------------------


@dataclass
class Shell:
    """A directory with a copy of examples/, a store of its own, and the programs a block names."""

    cwd: Path
    env: dict[str, str]
    ports: dict[str, str] = field(default_factory=dict)
    background: list[subprocess.Popen[bytes]] = field(default_factory=list)

    def argv(self, command: str) -> list[str] | None:
        for printed, free in self.ports.items():
            command = command.replace(printed, free)
        argv = shlex.split(command)
        if argv[0] == "stepnc-graph":
            return [*CLI, *argv[1:]]
        if argv[0] == "oxigraph":
            from oxigraph_server import ServerUnavailable, oxigraph_server_binary

            try:
                return [oxigraph_server_binary(), *argv[1:]]
            except ServerUnavailable as exc:
                pytest.skip(str(exc))
        if argv[0] == "curl":
            return [shutil.which("curl") or pytest.skip("no curl here"), *argv[1:]]
        raise AssertionError(f"a documented command this test cannot run: {command}")

    def run(self, line: str) -> tuple[int, str]:
        """Run one documented line; the exit code and stdout + stderr."""
        command = line.partition(" #")[0].strip()
        if command.startswith("export "):
            name, _, value = command.removeprefix("export ").partition("=")
            for printed, free in self.ports.items():
                value = value.replace(printed, free)
            self.env[name] = value
            return 0, ""
        if command.endswith("&"):
            from oxigraph_server import wait_until_answers

            argv = self.argv(command[:-1])
            assert argv is not None
            process = subprocess.Popen(argv, cwd=self.cwd, env=self.env, stdout=subprocess.DEVNULL,
                                       stderr=subprocess.DEVNULL)
            self.background.append(process)
            port = next(p for p in self.ports.values() if p in " ".join(argv))
            wait_until_answers(f"http://127.0.0.1:{port}", process)
            return 0, ""
        argv = self.argv(command)
        assert argv is not None
        done = subprocess.run(argv, cwd=self.cwd, env=self.env, capture_output=True, text=True, timeout=300)
        return done.returncode, done.stdout + done.stderr


@contextmanager
def shell(tmp_path: Path, ports: tuple[str, ...] = ()) -> Iterator[Shell]:
    from oxigraph_server import free_port

    shutil.copytree(ROOT / "examples", tmp_path / "examples")
    env = {**os.environ, "STEPNC_GRAPH_STORE": str(tmp_path / "store"), "COLUMNS": "200"}
    env.pop("STEPNC_GRAPH_ENDPOINT", None)
    sh = Shell(tmp_path, env, {p: str(free_port()) for p in ports})
    try:
        yield sh
    finally:
        for process in sh.background:
            process.terminate()
            process.wait(timeout=30)


def lines_of(block: Block) -> list[str]:
    """The block's commands: continuation lines joined, comments-only and blank lines left out."""
    joined = block.text.replace("\\\n", " ")
    return [line for line in joined.splitlines() if line.strip() and not line.lstrip().startswith("#")]


def run_shell(block: Block, tmp_path: Path, expect: dict[str, list[str]], setup: tuple[str, ...] = (),
              replace: dict[str, str] | None = None, ports: tuple[str, ...] = (), skip: tuple[str, ...] = (),
              files: Callable[[], dict[str, str]] | None = None) -> None:
    """Run every line of ``block``: the exit code its comment gives (``exit N``, else 0), and for
    each line starting with a key of ``expect`` every text of its value in the output. ``setup``
    lines run first, ``files`` (name -> text) are written first, ``replace`` fills placeholders."""
    with shell(tmp_path, ports) as sh:
        for name, text in (files() if files else {}).items():
            (tmp_path / name).write_text(text, encoding="utf-8")
        for line in setup:
            code, output = sh.run(line)
            assert code in (0, 1), (line, output[-800:])
        seen = set()
        for line in lines_of(block):
            if line.startswith(skip):
                continue
            command = line
            for placeholder, value in (replace or {}).items():
                command = re.sub(rf"(?<![\w/.-]){re.escape(placeholder)}(?![\w/.-])", value, command)
            code, output = sh.run(command)
            m = re.search(r"exit (\d)", line.partition(" #")[2])
            assert code == (int(m.group(1)) if m else 0), (line, code, output[-1500:])
            assert "Traceback" not in output, (line, output[-1500:])
            for key, texts in expect.items():
                if line.startswith(key) if not key.endswith("$") else line.partition(" #")[0].strip() == key[:-1]:
                    seen.add(key)
                    for text in texts:
                        assert text in output, (line, text, output[-1500:])
        assert seen == set(expect), f"expected lines not in the block: {set(expect) - seen}"


# -- the store SPARQL and Python blocks run on ------------------------------------------------------


@pytest.fixture(scope="module")
def example() -> GraphStore:
    cwd = os.getcwd()
    os.chdir(ROOT)
    try:
        store = sg.open_store(memory=True)
        sg.load(store, ["examples/shaft_two_setups.stp"])
        sg.link(store, ROOT / "examples" / "shaft_plm_links.csv", SHAFT)
    finally:
        os.chdir(cwd)
    return store


def sparql_rows(store: GraphStore, block: Block) -> list[dict[str, object]]:
    result = sg.query(store, block.text)
    assert result.warnings == [], result.warnings
    return result.rows


@dataclass(frozen=True)
class Check:
    """How a block is checked: ``first`` starts its first line; ``run(block, tmp_path, store)``."""

    first: str
    run: Callable[[Block, Path, GraphStore], None]


def _sparql(rows: int, *values: str) -> Callable[[Block, Path, GraphStore], None]:
    def check(block: Block, tmp_path: Path, store: GraphStore) -> None:
        found = sparql_rows(store, block)
        assert len(found) == rows, found
        text = json.dumps(found)
        for value in values:
            assert value in text, (value, text[:1500])
    return check


def _shell(expect: dict[str, list[str]], **options: object) -> Callable[[Block, Path, GraphStore], None]:
    def check(block: Block, tmp_path: Path, store: GraphStore) -> None:
        run_shell(block, tmp_path, expect, **options)  # type: ignore[arg-type]
    return check


def _python(check_namespace: Callable[[dict[str, object]], None], before: str = "",
            optional: tuple[tuple[str, str], ...] = ()) -> Callable[[Block, Path, GraphStore], None]:
    """Run the block in a copy of examples/ (``before`` first) and check its names; a line holding
    the text of an ``optional`` (module, text) pair is left out when that module is not installed."""
    def check(block: Block, tmp_path: Path, store: GraphStore) -> None:
        import importlib.util

        text = "\n".join(line for line in block.text.splitlines()
                         if not any(t in line and importlib.util.find_spec(m) is None for m, t in optional))
        shutil.copytree(ROOT / "examples", tmp_path / "examples")
        cwd = os.getcwd()
        os.chdir(tmp_path)
        try:
            namespace: dict[str, object] = {}
            exec(compile(before + text, f"{block.file}:{block.line}", "exec"), namespace)  # noqa: S102
            check_namespace(namespace)
        finally:
            os.chdir(cwd)
    return check


def _not_run(reason: str) -> Callable[[Block, Path, GraphStore], None]:
    def check(block: Block, tmp_path: Path, store: GraphStore) -> None:
        assert reason
    return check


def _install_then(expect: list[str]) -> Callable[[Block, Path, GraphStore], None]:
    """``python3 -m venv ... && pip install . && stepnc-graph ...``: the stepnc-graph commands of the
    line (the test runs in the installed checkout; CI's .ci/run does the install itself)."""
    def check(block: Block, tmp_path: Path, store: GraphStore) -> None:
        commands = [c.strip() for c in block.first.split("&&") if c.strip().startswith("stepnc-graph")]
        assert commands
        with shell(tmp_path) as sh:
            output = ""
            for command in commands:
                code, out = sh.run(command)
                assert code == 0, (command, out)
                output += out
        for text in expect:
            assert text in output, (text, output)
    return check


def _layout(block: Block, tmp_path: Path, store: GraphStore) -> None:
    """Every path the layout names exists: top-level entries, and the packages under src/stepnc_graph/."""
    package = ROOT / "src" / "stepnc_graph"
    named = 0
    for line in block.text.splitlines():
        m = re.match(r"^( ?)( *)((?:[\w.*/-]+(?:, )?)+)(?:  |:| \(|$)", line)
        if m is None or line.startswith(" " * 10):
            continue  # a continued description
        base = package if m.group(2) else ROOT
        for name in m.group(3).split(", "):
            named += 1
            assert list(base.glob(name)) if "*" in name else (base / name).exists(), f"the layout names {name}"
    assert named > 30
    listed = {n.rstrip("/") for line in block.text.splitlines() if line.startswith("  ")
              for n in re.findall(r"(?:^  |, )([a-z0-9_]+/)", line)}
    real = {p.name for p in package.iterdir() if p.is_dir() and (p / "__init__.py").exists()}
    assert real <= listed, f"packages the layout does not name: {sorted(real - listed)}"


def _provenance(block: Block, tmp_path: Path, store: GraphStore) -> None:
    """Every term the Turtle sketch uses is in a loaded program's graph."""
    predicates = set(re.findall(r"\b(?:p21|prov|dcterms):\w+", block.text))
    text = sg.export(store, "ttl", SHAFT).decode("utf-8")
    missing = {p for p in predicates if p not in text}
    assert not missing, missing


def _mapping_csv(block: Block, tmp_path: Path, store: GraphStore) -> None:
    assert block.text == (ROOT / "examples" / "shaft_plm_links.csv").read_text(encoding="utf-8")


def _jsonld_node(block: Block, tmp_path: Path, store: GraphStore) -> None:
    """The node the sketch shows is in the export, with those values."""
    shown = json.loads(block.text)
    exported = json.loads(sg.export(store, "jsonld", SHAFT))
    assert exported["@id"] == shown["@id"] and exported["@context"]["@base"] == shown["@context"]["@base"]
    [node] = shown["@graph"]
    [real] = [n for n in exported["@graph"] if n.get("@id") == node["@id"]]
    assert {k: real.get(k) for k in node} == node


def _text_report(block: Block, tmp_path: Path, store: GraphStore) -> None:
    """The text report's line format is what validate prints (line, #id, entity, path: message [clause])."""
    shape = re.compile(r"^line \d+ +#\d+ +[A-Z_]+  [a-z_]+: .+  \[.+\]$")
    assert shape.match(block.text.strip()), block.text
    rules = tmp_path / "allowance.ttl"
    rules.write_text("""@prefix sh: <http://www.w3.org/ns/shacl#> .
@prefix stepnc: <https://w3id.org/stepnc-graph/iso14649#> .
<urn:x:s> a sh:NodeShape ; sh:targetClass stepnc:turning_technology ;
  sh:property [ sh:path stepnc:technology.feedrate ; sh:maxInclusive 0.2 ] .
""", encoding="utf-8")
    done = subprocess.run([*CLI, "validate", str(ROOT / "examples" / "shaft_two_setups.stp"), "--shapes", str(rules)],
                          capture_output=True, text=True, timeout=300)
    assert any(shape.match(line.strip()) for line in done.stdout.splitlines()), done.stdout


def _readme_python(ns: dict[str, object]) -> None:
    assert ns["rows"] and ns["turtle"] and ns["dataset"] is not None
    assert [r["workingstep"] for r in ns["rows"]] == ["WS5 RELIEF GROOVE", "WS6 FACE LEFT FINISH"]  # type: ignore[attr-defined, index]
    assert ns["STEPNC"]["machining_operation.its_tool"].endswith("#machining_operation.its_tool")  # type: ignore[index]


def _querying_python(ns: dict[str, object]) -> None:
    result, plan = ns["result"], ns["plan"]
    assert [r["setup"] for r in result.rows] == ["SETUP 1", "SETUP 1", "SETUP 2"]  # type: ignore[attr-defined]
    assert len(plan.tool_changes()) == 2 and plan.critical_tool()[0].label == "T01 CNMG 120408"  # type: ignore[attr-defined]
    assert plan.graph.number_of_nodes() > 8  # type: ignore[attr-defined]


_RULES = "our lathes"
_VALIDATION_SETUP = ("stepnc-graph load examples/shaft_two_setups.stp",
                     f"stepnc-graph export --format ttl --graph {SHAFT} -o data.ttl")


def _relaxed_rules() -> dict[str, str]:
    """The shop rules with a limit the example keeps (the block's lines have no exit-1 comment)."""
    text = (ROOT / "examples" / "shop_rules.ttl").read_text(encoding="utf-8")
    assert "sh:maxInclusive 0.2 ;" in text
    return {"our-rules.ttl": text.replace("sh:maxInclusive 0.2 ;", "sh:maxInclusive 0.3 ;")}
_TOUR = {
    "stepnc-graph load examples/shaft_two_setups.stp ": ["89 instances (0 kept raw), 781 triples, 0 diagnostics", "edition 2002 (chosen by header"],
    "stepnc-graph load examples/shaft_damaged.stp": ["shaft_damaged.stp:", "nothing loaded"],
    "stepnc-graph load --lenient examples/shaft_damaged.stp": ["P21-CURLY-QUOTE", "9 diagnostics"],
    "stepnc-graph load --format json": ['"instances": 89', '"graph": "https://w3id.org/stepnc-graph/data/shaft_two'],
    "stepnc-graph info": ["shaft_damaged.stp", "shaft_two_setups.stp", "89 instances"],
    "stepnc-graph link": ["linked 5 entities", "/links/shaft_plm_links.csv"],
    f"stepnc-graph export --format ttl --graph {SHAFT}$": ["stepnc:machining_workingstep.its_operation", "p21:id 30"],
    f"stepnc-graph export --format ttl --graph {SHAFT} -o shaft.ttl": ["wrote shaft.ttl"],
    "stepnc-graph export --format p21": ["wrote repaired.stp"],
    "stepnc-graph load repaired.stp": ["P21-UNRESOLVED-REF"],
    "stepnc-graph unload": ["removed: https://w3id.org/stepnc-graph/data/repaired.stp"],
    "stepnc-graph compact": ["compacted"],
    "stepnc-graph validate examples/shaft_two_setups.stp  ": ["passes", "0 violation(s)"],
    "stepnc-graph validate examples/shaft_damaged.stp": ["does not conform", "P21-CURLY-QUOTE"],
    "stepnc-graph validate examples/shaft_two_setups.stp --shapes": [_RULES],
    "stepnc-graph validate shaft.ttl": [_RULES, "1 violation(s)"],
    "stepnc-graph queries": ["tool-changes", "workingsteps-by-tool-type"],
    "stepnc-graph query tool-changes": ["WS5 RELIEF GROOVE", "WS6 FACE LEFT FINISH", "2 row(s)"],
    "stepnc-graph query workingsteps-by-tool-type": ["WS5 RELIEF GROOVE", "T02 GROOVING 3MM", "1 row(s)"],
    "stepnc-graph query -e": ["shaft_two_setups.stp/i30"],
    "stepnc-graph plan": ["SHAFT-42 (", "8 workingsteps, 2 tool changes", "WS5 RELIEF GROOVE"],
    "stepnc-graph schema entity": ["its_features : LIST [2:?] OF manufacturing_feature"],
    "stepnc-graph ontology build --check": ["0 stale"],
    "stepnc-graph ontology stats": ["turning_schema"],
}

#: (file, index among its blocks) -> how that block is checked.
CHECKS: dict[tuple[str, int], Check] = {
    ("README.md", 0): Check("python3 -m venv .venv && . .venv/bin/activate && pip install . && stepnc-graph load",
                            _install_then(["89 instances", "1 graph(s)"])),
    ("README.md", 1): Check("python3 -m venv .venv && . .venv/bin/activate && pip install -q -e '.[test]'",
                            _not_run("the test suite itself: this is the command that runs this test")),
    ("README.md", 2): Check("stepnc-graph load examples/shaft_two_setups.stp", _shell(_TOUR)),
    ("README.md", 3): Check("stepnc-graph query workingsteps-by-tool-type --param tool_type=grooving_tool", _shell(
        {"stepnc-graph query workingsteps-by-tool-type": ["WS5 RELIEF GROOVE"],
         "stepnc-graph query setup-sheet --format md": ["| SETUP 2 |", "T02 GROOVING 3MM"],
         "stepnc-graph plan": ["8 workingsteps, 2 tool changes"]},
        setup=("stepnc-graph load examples/shaft_two_setups.stp",))),
    ("README.md", 4): Check("import stepnc_graph as sg", _python(_readme_python)),
    ("README.md", 5): Check("stepnc-graph load examples/shaft_two_setups.stp", _shell(
        {"stepnc-graph query tool-changes --endpoint": ["T01 CNMG 120408", "T02 GROOVING 3MM", "2 row(s)"],
         "stepnc-graph export --endpoint": ['"@context"', '"WS1 FACE RIGHT ROUGH"'],
         "curl": ["https://w3id.org/stepnc-graph/data/shaft_two_setups.stp"]},
        ports=("7878", "7879"))),
    ("README.md", 6): Check("ontology/express/", _layout),
    ("docs/architecture.md", 0): Check("src/stepnc_graph/", _not_run(
        "the package tree: tests/test_architecture.py checks that it names every module and no other")),
    ("docs/linked-data.md", 0): Check("<G> a p21:ExchangeStructure, prov:Entity ;", _provenance),
    ("docs/linked-data.md", 1): Check("PREFIX prov: <http://www.w3.org/ns/prov#>",
                                      _sparql(2, "shaft_plm_links.csv", "stepnc-graph")),
    ("docs/linked-data.md", 2): Check("its_id,scope,p21_id,identifier,same_as", _mapping_csv),
    ("docs/linked-data.md", 3): Check("PREFIX stepnc: <https://w3id.org/stepnc-graph/iso14649#>",
                                      _sparql(7, "WS1 FACE RIGHT ROUGH", "WS8 OD40 FINISH")),
    ("docs/linked-data.md", 4): Check("{", _jsonld_node),
    ("docs/linked-data.md", 5): Check("pip install oxigraph", _shell(
        {"stepnc-graph info --endpoint": ["shaft_two_setups.stp", "89 instances"],
         "stepnc-graph validate --endpoint": ["0 violation(s)"],
         "stepnc-graph export --format p21": ["ISO-10303-21;", "WS1 FACE RIGHT ROUGH"]},
        ports=("7878",), skip=("pip install",))),
    ("docs/linked-data.md", 6): Check("stepnc-graph serve", _shell(
        {"curl": ['"value":"https://w3id.org/stepnc-graph/data/shaft_two_setups.stp"']},
        setup=("stepnc-graph load examples/shaft_two_setups.stp",), ports=("7878",),
        replace={"stepnc-graph serve": "stepnc-graph serve --port 7878 &"})),  # it runs until stopped
    ("docs/linked-data.md", 7): Check("PREFIX prov: <http://www.w3.org/ns/prov#>",
                                      _sparql(2, "shaft_two_setups.stp", "shaft_plm_links.csv", "tool/0.1.0")),
    ("docs/querying.md", 0): Check("stepnc-graph load examples/shaft_two_setups.stp", _shell(
        {"stepnc-graph queries": ["setup-sheet"],
         "stepnc-graph query workingsteps-by-tool-type  ": ["WS5 RELIEF GROOVE", "1 row(s)"],
         "stepnc-graph query workingsteps-by-tool-type --param tool_type=knurling_tool": ["program,order,workingstep"],
         "stepnc-graph query tool-changes": ["2 row(s)"],
         "stepnc-graph query -e": ["WS1 FACE RIGHT ROUGH", "8 row(s)"],
         "stepnc-graph plan": ["2 tool changes"]})),
    ("docs/querying.md", 1): Check("import stepnc_graph as sg", _python(
        _querying_python, before="import stepnc_graph as _sg\n_sg.load(_sg.open_store(), ['examples/shaft_two_setups.stp'])\n",
        optional=(("pandas", "to_dataframe()"),))),
    ("docs/querying.md", 2): Check("SELECT ?ws ?label WHERE {", _sparql(1, "WS5 RELIEF GROOVE")),
    ("docs/querying.md", 3): Check("SELECT ?o ?ws ?setup WHERE {", _sparql(8, '"WS1 FACE RIGHT ROUGH", "setup": "SETUP 1"')),
    ("docs/querying.md", 4): Check("SELECT ?o ?from ?to WHERE {", _sparql(2, '"from": "T01 CNMG 120408", "to": "T02')),
    ("docs/querying.md", 5): Check("SELECT ?ws ?f WHERE {", _sparql(1, "shaft_two_setups.stp/i34", "i42")),
    ("docs/querying.md", 6): Check("SELECT ?super (COUNT(?i) AS ?n) WHERE {", _sparql(1, '"n": 8')),
    ("docs/querying.md", 7): Check("SELECT ?program ?label ?n WHERE {", _sparql(8, '"n": 30')),
    ("docs/querying.md", 8): Check("SELECT ?x ?id WHERE { ?x attr:its_id ?id } ORDER BY ?id", _sparql(30)),
    ("docs/querying.md", 9): Check("SELECT DISTINCT ?p ?name WHERE {",
                                   _sparql(6, "technology.feedrate", "turning_technology.spindle_speed")),
    ("docs/querying.md", 10): Check("SELECT ?c WHERE { ?c rdfs:subClassOf* stepnc:speed_select_type }",
                                    _sparql(3, "const_cutting_speed", "const_spindle_speed")),
    ("docs/querying.md", 11): Check("# title: Steps using a tool", _sparql(7, "T01 CNMG 120408", "WS8 OD40 FINISH")),
    ("docs/validation.md", 0): Check("stepnc-graph validate part.stp", _shell(
        {"stepnc-graph validate part.stp ": ["passes", "0 violation(s), 1 warning(s)"],
         "stepnc-graph validate --format json": ['"passes": true', '"p21_id": 34'],
         "stepnc-graph validate --format turtle": ["sh:ValidationReport", "sh:conforms false"],
         "stepnc-graph validate --store S": ["0 violation(s)"],
         "stepnc-graph validate --severity violation": ["0 violation(s)"],
         "stepnc-graph validate data.ttl": ["0 violation(s)"]},
        setup=_VALIDATION_SETUP,
        replace={"part.stp": "examples/shaft_two_setups.stp", "S": "store", "IRI": SHAFT, "shapes.ttl": "our-rules.ttl"},
        files=_relaxed_rules)),
    ("docs/validation.md", 1): Check("line 42    #50     FACING_ROUGH  allowance:", _text_report),
}


def test_every_block_has_a_check() -> None:
    found = {(b.file, b.index): b for b in blocks()}
    assert set(found) == set(CHECKS), (sorted(set(found) - set(CHECKS)), sorted(set(CHECKS) - set(found)))
    for key, check in CHECKS.items():
        assert found[key].first.startswith(check.first.rstrip()), (key, found[key].first, check.first)


@pytest.mark.parametrize("key", sorted(CHECKS), ids=lambda k: f"{k[0]}:{k[1]}")
def test_block_runs_and_says_what_it_does(key: tuple[str, int], tmp_path: Path, example: GraphStore,
                                          process_time_bound: None) -> None:
    block = next(b for b in blocks() if (b.file, b.index) == key)
    CHECKS[key].run(block, tmp_path, example)


def test_ci_runs_the_readme_test_command() -> None:
    """CI runs exactly the README's test command: what follows the venv's creation there is a line
    of .ci/run (install and test), so the two cannot drift apart."""
    block = next(b for b in blocks() if (b.file, b.index) == ("README.md", 1))
    command = block.first.split("&& . .venv/bin/activate && ", 1)[1].strip()
    assert "pytest" in command
    ci = (ROOT / ".ci" / "run").read_text(encoding="utf-8").splitlines()
    assert command in [line.strip() for line in ci], (command, ci)
