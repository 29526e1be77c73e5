"""Daily use (issue 31): what a new user trips over -- false warnings, misleading messages, output
people read. Each test here failed on the code before its fix."""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

import pytest
from click.testing import CliRunner

import stepnc_graph as sg
from stepnc_graph.cli import main
from stepnc_graph.core.naming import DATA_BASE
from stepnc_graph.querying.query import QueryError, dataset
from stepnc_graph.store import GraphStore
from stepnc_graph.workplan.plan import build_plan

from conftest import ROOT

EXAMPLE = ROOT / "examples" / "shaft_two_setups.stp"
MAPPING = ROOT / "examples" / "shaft_plm_links.csv"
SHAFT = DATA_BASE + "shaft_two_setups.stp"


def linked() -> GraphStore:
    store = sg.open_store(memory=True)
    sg.load(store, [EXAMPLE])
    sg.link(store, MAPPING, SHAFT)
    return store


# -- 1: link graphs are not programs ---------------------------------------------------------------


def test_a_link_graph_is_not_counted_as_a_program() -> None:
    store = linked()
    assert sg.query(store, "tool-changes").warnings == []
    assert sg.query(store, "SELECT * WHERE { ?s ?p ?o } LIMIT 1").warnings == []
    assert build_plan(store).program == SHAFT  # the only program, beside its link graph
    link = SHAFT + "/links/shaft_plm_links.csv"
    assert [g.value for g in dataset(store, None)["named_graphs"]] == [SHAFT, link]  # GRAPH ?links reaches it
    with pytest.raises(QueryError, match="no loaded file with graph"):
        sg.query(store, "tool-changes", graph=link)  # --graph picks a program: its graph and its derived layer


def test_cli_query_and_plan_after_link_in_an_on_disk_store(tmp_path: Path) -> None:
    store = ["--store", str(tmp_path / "store")]
    runner = CliRunner()
    assert runner.invoke(main, ["load", *store, str(EXAMPLE)]).exit_code == 0
    assert runner.invoke(main, ["link", *store, "--graph", SHAFT, str(MAPPING)]).exit_code == 0
    done = runner.invoke(main, ["query", *store, "tool-changes"])
    assert done.exit_code == 0 and "warning" not in done.stderr, done.stderr
    done = runner.invoke(main, ["plan", *store])
    assert done.exit_code == 0, done.output


# -- 2: a mistyped or never-written term warns ------------------------------------------------------


@pytest.fixture(scope="module")
def shaft() -> GraphStore:
    store = sg.open_store(memory=True)
    sg.load(store, [EXAMPLE])
    return store


def test_a_mistyped_class_warns_with_did_you_mean(shaft: GraphStore) -> None:
    result = sg.query(shaft, "SELECT ?ws WHERE { ?ws a stepnc:workingstepp }")
    assert len(result) == 0
    [warning] = result.warnings
    assert "stepnc:workingstepp is not in the vocabulary" in warning and "stepnc:workingstep" in warning


def test_terms_in_full_and_under_declared_prefixes_are_checked(shaft: GraphStore) -> None:
    text = ("PREFIX s: <https://w3id.org/stepnc-graph/iso14649#> SELECT ?x WHERE { ?x a s:Turning_Workingstep ; "
            "<https://w3id.org/stepnc-graph/attribute#its_idd> ?id }")
    warnings = " ".join(sg.query(shaft, text).warnings)
    assert "stepnc:Turning_Workingstep" in warnings and "stepnc:turning_workingstep" in warnings
    assert "attr:its_idd" in warnings and "attr:its_id" in warnings


def test_correct_terms_strings_and_comments_give_no_warning(shaft: GraphStore) -> None:
    text = ('SELECT ?ws ?id WHERE { ?ws a stepnc:machining_workingstep ; attr:its_id ?id . ?s sga:executes ?ws '
            'FILTER(?id != "stepnc:nothing") }  # stepnc:nothing either')
    result = sg.query(shaft, text)
    assert len(result) > 0 and result.warnings == []


def test_a_generic_property_the_layer_never_writes_names_the_per_entity_one(shaft: GraphStore) -> None:
    result = sg.query(shaft, "SELECT ?x ?v WHERE { ?x attr:theoretical_size ?v }")
    [warning] = result.warnings
    assert "attr:theoretical_size is never written" in warning
    assert "stepnc:toleranced_length_measure.theoretical_size" in warning


def test_cli_prints_the_term_warning(tmp_path: Path) -> None:
    done = CliRunner().invoke(main, ["query", str(EXAMPLE), "-e", "SELECT ?ws WHERE { ?ws a stepnc:workingstepp }"])
    assert done.exit_code == 0 and "did you mean stepnc:workingstep" in done.stderr, done.stderr


# -- 3: SPARQL errors name the cause -----------------------------------------------------------------


@pytest.mark.parametrize(("text", "message", "line", "column"), [
    ("SELEKT ?x WHERE { ?x ?p ?o }", "found 'SELEKT'; did you mean SELECT?", 1, 1),
    ("SELECT (COUNT(?x AS ?n) WHERE { ?x ?p ?o }", "'(' opened here is never closed (a ')' is missing)", 1, 8),
    ("DELETE WHERE { ?x ?p ?o }", "updates are not allowed, queries are read-only", 1, 1),
    ("PREFIX a: <urn:x#>\nINSERT DATA { a:b a:c a:d }", "INSERT is SPARQL Update: updates are not allowed", 2, 1),
    ("SELECT ?x WHERE { ?x ?p }", "'}' ends an incomplete triple pattern", 1, 25),
    ("SELECT ?x WHERE {\n  ?x ?p ?o ;\n     ?q .\n}", "'.' ends an incomplete triple pattern", 3, 9),
    ('SELECT ?x WHERE { ?x ?p "abc }', "the string opened here with \" is not closed", 1, 25),
    ("SELECT ?x WHERE { ?x ?p ?o } LIMT 3", "'LIMT' is no SPARQL keyword or function; did you mean LIMIT?", 1, 30),
    ("SELECT ?x WHERE { ?x ?p ?o ", "the '{' opened here is never closed", 1, 17),
])
def test_syntax_errors_name_the_cause(shaft: GraphStore, text: str, message: str, line: int, column: int) -> None:
    with pytest.raises(QueryError) as bad:
        sg.query(shaft, text)
    assert message in str(bad.value)
    assert (bad.value.line, bad.value.column) == (line, column)
    for noise in ("CONSTRUCT", "GROUP_CONCAT", "<<", "{|", "~", "LATERAL"):
        assert noise not in str(bad.value).split("\n")[0].replace("CONSTRUCT, ASK", ""), noise


def test_valid_queries_with_values_filters_and_blank_nodes_still_run(shaft: GraphStore) -> None:
    text = ('SELECT ?ws ?id WHERE { VALUES ?c { stepnc:machining_workingstep } ?ws a ?c ; attr:its_id ?id . '
            'FILTER(STRLEN(?id) > 2) OPTIONAL { ?ws rdfs:label ?l } [] sga:executes ?ws . } ORDER BY ?id LIMIT 3')
    assert len(sg.query(shaft, text)) == 3


def test_query_dash_e_dash_reads_standard_input() -> None:
    runner = CliRunner()
    text = "SELECT ?ws WHERE { ?ws a stepnc:machining_workingstep }"
    for args in (["query", "-"], ["query", "-e", "-"]):
        done = runner.invoke(main, [*args, str(EXAMPLE), "--format", "csv"], input=text)
        assert done.exit_code == 0 and done.stdout.count("\n") == 9, (args, done.output)
    done = runner.invoke(main, ["query", "-e", "-", str(EXAMPLE)], input="SELEKT ?x")
    assert done.exit_code == 2 and "<stdin>:1:1" in done.stderr, done.stderr


def test_a_library_query_over_an_endpoint_gives_the_embedded_rows(tmp_path: Path) -> None:
    from oxigraph_server import OxigraphServer, ServerUnavailable

    server = OxigraphServer(tmp_path / "server")
    try:
        server.start()
    except ServerUnavailable as exc:
        pytest.skip(str(exc))
    try:
        done = CliRunner().invoke(main, ["load", "--endpoint", server.url, str(EXAMPLE)])
        assert done.exit_code == 0, done.output
        done = CliRunner().invoke(main, ["query", "tool-changes", "--endpoint", server.url, "--format", "csv"])
    finally:
        server.stop()
    assert done.exit_code == 0 and "T02 GROOVING 3MM" in done.stdout, done.output


# -- 5: documented examples that failed as written -------------------------------------------------


def test_a_graph_outside_the_dataset_warns_instead_of_answering_nothing(shaft: GraphStore) -> None:
    old = ("SELECT ?p ?name WHERE { GRAPH <https://w3id.org/stepnc-graph/iso14649> { ?p rdfs:domain "
           "stepnc:turning_technology ; rdfs:label ?name } }")  # docs/querying.md query 8 as it was
    result = sg.query(shaft, old)  # a query naming the vocabulary graph gets it as a named graph
    plain = sg.query(shaft, old.replace("GRAPH <https://w3id.org/stepnc-graph/iso14649> {", "{"))
    assert len(result) == 4 and result.rows == plain.rows and result.warnings == []
    layer = sg.query(shaft, f"SELECT * WHERE {{ GRAPH <{SHAFT}/derived> {{ ?s ?p ?o }} }} LIMIT 1")
    [warning] = layer.warnings
    assert len(layer) == 0 and f"GRAPH <{SHAFT}/derived> matches nothing" in warning and "leave out" in warning
    assert sg.query(shaft, f"SELECT * WHERE {{ GRAPH <{SHAFT}> {{ ?s ?p ?o }} }} LIMIT 1").warnings == []


def test_the_plan_is_part_of_the_api() -> None:
    store = sg.open_store(memory=True)
    sg.load(store, [EXAMPLE])
    plan = sg.build_plan(store)
    assert isinstance(plan, sg.Plan) and len(plan.tool_changes()) == 2


def test_the_generator_explains_itself(tmp_path: Path) -> None:
    import subprocess
    import sys

    script = str(ROOT / "bench" / "generate.py")
    done = subprocess.run([sys.executable, script, "--help"], capture_output=True, text=True, timeout=60)
    assert done.returncode == 0 and "usage:" in done.stdout and "SOURCE" in done.stdout, done.stderr
    done = subprocess.run([sys.executable, script, "many", str(tmp_path / "x.stp")], capture_output=True, text=True,
                          timeout=60)
    assert done.returncode == 2 and "Traceback" not in done.stderr and "invalid int value" in done.stderr


# -- 6: export without --graph: one rule for every format ------------------------------------------


def test_export_without_graph_writes_the_same_graphs_in_every_format() -> None:
    import json

    import pyoxigraph as ox

    store = linked()
    link = SHAFT + "/links/shaft_plm_links.csv"
    for fmt, rdf in (("nq", ox.RdfFormat.N_QUADS), ("trig", ox.RdfFormat.TRIG)):
        graphs = {q.graph_name.value for q in ox.parse(sg.export(store, fmt), rdf)}
        assert graphs == {SHAFT, link}, fmt
    document = json.loads(sg.export(store, "jsonld"))
    assert {g["@id"] for g in document["@graph"]} == {SHAFT, link}
    assert sg.export(store, "ttl") == sg.export(store, "ttl", SHAFT)  # the one program, beside its link graph
    derived = {q.graph_name.value for q in ox.parse(sg.export(store, "nq", SHAFT + "/derived"), ox.RdfFormat.N_QUADS)}
    assert derived == {SHAFT + "/derived"}  # a layer on request


# -- 7: feedback on long work, output people read --------------------------------------------------


DAMAGED = ROOT / "examples" / "shaft_damaged.stp"


def test_validate_summarises_by_rule_and_limits_the_listing() -> None:
    import json

    done = CliRunner().invoke(main, ["validate", str(DAMAGED), "--max-results", "3"])
    assert done.exit_code == 1
    lines = done.stdout.splitlines()
    assert sum(line.startswith("  line ") for line in lines) == 3
    assert "... 13 more result(s) not listed (--max-results 3)" in done.stdout
    summary = lines[lines.index("16 result(s) by rule:") + 1:]
    assert summary[0].split()[:2] == ["5", "violation"] and "P21-UNRESOLVED-REF" in summary[0]
    assert sum(int(line.split()[0]) for line in summary) == 16
    done = CliRunner().invoke(main, ["validate", "--format", "json", "--max-results", "1", str(DAMAGED)])
    report = json.loads(done.stdout)
    # 14 loader errors; the recovered curly quote and missing ';' are the loader's warnings
    assert len(report["results"]) == 1 and report["omitted"] == 15 and report["counts"] == {
        "Violation": 14, "Warning": 2, "Info": 0}
    assert report["by_rule"][0]["count"] == 5 and done.stdout.endswith("}\n")


def test_validate_tells_its_phases() -> None:
    from stepnc_graph.validation import validate

    heard: list[str] = []
    validate([EXAMPLE], progress=heard.append)
    kinds = [h.split()[0] for h in heard]
    assert {"loading", "checking", "describing"} <= set(kinds)
    assert kinds.index("loading") < kinds.index("checking") < kinds.index("describing")
    assert any(h.endswith("100 %") for h in heard if h.startswith("loading"))


def test_load_summary_uses_thousands_separators_and_gives_the_rate(tmp_path: Path) -> None:
    from generate import write  # type: ignore[import-not-found]

    program = tmp_path / "big.stp"
    count = write(2500, program)
    done = CliRunner().invoke(main, ["load", "--memory", str(program)])
    assert done.exit_code == 0, done.output
    assert f"{count:,} instances" in done.stdout and "instances/s)" in done.stdout
    assert f" {count} instances" not in done.stdout


def test_load_summary_states_the_store_size_on_disk(tmp_path: Path) -> None:
    import json

    from stepnc_graph.store import directory_bytes

    store_dir = tmp_path / "store"
    done = CliRunner().invoke(main, ["load", "--store", str(store_dir), str(EXAMPLE)])
    assert done.exit_code == 0, done.output
    size = directory_bytes(store_dir)
    assert done.stdout.splitlines()[-1] == f"store {store_dir.resolve()}: {size / 1e6:,.1f} MB on disk"
    done = CliRunner().invoke(main, ["load", "--store", str(store_dir), str(EXAMPLE), "--format", "json"])
    report = json.loads(done.stdout)
    assert report["store"] == str(store_dir.resolve()) and report["disk_bytes"] == directory_bytes(store_dir)
    done = CliRunner().invoke(main, ["load", "--memory", str(EXAMPLE), "--format", "json"])
    assert json.loads(done.stdout)["disk_bytes"] is None and json.loads(done.stdout)["store"] == "memory"
    done = CliRunner().invoke(main, ["load", "--memory", str(EXAMPLE)])
    assert "on disk" not in done.stdout


def test_sizes_for_people_use_decimal_units() -> None:
    from stepnc_graph.cli.store import human_bytes

    assert [human_bytes(n) for n in (812, 1000, 12_345_678, 1_400_000_000, 3 * 10**15)] == [
        "812 B", "1.0 kB", "12.3 MB", "1.4 GB", "3,000.0 TB"]


# -- 9: --graph and unload take a unique end of a graph IRI, and suggest on a miss ------------------


def test_a_graph_is_named_by_a_unique_end_of_its_iri() -> None:
    from stepnc_graph.graphs.names import UnknownGraph, resolve_graph

    graphs = [SHAFT, SHAFT + "/links/shaft_plm_links.csv", DATA_BASE + "sleeve.stp", "https://example.org/a/sleeve.stp"]
    assert resolve_graph("shaft_two_setups.stp", graphs) == SHAFT
    assert resolve_graph("data/shaft_two_setups.stp", graphs) == SHAFT
    assert resolve_graph("shaft_two_setups", graphs) == SHAFT  # the file name without its extension
    assert resolve_graph("shaft_plm_links.csv", graphs) == SHAFT + "/links/shaft_plm_links.csv"
    with pytest.raises(UnknownGraph, match="names 2 graphs"):
        resolve_graph("sleeve.stp", graphs)
    assert resolve_graph("a/sleeve.stp", graphs) == "https://example.org/a/sleeve.stp"
    with pytest.raises(UnknownGraph, match=f"did you mean {SHAFT}"):
        resolve_graph("shaft_two_setup.stp", graphs)
    with pytest.raises(UnknownGraph, match="setups.stp"):
        resolve_graph("setups.stp", graphs)  # not at a '/': no match, but a suggestion


def test_cli_commands_take_a_file_name_for_the_graph(tmp_path: Path) -> None:
    store = ["--store", str(tmp_path / "store")]
    runner = CliRunner()
    assert runner.invoke(main, ["load", *store, "--lenient", str(EXAMPLE), str(DAMAGED)]).exit_code == 1
    done = runner.invoke(main, ["export", *store, "--format", "nt", "--graph", "shaft_two_setups.stp"])
    assert done.exit_code == 0 and done.stdout.startswith(f"<{SHAFT}>"), done.output
    done = runner.invoke(main, ["query", *store, "tool-changes", "--graph", "shaft_two_setups.stp", "--format", "csv"])
    assert done.exit_code == 0 and "T02 GROOVING 3MM" in done.stdout, done.output
    done = runner.invoke(main, ["plan", *store, "--graph", "shaft_two_setups"])
    assert done.exit_code == 0 and "8 workingsteps" in done.stdout, done.output
    done = runner.invoke(main, ["unload", *store, "shaft_damage.stp"])
    assert done.exit_code == 2 and "did you mean https://w3id.org/stepnc-graph/data/shaft_damaged.stp" in done.stderr
    done = runner.invoke(main, ["unload", *store, "shaft_damaged.stp"])
    assert done.exit_code == 0 and "removed: https://w3id.org/stepnc-graph/data/shaft_damaged.stp" in done.stdout


# -- 10: the notebook: a reader that blocks no load, a report that shows itself, errors in API terms --


def test_api_errors_name_keywords_and_the_cli_names_flags(tmp_path: Path) -> None:
    from stepnc_graph.workplan.plan import PlanError

    store = sg.open_store(memory=True)
    sg.load(store, [EXAMPLE, DAMAGED], lenient=True)
    with pytest.raises(PlanError) as bad:
        sg.build_plan(store)
    assert "graph=" in str(bad.value) and "--graph" not in str(bad.value) and "sg.info(store)" in str(bad.value)
    with pytest.raises(ValueError) as bad:
        sg.export(store, "ttl")
    assert "graph=" in str(bad.value) and "--" not in str(bad.value)
    with pytest.raises(ValueError) as bad:
        sg.query(store, "workingsteps-by-tool-type", tool_type="spoon")
    assert "tool_type='spoon'" in str(bad.value) and "--param" not in str(bad.value)
    saved = ["--store", str(tmp_path / "s")]
    assert CliRunner().invoke(main, ["load", *saved, "--lenient", str(EXAMPLE), str(DAMAGED)]).exit_code == 1
    done = CliRunner().invoke(main, ["plan", *saved])
    assert done.exit_code == 2 and "--graph" in done.stderr and "stepnc-graph info" in done.stderr


def test_a_validation_report_shows_itself_in_a_notebook() -> None:
    from stepnc_graph.validation import validate

    report = validate([DAMAGED])
    html = report._repr_html_()
    assert "does not conform" in html and "14 violation(s), 2 warning(s)" in html
    assert html.count("<tr>") == 1 + len(report.by_rule()) + 1 + 16  # two tables with their heads
    assert "<td>P21-UNRESOLVED-REF</td>" in html and "&lt;" not in report.results[0].message
    assert repr(report).startswith("<ValidationReport fails: 14 violation(s), 2 warning(s)")


def test_a_notebook_reader_does_not_block_a_load(tmp_path: Path) -> None:
    store_dir = tmp_path / "store"
    saved = ["--store", str(store_dir)]
    assert CliRunner().invoke(main, ["load", *saved, str(EXAMPLE)]).exit_code == 0
    text = (ROOT / "docs" / "querying.md").read_text(encoding="utf-8")
    recipe = text.split("```python\n", 1)[1].split("\n", 2)[1]  # the notebook's open_store line
    assert "readonly=True" in recipe
    with sg.open_store(store_dir, readonly=True) as reader:
        assert CliRunner().invoke(main, ["load", *saved, str(DAMAGED), "--lenient"]).exit_code == 1
        assert len(sg.query(reader, "tool-changes")) == 2


def _cli(*args: str) -> subprocess.CompletedProcess[str]:
    return subprocess.run([sys.executable, "-m", "stepnc_graph.cli", *args], capture_output=True, text=True,
                          timeout=300)


def test_open_store_reads_without_the_lock_until_it_writes(tmp_path: Path) -> None:
    """``sg.open_store(path)`` in a notebook: CLI loads go on while it reads; its own load takes the
    writer's lock then, from the newest published state, and holds it until it is closed."""
    store_dir = tmp_path / "store"
    assert _cli("load", "--store", str(store_dir), str(EXAMPLE)).returncode == 0
    other = DATA_BASE + "shaft_damaged.stp"
    with sg.open_store(store_dir) as notebook:
        held = notebook.oxigraph  # a handle on the generation it reads
        seen = notebook.generation
        done = _cli("load", "--store", str(store_dir), "--lenient", str(DAMAGED))
        assert done.returncode == 1, done.stderr  # not busy: the notebook only reads
        assert len(sg.query(notebook, "tool-changes")) == 2  # still reads (the generation it opened)
        sg.load(notebook, [EXAMPLE], base_iri="urn:notebook")  # takes the lock now
        assert {g.graph for g in sg.info(notebook)} == {SHAFT, other, "urn:notebook"}  # the CLI's load kept
        assert len(held) > 0 and (store_dir / str(seen)).is_dir()  # not collected under its handle
        busy = _cli("load", "--store", str(store_dir), str(EXAMPLE))
        assert busy.returncode == 2 and "is being written by" in busy.stderr, busy.stderr
    del held
    assert _cli("load", "--store", str(store_dir), str(EXAMPLE)).returncode == 0  # closed: the lock is free


def test_a_new_store_opened_to_read_is_created_empty(tmp_path: Path) -> None:
    with sg.open_store(tmp_path / "new") as store:
        assert sg.info(store) == [] and _cli("load", "--store", str(tmp_path / "new"), str(EXAMPLE)).returncode == 0
        assert sg.unload(store, SHAFT)  # the unload reads the newest state: the graph the CLI loaded is there
    with sg.open_store(tmp_path / "new", readonly=True) as store:
        assert sg.info(store) == []


# -- 4: a strict error caused by a string that ran on names where it opened -------------------------


def test_strict_error_names_where_a_runaway_string_opened(tmp_path: Path) -> None:
    from stepnc_graph.part21 import Part21SyntaxError

    def read_file(path: Path) -> None:
        sg.load(sg.open_store(memory=True), [path])

    with pytest.raises(Part21SyntaxError) as bad:
        read_file(DAMAGED)
    error = bad.value
    assert (error.line, error.column) == (18, 24) and error.p21_id == 12
    assert "not closed before the next instance (line 20)" in str(error)
    assert "typographic quote (U+2019) at 18:51" in str(error)
    plain = tmp_path / "plain.stp"
    text = EXAMPLE.read_text(encoding="utf-8")
    plain.write_text(text.replace("'WS1 FACE RIGHT ROUGH'", "'WS1 FACE RIGHT ROUGH", 1), encoding="utf-8")
    with pytest.raises(Part21SyntaxError) as bad:
        read_file(plain)
    line = next(n for n, t in enumerate(text.splitlines(), 1) if "'WS1 FACE RIGHT ROUGH'" in t)
    assert bad.value.line == line and "not closed before the next instance" in str(bad.value)
    assert "typographic" not in str(bad.value)


# -- 8: output people read: terminal width, one name per format, JSON lines, RDF for CONSTRUCT ------


STDIN_GRAPH = DATA_BASE + "stdin"


def test_a_program_on_standard_input_wherever_a_program_is_read() -> None:
    """``-`` reads a Part 21 program from standard input in validate, query and plan, as in load;
    messages name it <stdin>."""
    runner, program = CliRunner(), EXAMPLE.read_text(encoding="utf-8")
    checked = runner.invoke(main, ["validate", "-"], input=program)
    assert checked.exit_code == 0 and checked.stdout.startswith(f"{STDIN_GRAPH}: passes"), checked.output
    rows = runner.invoke(main, ["query", "tool-changes", "-", "--format", "csv"], input=program)
    assert rows.exit_code == 0 and rows.stdout.count(f"\n{STDIN_GRAPH},") == 2, rows.output
    plan = runner.invoke(main, ["plan", "-", "--format", "json"], input=program)
    assert plan.exit_code == 0 and '"critical_tool"' in plan.stdout, plan.output
    damaged = DAMAGED.read_text(encoding="utf-8")
    strict = runner.invoke(main, ["validate", "--strict", "-"], input=damaged)
    assert strict.exit_code == 2 and "<stdin>:18:24" in strict.stderr, strict.stderr
    found = runner.invoke(main, ["validate", "-"], input=damaged)
    assert found.exit_code == 1 and "14 violation(s), 2 warning(s)" in found.stdout


def test_an_express_file_on_standard_input() -> None:
    done = CliRunner().invoke(main, ["schema", "check", "--parse-only", "-"],
                              input="SCHEMA x; ENTITY a; END_ENTITY; END_SCHEMA;\n")
    assert done.exit_code == 0 and "parsed <stdin>" in done.stdout, done.output
    done = CliRunner().invoke(main, ["schema", "check", "-"], input="SCHEMA x; ENTITY a; END_ENTITY END_SCHEMA;\n")
    assert done.exit_code == 2 and "<stdin>:1:32" in done.stderr, done.stderr


@pytest.mark.parametrize(("args", "says"), [
    (["query", "-", "-"], "standard input is read once"),
    (["validate", "-", "-"], "standard input (-) is given twice"),
    (["schema", "check", "-", "-"], "standard input (-) is given twice"),
    (["validate", "--shapes", "-", str(EXAMPLE)], "--shapes -: shapes are read from a file"),
    (["link", "-"], "link -: the mapping must be a file"),
])
def test_standard_input_where_it_cannot_serve_is_refused_with_the_reason(args: list[str], says: str) -> None:
    done = CliRunner().invoke(main, args, input="")
    assert done.exit_code == 2 and says in done.stderr and "Traceback" not in done.output, done.output



def test_a_table_fits_the_width_it_is_given(shaft: GraphStore) -> None:
    result = sg.query(shaft, "tool-changes")
    wide = result.serialize("table").decode().splitlines()
    assert max(len(line) for line in wide) > 80
    fitted = result.serialize("table", width=80).decode().splitlines()
    assert len(fitted) == len(wide) and max(len(line) for line in fitted) <= 80
    assert "\u2026" in fitted[1] and "SETUP 1" in fitted[1] and " #34 " in fitted[1]  # short cells stay whole
    roomy = result.serialize("table", width=200).decode().splitlines()
    assert roomy == wide  # a table that fits is not touched


def test_format_names_are_one_set_in_any_case() -> None:
    runner = CliRunner()
    done = runner.invoke(main, ["validate", "--format", "ttl", str(EXAMPLE)])
    assert done.exit_code == 0 and "sh:ValidationReport" in done.stdout, done.output
    done = runner.invoke(main, ["query", "tool-changes", str(EXAMPLE), "--format", "CSV"])
    assert done.exit_code == 0 and done.stdout.startswith("program,changes"), done.output
    done = runner.invoke(main, ["query", "tool-changes", str(EXAMPLE), "--format", "markdown"])
    assert done.exit_code == 0 and done.stdout.startswith("| program |"), done.output


def test_json_ends_with_a_newline_and_construct_gives_rdf() -> None:
    runner = CliRunner()
    done = runner.invoke(main, ["query", "tool-changes", str(EXAMPLE), "--format", "json"])
    assert done.exit_code == 0 and done.stdout.endswith("}\n")
    construct = "CONSTRUCT { ?ws rdfs:label ?l } WHERE { ?ws a stepnc:machining_workingstep ; rdfs:label ?l }"
    done = runner.invoke(main, ["query", "-e", construct, str(EXAMPLE), "--format", "turtle"])
    assert done.exit_code == 0 and "@prefix rdfs:" in done.stdout and 'rdfs:label "WS1 FACE RIGHT ROUGH"' in done.stdout
    done = runner.invoke(main, ["query", "tool-changes", str(EXAMPLE), "--format", "nt"])
    assert done.exit_code == 2 and "for CONSTRUCT and DESCRIBE results" in done.stderr


# -- 11: the reference is installed and complete, completion is documented --------------------------


def test_used_by_reaches_through_supertypes_and_selects() -> None:
    html = (ROOT / "docs" / "ontology.html").read_text(encoding="utf-8")
    section = html[html.index('id="turning_technology"'):]
    section = section[:section.index("</section>")]
    assert "Used through a supertype or SELECT" in section
    assert ('<a href="#machining_operation"><code>machining_operation</code></a>.<code>its_technology</code> '
            '(as <a href="#technology"><code>technology</code></a>)') in section


def test_the_reference_ships_in_the_wheel_and_the_cli_finds_it() -> None:
    import tomllib

    config = tomllib.loads((ROOT / "pyproject.toml").read_text(encoding="utf-8"))
    shipped = config["tool"]["hatch"]["build"]["targets"]["wheel"]["force-include"]
    assert shipped["docs/ontology.html"] == "stepnc_graph/data/docs/ontology.html"
    done = CliRunner().invoke(main, ["ontology", "reference"])
    assert done.exit_code == 0 and Path(done.stdout.strip()) == ROOT / "docs" / "ontology.html"


def test_shell_completion_works_as_documented() -> None:
    import os
    import subprocess
    import sys

    readme = (ROOT / "README.md").read_text(encoding="utf-8")
    assert 'eval "$(_STEPNC_GRAPH_COMPLETE=bash_source stepnc-graph)"' in readme
    env = {**os.environ, "_STEPNC_GRAPH_COMPLETE": "bash_complete", "COMP_WORDS": "stepnc-graph val",
           "COMP_CWORD": "1"}
    done = subprocess.run([sys.executable, "-c", "from stepnc_graph.cli import main; main(prog_name='stepnc-graph')"], env=env,
                          capture_output=True, text=True, timeout=60)
    assert "validate" in done.stdout, (done.stdout, done.stderr)


# -- 12: the plan picture: whole labels, lanes named by their workplans, the operation on the box --


def test_plan_boxes_hold_whole_labels_and_the_operation_and_lanes_name_workplans() -> None:
    import xml.etree.ElementTree as ET

    store = sg.open_store(memory=True)
    sg.load(store, [EXAMPLE])
    svg = ET.fromstring(sg.build_plan(store).svg())
    ns = "{http://www.w3.org/2000/svg}"
    first = next(g for g in svg.iter(f"{ns}g") if g.get("data-order") == "1")
    texts = [t.text for t in first.iter(f"{ns}text")]
    assert " ".join(texts[:2]) == "1. WS1 FACE RIGHT ROUGH" and "\u2026" not in " ".join(texts)
    assert "facing_rough" in texts
    lanes = {g.get("data-setup"): g.get("data-workplan") for g in svg.iter(f"{ns}g") if g.get("class") == "lane"}
    assert lanes == {"SETUP 1": "SETUP 1 - RIGHT END", "SETUP 2": "SETUP 2 - LEFT END"}


def test_plan_summary_names_the_shared_tool() -> None:
    done = CliRunner().invoke(main, ["plan", str(EXAMPLE)])
    assert done.exit_code == 0 and "shared tool T01 CNMG 120408 #100: SETUP 1, SETUP 2" in done.stdout
