"""Untrusted text never reaches a terminal raw, and CSV never hands a spreadsheet a formula.

Untrusted: file names, a program's values, link identifiers, the detail of an error from
Oxigraph or from a remote server. A terminal acts on escape sequences (the window title, links,
colours, clearing the screen) and on the bidirectional overrides; rich reads ``[...]`` as
markup. The commands run here as a user runs them: in a child process whose standard output
and error are real pseudo-terminals (:mod:`pty`), or pipes. On a terminal every such character
is shown escaped (``\\x1b``); into a pipe the data stays exact, and standard error is always
escaped. Every case here failed before the CLI printed through ``terminal_safe``.
"""

from __future__ import annotations

import csv
import fcntl
import http.server
import io
import json
import os
import pty
import select
import struct
import subprocess
import sys
import termios
import threading
import time
import tty
from pathlib import Path
from typing import Any

import pyoxigraph as ox
import pytest

import stepnc_graph as sg
from stepnc_graph.core.errors import excerpt
from stepnc_graph.validation.report import Result, ValidationReport

from conftest import ROOT
from test_load import HEADER

pytestmark = pytest.mark.usefixtures("process_time_bound")

EXAMPLE = ROOT / "examples" / "shaft_two_setups.stp"
CLI = [sys.executable, "-m", "stepnc_graph.cli"]
#: what a hostile text holds: an OSC sequence setting the window title, a colour, a C1 CSI,
#: a right-to-left override, and rich markup that would make a link
OSC = "\x1b]0;PWNED\x07"
HOSTILE = f"{OSC}\x1b[31mRED\x9b2J\u202eevil[link=evil.example]click"  # no "/": a file name too
#: the byte strings a terminal must never receive from data
RAW = [b"\x1b]0;PWNED", b"\x1b[31mRED", "\x9b".encode(), "\u202e".encode(), b"\x1b]8;"]


def run(*args: str, tty_out: bool = False, tty_err: bool = False, cwd: Path | None = None,
        columns: int = 200) -> tuple[int, bytes, bytes]:
    """The real command; standard output and/or error a pseudo-terminal of ``columns`` (raw: no CR
    added), else pipes.

    TERM is a colour terminal's, so rich writes its own escape sequences as it would for a user.
    """
    env = {k: v for k, v in os.environ.items()
           if k not in ("NO_COLOR", "FORCE_COLOR", "TTY_COMPATIBLE", "TTY_INTERACTIVE", "COLUMNS", "LINES")}
    env["TERM"] = "xterm-256color"
    streams: dict[str, Any] = {}
    masters: dict[str, int] = {}
    for name, wanted in (("stdout", tty_out), ("stderr", tty_err)):
        if wanted:
            masters[name], streams[name] = pty.openpty()
            tty.setraw(streams[name])
            fcntl.ioctl(streams[name], termios.TIOCSWINSZ, struct.pack("HHHH", 50, columns, 0, 0))
        else:
            streams[name] = subprocess.PIPE
    child = subprocess.Popen([*CLI, *args], cwd=cwd, env=env, stdin=subprocess.DEVNULL, **streams)
    fds: dict[str, int] = {}
    for name in ("stdout", "stderr"):
        if name in masters:
            os.close(streams[name])
            fds[name] = masters[name]
        else:
            fds[name] = getattr(child, name).fileno()
    received: dict[int, list[bytes]] = {fd: [] for fd in fds.values()}
    open_fds = set(received)
    deadline = time.monotonic() + 120
    while open_fds and time.monotonic() < deadline:
        ready, _, _ = select.select(list(open_fds), [], [], 1)
        for fd in ready:
            try:
                data = os.read(fd, 1 << 16)
            except OSError:  # EIO: the terminal's last writer has gone
                data = b""
            if data:
                received[fd].append(data)
            else:
                open_fds.discard(fd)
    child.wait(timeout=60)
    for fd in masters.values():
        os.close(fd)
    for pipe in (child.stdout, child.stderr):
        if pipe is not None:
            pipe.close()
    return child.returncode, b"".join(received[fds["stdout"]]), b"".join(received[fds["stderr"]])


def assert_no_raw(data: bytes) -> None:
    for raw in RAW:
        assert raw not in data, (raw, data)


def assert_shown(data: bytes) -> None:
    """The hostile text arrived, escaped (rich drops BEL itself) and with its markup as text."""
    text = data.decode()
    assert "\\x1b]0;PWNED" in text and "\\x1b[31mRED\\x9b2J\\u202eevil" in text, text
    assert "[link=evil.example]click" in text, text
    assert_no_raw(data)


# -- the function ------------------------------------------------------------------------------------


def test_terminal_safe_escapes_what_a_terminal_acts_on_and_nothing_else() -> None:
    from stepnc_graph.cli.common import terminal_safe

    assert terminal_safe(HOSTILE) == ("\\x1b]0;PWNED\\x07\\x1b[31mRED\\x9b2J\\u202eevil"
                                      "[link=evil.example]click")
    assert terminal_safe("\x00\x08\x0b\x0c\x0e\x1f\x7f\x80\x9f") == "\\x00\\x08\\x0b\\x0c\\x0e\\x1f\\x7f\\x80\\x9f"
    assert terminal_safe("\u061c\u200e\u200f\u202a\u202d\u2066\u2069") == \
        "\\u061c\\u200e\\u200f\\u202a\\u202d\\u2066\\u2069"
    normal = "T01 CNMG 120408\tØ 50 mm, µm, 日本, C:\\parts\\x.stp, «ä»\nline 2\r\nline 3\n"
    assert terminal_safe(normal) == normal  # tab, line breaks and printable Unicode stay
    assert terminal_safe("over\rwrite") == "over\\x0dwrite"  # a lone CR would overwrite the line
    assert terminal_safe("a\nb\r\nc", newlines=False) == "a\\x0ab\\x0d\\x0ac"
    doc = json.dumps({"v": "\x1b\x9b\u202e\x7f"}, ensure_ascii=False)
    assert json.loads(terminal_safe(doc, uchar=True)) == {"v": "\x1b\x9b\u202e\x7f"}  # JSON's notation: same data
    assert terminal_safe(terminal_safe(HOSTILE)) == terminal_safe(HOSTILE)


def test_a_syntax_error_excerpt_escapes_bidirectional_overrides() -> None:
    window, _ = excerpt("#1=X('abc\u202edef\x1b');", 5)
    assert window == "#1=X('abc\\u202edef\\x1b');"


# -- standard error: always ---------------------------------------------------------------------------


def test_an_error_naming_a_file_is_escaped_on_a_pipe_and_a_terminal(tmp_path: Path) -> None:
    name = f"missing{HOSTILE}.stp"
    for tty_err in (False, True):
        code, _, err = run("load", "--memory", name, cwd=tmp_path, tty_err=tty_err)
        assert code == 2
        assert_shown(err)
        assert err.count(b"\n") == 2  # the error and the hint: the name broke no line


def test_oxigraph_error_detail_is_escaped(tmp_path: Path) -> None:
    code, _, err = run("query", str(EXAMPLE), "-e", "SELECT ?x WHERE { BIND(1 AS ?y) }",
                       "--param", f"x=<http://a/{HOSTILE}>")
    assert code == 2 and b"Invalid IRI code point" in err
    assert_no_raw(err)
    assert b"\\x1b" in err


def test_a_remote_servers_error_body_is_escaped() -> None:
    class Hostile(http.server.BaseHTTPRequestHandler):
        def do_POST(self) -> None:  # noqa: N802 -- the http.server API
            body = f"bad request {HOSTILE}".encode()
            self.send_response(400)
            self.send_header("Content-Type", "text/plain; charset=utf-8")
            self.send_header("Content-Length", str(len(body)))
            self.end_headers()
            self.wfile.write(body)

        def log_message(self, *args: object) -> None:
            pass

    httpd = http.server.HTTPServer(("127.0.0.1", 0), Hostile)
    threading.Thread(target=httpd.serve_forever, daemon=True).start()
    try:
        code, _, err = run("query", "--endpoint", f"http://127.0.0.1:{httpd.server_address[1]}",
                           "-e", "ASK { ?s ?p ?o }", tty_err=True)
    finally:
        httpd.shutdown()
        httpd.server_close()
    assert code == 2 and b"answered 400" in err
    assert_shown(err)


def test_schema_entity_shows_its_argument_as_text() -> None:
    """`schema entity` echoed its argument as markup: ``[red]x`` lost its first word."""
    code, _, err = run("schema", "entity", f"[red]x{OSC}")
    assert code == 2 and b"[red]x\\x1b]0;PWNED" in err
    assert_no_raw(err)


def test_a_usage_error_quotes_the_command_line_escaped() -> None:
    code, _, err = run("info", f"extra{HOSTILE}", tty_err=True)
    assert code == 2 and b"unexpected extra argument (extra\\x1b]0;PWNED" in err
    assert_no_raw(err)


def test_the_progress_bar_shows_a_file_name_escaped(tmp_path: Path) -> None:
    from generate import write  # type: ignore[import-not-found]

    big = tmp_path / f"big{HOSTILE}.stp"
    write(20_000, tmp_path / "big.stp")  # 1.2 MB: a bar is drawn for a load of 1 MiB or more
    (tmp_path / "big.stp").rename(big)
    code, _, err = run("load", "--memory", "--format", "text", big.name, cwd=tmp_path, tty_err=True)
    assert code == 0, err
    assert b"loading big\\x1b]0;PWNED" in err  # the bar was drawn, with the name
    assert_shown(err)


# -- standard output: escaped on a terminal, exact into a pipe -----------------------------------------


@pytest.fixture
def linked(tmp_path: Path) -> Path:
    """A store whose program's entities carry hostile and formula-like link identifiers."""
    store = tmp_path / "s"
    assert run("load", "--store", str(store), str(EXAMPLE))[0] == 0
    mapping = tmp_path / "ids.csv"
    with mapping.open("w", newline="", encoding="utf-8") as f:
        w = csv.writer(f)
        w.writerow(["its_id", "scope", "identifier"])
        w.writerows([("SHAFT-42", "project", "=1+2"), ("T01 CNMG 120408", "machining_tool", HOSTILE),
                     ("T02 GROOVING 3MM", "machining_tool", "-3.5"), ("WS5 RELIEF GROOVE", "machining_workingstep",
                                                                     "@SUM(A1)\nfake row")])
    code, _, err = run("link", "--store", str(store), str(mapping))
    assert code == 0, err
    return store


IDS = "SELECT ?id WHERE { ?x dcterms:identifier ?id } ORDER BY ?id"


def test_query_table_on_a_terminal_escapes_link_identifiers(linked: Path) -> None:
    code, out, _ = run("query", "--store", str(linked), "-e", IDS, tty_out=True)
    assert code == 0
    assert_shown(out)
    lines = out.decode().splitlines()
    assert len(lines) == 5 and "@SUM(A1)\\x0afake row" in lines  # one line per row: a cell cannot fake one
    piped = run("query", "--store", str(linked), "-e", IDS)[1].decode()
    # into a pipe the characters are the data's; a table row is one line there too (csv, tsv and
    # json keep the line break: test_other_query_formats_on_a_terminal)
    assert HOSTILE in piped and "@SUM(A1) fake row" in piped and len(piped.splitlines()) == 5


def test_normal_output_is_the_same_on_a_terminal_and_a_pipe(tmp_path: Path) -> None:
    """Data without control characters is written byte for byte alike (rich's colours aside: none
    here), on a terminal wide enough for the table; a narrower one gets the table fitted to it."""
    store = tmp_path / "s"
    assert run("load", "--store", str(store), str(EXAMPLE))[0] == 0
    for args in (["query", "setup-sheet", str(EXAMPLE)], ["query", "setup-sheet", str(EXAMPLE), "--format", "csv"],
                 ["query", "setup-sheet", str(EXAMPLE), "--format", "json"], ["validate", str(EXAMPLE)],
                 ["export", "--store", str(store), "--format", "nt"], ["export", "--store", str(store), "--format", "p21"]):
        on_terminal = run(*args, tty_out=True, columns=1000)
        piped = run(*args)
        assert on_terminal[0] == piped[0] and on_terminal[1] == piped[1], args
    piped = run("query", "setup-sheet", str(EXAMPLE))[1].decode().splitlines()
    fitted = run("query", "setup-sheet", str(EXAMPLE), tty_out=True, columns=100)[1].decode().splitlines()
    assert max(map(len, piped)) > 100 >= max(map(len, fitted)) and len(fitted) == len(piped)


@pytest.mark.parametrize("fmt", ["json", "tsv", "md"])
def test_other_query_formats_on_a_terminal(linked: Path, fmt: str) -> None:
    code, out, _ = run("query", "--store", str(linked), "-e", IDS, "--format", fmt, tty_out=True)
    assert code == 0
    assert_no_raw(out)
    piped = run("query", "--store", str(linked), "-e", IDS, "--format", fmt)[1]
    if fmt == "json":  # the same JSON document: JSON's own escapes
        assert json.loads(out) == json.loads(piped) and b"\\u001b]0;PWNED" in out
    else:
        assert b"\\x1b]0;PWNED" in out and len(out.splitlines()) == len(piped.splitlines())  # both escape \\n


def test_plan_shows_labels_as_text_not_markup(tmp_path: Path) -> None:
    program = tmp_path / "plan.stp"
    # Part 21 writes ESC as \X\1B: the value holds the character itself once read
    label = "[link=http://evil.example]SETUP[/link] \\X\\1B]0;PWNED\\X\\07 1"
    program.write_text(EXAMPLE.read_text().replace("'SETUP 1", "'" + label))
    code, out, _ = run("plan", str(program), tty_out=True)
    assert code == 0
    assert b"[link=http://evil.example]SETUP[/link] \\x1b]0;PWNED" in out
    assert_no_raw(out)
    piped = run("plan", str(program))[1]
    # the markup is not eaten (rich itself drops BEL, BS, VT, FF and CR from what it prints)
    assert "[link=http://evil.example]SETUP[/link] \x1b]0;PWNED 1".encode() in piped


def test_export_on_a_terminal(tmp_path: Path) -> None:
    program = tmp_path / "p.stp"
    program.write_text(HEADER + "#1=PROPERTY_PARAMETER('a\\X\\1B]0;PWNED\\X\\07 b\\X2\\202E\\X0\\');\n"
                       "ENDSEC;END-ISO-10303-21;\n")
    store = str(tmp_path / "s")
    assert run("load", "--store", store, str(program))[0] == 0
    code, out, _ = run("export", "--store", store, "--format", "nt", tty_out=True)
    assert code == 0 and b" b\\u202e" in out  # N-Triples' escape (Oxigraph writes C0 ones itself): still valid
    assert_no_raw(out)
    piped = run("export", "--store", store, "--format", "nt")[1]
    assert " b\u202e".encode() in piped


def test_queries_shows_a_query_files_header_as_text(tmp_path: Path) -> None:
    rq = tmp_path / "mine.rq"
    rq.write_text(f"# title: [link=http://evil.example]mine[/link] {OSC}\n# description: d\nSELECT * WHERE {{}}\n")
    code, out, _ = run("queries", str(rq), tty_out=True)
    assert code == 0 and b"[link=http://evil.example]mine[/link] \\x1b]0;PWNED" in out
    assert_no_raw(out)


# -- validation reports -------------------------------------------------------------------------------------


def _result(message: str) -> Result:
    return Result("Violation", "urn:g", "urn:g/i1", 1, "property_parameter", 2, "parameter_name", "x", message,
                  "rule", "clause", "http://www.w3.org/ns/shacl#MaxLengthConstraintComponent")


def test_report_text_keeps_one_line_per_result() -> None:
    report = ValidationReport([_result("found 'a\nline 9  #9 FAKE  forged\r'")], ["urn:g"])
    assert report.to_text().count("\n") == 2  # the graph's line and the result's
    assert "found 'a\\nline 9  #9 FAKE  forged\\r'" in report.to_text()


def test_report_turtle_escapes_every_line_break() -> None:
    message = "found 'a\rb\nc\"d\\'"
    doc = ValidationReport([_result(message)], ["urn:g"]).to_turtle()
    store = ox.Store()
    store.load(doc.encode(), ox.RdfFormat.TURTLE)
    [quad] = store.quads_for_pattern(None, ox.NamedNode("http://www.w3.org/ns/shacl#resultMessage"), None)
    assert isinstance(quad.object, ox.Literal) and quad.object.value == message


# -- CSV and TSV: formula cells ---------------------------------------------------------------------------


FORMULAS = ("SELECT ?v WHERE { VALUES ?v { \"=1+2\" \"+1\" \"-x\" \"@SUM(A1)\" \"\\tx\" \"\\rx\" \"-3.5\" "
            "\"=x\"@en -3.5 -2 \"-1.5E3\"^^xsd:double \"-INF\"^^xsd:double \"=1\"^^xsd:integer \"plain\" "
            "<http://x.example/-> } }")


def _cells(data: bytes) -> list[str]:
    return [row["v"] for row in csv.DictReader(io.StringIO(data.decode(), newline=""))]


def test_csv_cells_a_spreadsheet_would_run_get_an_apostrophe() -> None:
    code, out, err = run("query", str(EXAMPLE), "-e", FORMULAS, "--format", "csv")
    assert code == 0, err
    raw = _cells(run("query", str(EXAMPLE), "-e", FORMULAS, "--format", "csv", "--csv-raw")[1])
    assert raw[:8] == ["=1+2", "+1", "-x", "@SUM(A1)", "\tx", "\rx", "-3.5", "=x"]
    numbers = {8, 9, 10}  # -3.5, -2 and -1.5E3 (as Oxigraph writes it): numeric literals, numbers in a sheet too
    assert _cells(out) == [c if i in numbers or i > 12 else "'" + c for i, c in enumerate(raw)]
    assert raw[11:] == ["-INF", "=1", "plain", "http://x.example/-"]  # -INF and =1 are no numbers: guarded


def test_csv_raw_is_the_w3c_format_exactly() -> None:
    store = sg.open_store(memory=True)
    sg.load(store, [EXAMPLE])
    solutions = store.query(FORMULAS, prefixes={"xsd": "http://www.w3.org/2001/XMLSchema#"})
    assert isinstance(solutions, ox.QuerySolutions)
    w3c = solutions.serialize(format=ox.QueryResultsFormat.CSV)
    code, out, _ = run("query", str(EXAMPLE), "-e", FORMULAS, "--format", "csv", "--csv-raw")
    assert code == 0 and out == w3c
    assert sg.query(store, FORMULAS).serialize("csv", csv_raw=True) == w3c
    assert _cells(sg.query(store, FORMULAS).serialize("csv"))[0] == "'=1+2"  # the API's default is the CLI's


def test_tsv_cells_get_the_apostrophe_inside_the_literal() -> None:
    code, out, _ = run("query", str(EXAMPLE), "-e", FORMULAS, "--format", "tsv")
    assert code == 0
    cells = out.decode().splitlines()[1:]
    assert cells[:3] == ['"\'=1+2"', '"\'+1"', '"\'-x"'] and '"\'=x"@en' in cells
    assert "-3.5" in cells and "-2" in cells and "<http://x.example/->" in cells
    parsed = ox.parse_query_results(out, format=ox.QueryResultsFormat.TSV)  # still valid SPARQL TSV
    assert isinstance(parsed, ox.QuerySolutions) and len(list(parsed)) == 15
    raw = run("query", str(EXAMPLE), "-e", FORMULAS, "--format", "tsv", "--csv-raw")[1]
    assert raw.decode().splitlines()[1] == '"=1+2"'


def test_csv_on_a_terminal_is_escaped_and_guarded(linked: Path) -> None:
    code, out, _ = run("query", "--store", str(linked), "-e", IDS, "--format", "csv", tty_out=True)
    assert code == 0
    assert_no_raw(out)
    assert out.splitlines()[1:] == [b"\\x1b]0;PWNED\\x07\\x1b[31mRED\\x9b2J\\u202eevil[link=evil.example]click",
                                    b"'-3.5", b"'=1+2", b"'@SUM(A1)\\x0afake row"]
    assert out.count(b"\r\n") == 5  # CSV's CR LF line ends are kept


def test_normal_csv_is_unchanged() -> None:
    store = sg.open_store(memory=True)
    sg.load(store, [EXAMPLE])
    for name in ("setup-sheet", "workplan-sequence", "tool-changes"):
        result = sg.query(store, name)
        assert result.serialize("csv") == result.serialize("csv", csv_raw=True)
        assert result.serialize("tsv") == result.serialize("tsv", csv_raw=True)


def test_the_formula_guard_does_not_depend_on_oxigraphs_json_layout() -> None:
    from stepnc_graph.querying.results import _guard_formulas

    compact = ('{"head":{"vars":["v"]},"results":{"bindings":[{"v":{"type":"literal","value":"=1"}},'
               '{"v":{"type":"literal","value":"-2","datatype":"http://www.w3.org/2001/XMLSchema#integer"}},'
               '{"v":{"type":"literal","value":"\\t\\"x"}},{"v":{"type":"literal","value":"a\\"+b"}},'
               '{"v":{"type":"literal","value":"@x","xml:lang":"en"}}]}}').encode()
    spaced = json.dumps(json.loads(compact), indent=1).encode()  # another writer's layout
    for data in (compact, spaced):
        values = [b["v"]["value"] for b in json.loads(_guard_formulas(data))["results"]["bindings"]]
        assert values == ["'=1", "-2", "'\t\"x", 'a"+b', "'@x"]
