"""What every command module shares: consoles, exit codes, error output, store options.

The CLI is the only part of stepnc-graph that prints. Each command group is a
module of this package that calls the Python API; this module holds the few
pieces they all need, so the commands stay thin and report errors alike: a
user error (bad input, bad usage, a store that cannot be used) is one line on
standard error -- or a JSON object on standard output under ``--format json``
-- and exit code 2, never a traceback.

Much of what the CLI prints is untrusted: file names, values of a program, link
identifiers, the text of an error from Oxigraph or from a remote server. A terminal
acts on some characters instead of showing them (escape sequences set the window
title, make links, clear the screen; U+202E reverses the text after it), so the CLI
shows such text through :func:`terminal_safe` at the two places it writes: its rich
consoles (:data:`out`, :data:`err`) and :func:`write_out` for data. Standard error is
always made safe; standard output only when it is a terminal -- into a pipe or a
file, data stays exact. Text put into rich markup goes through :func:`escape`, so
``[bold]`` or ``[link=...]`` in data is shown, never read as markup.
"""

from __future__ import annotations

import functools
import io
import json
import re
import sys
from dataclasses import dataclass
import warnings
from collections.abc import Callable, Iterable, Iterator
from contextlib import contextmanager
from pathlib import Path
from typing import IO, TYPE_CHECKING, Any, NoReturn, TypeVar, cast

import click

from stepnc_graph.core.errors import CONTROLS, StepncGraphError, escaped

if TYPE_CHECKING:
    from rich.console import Console
    from rich.segment import Segment

    from stepnc_graph.store import Store, Writer

EXIT_OK, EXIT_NONCONFORMING, EXIT_BAD_INPUT = 0, 1, 2
EXIT_INTERRUPTED = 130  # 128 + SIGINT, what shells report for Ctrl-C

#: Characters shown escaped where line breaks are kept: every control but a line feed and the
#: carriage return of a CR LF (CSV ends its lines so); a lone CR would overwrite the line.
_UNSAFE_IN_TEXT = re.compile(f"(?!\r\n)[{CONTROLS}]")
#: ... and where one value must stay on one line (a table cell): line breaks too.
_UNSAFE_IN_LINE = re.compile(f"[{CONTROLS}\n]")


def terminal_safe(text: str, newlines: bool = True, uchar: bool = False) -> str:
    """``text`` as a terminal must receive it: each character a terminal would act on (C0 and C1
    controls but tab, ESC among them, DEL, the bidirectional overrides such as U+202E) written as a
    visible escape, ``\\x1b`` or ``\\u202e``; everything else as it is.

    ``newlines``: keep line breaks (``\\n`` and ``\\r\\n``); else they are escaped too, for a
    value that must stay on its line. ``uchar``: write ``\\u001b``, the escape of JSON, Turtle and
    N-Triples strings, so such a document stays valid and means the same to a reader (where these
    formats allow such characters at all, it is inside strings).
    """
    pattern = _UNSAFE_IN_TEXT if newlines else _UNSAFE_IN_LINE
    return pattern.sub(lambda m: escaped(m.group(), uchar), text)


def safe_cell(text: str) -> str:
    """One value of a table or report for a terminal: :func:`terminal_safe`, line breaks escaped."""
    return terminal_safe(text, newlines=False)


def is_terminal(stream: IO[Any] | Any) -> bool:
    """Whether ``stream`` is a terminal (a closed or unusual stream counts as not one)."""
    try:
        return bool(stream.isatty())
    except (AttributeError, ValueError, OSError):
        return False


#: Other names of the formats, accepted by every --format (any case): one name per format across
#: commands, whatever a user remembers (validate's ``turtle`` is export's ``ttl``).
FORMAT_ALIASES = {"turtle": "ttl", "ntriples": "nt", "n-triples": "nt", "nquads": "nq", "n-quads": "nq",
                  "json-ld": "jsonld", "markdown": "md", "txt": "text"}


def format_choice(names: Iterable[str]) -> click.Choice[str]:
    """A --format choice of ``names`` that takes them in any case and by their other names
    (:data:`FORMAT_ALIASES`); the command gets the name it lists."""
    listed = list(names)

    class FormatChoice(click.Choice[str]):
        def convert(self, value: Any, param: click.Parameter | None, ctx: click.Context | None) -> str:
            text = str(value).lower()
            text = FORMAT_ALIASES.get(text, text)
            for name in listed:  # a command that lists the long name (validate: turtle) gets it
                if FORMAT_ALIASES.get(name, name) == text:
                    return name
            return str(super().convert(value, param, ctx))

    return FormatChoice(listed, case_sensitive=False)


def table_width() -> int | None:
    """The terminal's width for tables written to it (``$COLUMNS`` first); None into a pipe or a file."""
    import shutil

    if not is_terminal(sys.stdout):
        return None
    return shutil.get_terminal_size().columns


def write_out(data: str | bytes, uchar: bool = False) -> None:
    """Data (query results, an export, a report) on standard output: exact into a pipe or a file;
    on a terminal through :func:`terminal_safe` (``uchar`` for JSON and RDF syntaxes: still valid)."""
    if is_terminal(sys.stdout):
        text = data.decode("utf-8", "backslashreplace") if isinstance(data, bytes) else data
        data = terminal_safe(text, uchar=uchar)
    if isinstance(data, str):
        sys.stdout.write(data)
    else:
        sys.stdout.flush()
        sys.stdout.buffer.write(data)
    sys.stdout.flush()


def echo_json(document: Any) -> None:
    """A JSON document (the ``--format json`` outputs) on standard output, see :func:`write_out`."""
    write_out(json.dumps(document, indent=2) + "\n", uchar=True)


def _console(stderr: bool) -> Console:
    """A rich console that shows every text it renders through :func:`terminal_safe`: always on
    standard error, on standard output when that is a terminal.

    Rendering is the one place all of a console's text passes -- messages, table cells, progress
    descriptions, the status line -- after rich has laid it out and before it adds its own escape
    sequences (styles, cursor moves: the control segments, left as they are).
    """
    from rich.console import Console

    class SafeConsole(Console):
        def _render_buffer(self, buffer: Iterable[Segment]) -> str:
            if stderr or is_terminal(self.file):
                buffer = [s if s.control else s._replace(text=terminal_safe(s.text)) for s in buffer]
            return super()._render_buffer(buffer)

    return SafeConsole(stderr=stderr, highlight=False, soft_wrap=True)


class _LazyConsole:
    """A rich ``Console`` made on first use, standing in for it.

    Importing rich.console takes about 15 ms, a quarter of ``--help``, which
    prints through click; so the consoles are made when a command first prints.
    Attribute access and ``with`` (rich's live displays use it) go to the console.
    """

    def __init__(self, stderr: bool) -> None:
        self._stderr = stderr
        self._console: Console | None = None

    @property
    def console(self) -> Console:
        if self._console is None:
            self._console = _console(self._stderr)
        return self._console

    def __getattr__(self, name: str) -> Any:
        return getattr(self.console, name)

    def __enter__(self) -> Console:
        return self.console.__enter__()

    def __exit__(self, *exc_info: Any) -> None:
        self.console.__exit__(*exc_info)


out = cast("Console", _LazyConsole(stderr=False))
err = cast("Console", _LazyConsole(stderr=True))


def show_warnings() -> None:
    """Print stepnc-graph's own warnings (a stale compiled model, say) as ``warning: ...`` lines on
    stderr; other libraries' warnings (deprecations) stay with Python's handler and its filters."""
    from stepnc_graph.core.errors import StepncGraphWarning

    previous = warnings.showwarning

    def show(message: Warning | str, category: type[Warning], filename: str, lineno: int,
             file: Any = None, line: str | None = None) -> None:
        if issubclass(category, StepncGraphWarning):
            err.print(f"[yellow]warning:[/] {escape(str(message))}", markup=True, highlight=False)
        else:
            previous(message, category, filename, lineno, file, line)

    warnings.showwarning = show


def escape(text: str) -> str:
    """``text`` with rich markup escaped: file content must never be read as markup."""
    from rich.markup import escape as rich_escape

    return rich_escape(text)


class UsageProblem(StepncGraphError):
    """A request the command cannot carry out as given (exit 2)."""


def error_record(exc: BaseException) -> dict[str, Any]:
    """A JSON-ready view of an error: positioned errors give their own ``asdict()``."""
    if hasattr(exc, "asdict"):
        return exc.asdict()  # type: ignore[no-any-return]
    record: dict[str, Any] = {"type": type(exc).__name__, "message": error_text(exc)}
    if isinstance(exc, OSError) and exc.filename:
        record["file"] = str(exc.filename)
    return record


def error_text(exc: BaseException) -> str:
    """The one-line (or positioned, with a caret) text of an error for a person."""
    if isinstance(exc, OSError) and exc.strerror and exc.filename:
        return f"{exc.filename}: {exc.strerror}"
    return str(exc)


def print_error(exc: BaseException, hint: str = "") -> None:
    """``error: ...`` on standard error; file content in the message is never read as markup."""
    err.print(f"[bold red]error:[/] {escape(error_text(exc))}" + (f"\n[dim]{escape(hint)}[/]" if hint else ""))


def fail(errors: list[BaseException], fmt: str = "text") -> NoReturn:
    """Report input errors and exit 2."""
    if fmt == "json":
        echo_json({"ok": False, "errors": [error_record(e) for e in errors]})
    else:
        for e in errors:
            print_error(e)
    sys.exit(EXIT_BAD_INPUT)


def fail_input(exc: Exception, fmt: str = "text") -> NoReturn:
    """Report a positioned input error (or several, for SchemaErrors) and exit 2."""
    from stepnc_graph.schema import SchemaErrors

    fail(list(exc.errors) if isinstance(exc, SchemaErrors) else [exc], fmt)


def user_errors() -> tuple[type[BaseException], ...]:
    """The exceptions that mean bad input or usage, not a bug: the project's error root (every
    error it raises for a user derives from it) and what the operating system or a decoder says
    of an input file."""
    return (StepncGraphError, OSError, UnicodeError)



F = TypeVar("F", bound=Callable[..., Any])


def reports_errors(f: F) -> F:
    """Turn a user error raised by the command into one message and exit 2 (JSON with --format json)."""

    @functools.wraps(f)
    def wrapper(*args: Any, **kwargs: Any) -> Any:
        try:
            return f(*args, **kwargs)
        except user_errors() as exc:
            fmt = kwargs.get("fmt")
            fail([exc], "json" if fmt == "json" else "text")

    return wrapper  # type: ignore[return-value]


root_option = click.option(
    "--root", type=click.Path(file_okay=False, path_type=Path), default=None,
    help="Project root holding ontology/express/ (default: this checkout, or the installed data).")

store_option = click.option(
    "--store", "store_path", type=click.Path(path_type=Path), default=None,
    help="Store directory (default: $STEPNC_GRAPH_STORE, else ./.stepnc-graph).")
memory_option = click.option("--memory", is_flag=True, help="Use a throw-away in-memory store.")
wait_option = click.option(
    "--wait", is_flag=True,
    help="If another process is writing to the store, wait for it instead of failing (exit 2).")


def with_store(f: F) -> F:
    """``--store`` and ``--memory``: for commands that can work on a throw-away store."""
    return store_option(memory_option(f))


@dataclass(frozen=True)
class RemoteOptions:
    """``--endpoint`` and the URLs of servers that split query, update and graph store."""

    endpoint: str | None
    query_url: str | None
    update_url: str | None
    store_url: str | None
    timeout: float | None = None

    def wanted(self, store_path: Path | None, memory: bool) -> bool:
        """An endpoint was asked for (``$STEPNC_GRAPH_ENDPOINT`` counts unless --store or --memory is given)."""
        import os

        from stepnc_graph.store.remote import ENDPOINT_ENV

        given = bool(self.endpoint or self.query_url)
        if given and (store_path is not None or memory):
            raise UsageProblem("--endpoint and --store/--memory exclude each other")
        return given or (store_path is None and not memory and bool(os.environ.get(ENDPOINT_ENV)))

    def open(self) -> Store:
        from stepnc_graph.store.remote import open_remote

        return open_remote(self.endpoint, self.query_url, self.update_url, self.store_url, self.timeout)


def with_endpoint(f: F) -> F:
    """``--endpoint URL`` (or ``$STEPNC_GRAPH_ENDPOINT``): a remote SPARQL 1.1 store instead of
    ``--store``; the options arrive as one ``remote`` argument."""

    @functools.wraps(f)
    def wrapper(*args: Any, endpoint: str | None, query_url: str | None, update_url: str | None,
                store_url: str | None, endpoint_timeout: float | None, **kwargs: Any) -> Any:
        return f(*args, remote=RemoteOptions(endpoint, query_url, update_url, store_url, endpoint_timeout), **kwargs)

    options = [
        click.option("--endpoint", default=None, metavar="URL",
                     help="A SPARQL 1.1 store to use instead of --store (default: $STEPNC_GRAPH_ENDPOINT): "
                          "URL/query, URL/update and URL/store (Oxigraph's layout) unless given below. "
                          "Credentials: $STEPNC_GRAPH_ENDPOINT_TOKEN, or _USER and _PASSWORD."),
        click.option("--query-url", default=None, metavar="URL", help="The SPARQL query endpoint, if not URL/query."),
        click.option("--update-url", default=None, metavar="URL",
                     help="The SPARQL update endpoint, if not URL/update."),
        click.option("--store-url", default=None, metavar="URL",
                     help="The Graph Store Protocol endpoint, if not URL/store."),
        click.option("--timeout", "endpoint_timeout", default=None, type=click.FloatRange(min=0, min_open=True),
                     metavar="SECONDS", help="Seconds to wait for the endpoint's answer to one request (default: "
                                             "$STEPNC_GRAPH_TIMEOUT, else 120). A write that times out is not "
                                             "sent again."),
    ]
    for option in reversed(options):
        wrapper = option(wrapper)
    return wrapper  # type: ignore[return-value]


def open_writer(store_path: Path | None, memory: bool = False, wait: bool = False,
                remote: RemoteOptions | None = None, create: bool = True) -> Store:
    """The store, opened for writing at once (created if need be and ``create``: only `load`
    creates): the writer's lock is taken before anything is read; busy: exit 2, or wait with a note."""
    from stepnc_graph.api import open_store

    if remote is not None and remote.wanted(store_path, memory):
        return remote.open()

    def waiting(writer: Writer) -> None:
        err.print(f"waiting for the store's writer ({escape(str(writer))}) to finish ...")

    return open_store(store_path, memory, readonly=False, wait=wait, on_wait=waiting, create=create)


def open_reader(store_path: Path | None, remote: RemoteOptions | None = None) -> Store:
    """The store's last published state, read-only; never created, never waits for a writer."""
    from stepnc_graph.api import open_store

    if remote is not None and remote.wanted(store_path, False):
        return remote.open()
    return open_store(store_path, readonly=True)


@contextmanager
def _safe_usage_errors() -> Iterator[None]:
    """Click's usage errors quote the command line (``Got unexpected extra argument (...)``): what
    click would print on standard error is printed through :func:`terminal_safe`, same exit code."""
    try:
        yield
    except click.ClickException as exc:
        shown = io.StringIO()
        exc.show(file=shown)
        sys.stderr.write(terminal_safe(shown.getvalue()))
        sys.stderr.flush()
        sys.exit(exc.exit_code)


class Group(click.Group):
    """The CLI's groups: Ctrl-C exits 130 (scripts read 1 as "non-conforming data"); usage errors
    show the command line's text escaped."""

    def make_context(self, info_name: str | None, args: list[str], parent: click.Context | None = None,
                     **extra: Any) -> click.Context:
        with _safe_usage_errors():
            return super().make_context(info_name, args, parent, **extra)

    def invoke(self, ctx: click.Context) -> Any:
        from stepnc_graph.core.errors import command_line

        try:
            with _safe_usage_errors(), command_line():
                return super().invoke(ctx)
        except KeyboardInterrupt:
            err.print("interrupted")
            sys.exit(EXIT_INTERRUPTED)


def pick_graph(store: Store, given: str) -> str:
    """The graph of ``store`` that ``--graph``/``unload`` ``given`` names: a graph's full IRI, or a
    unique end of one (a file name; see :mod:`stepnc_graph.graphs.names`). A miss or an ambiguous
    name is a UsageProblem that lists what it could mean."""
    from stepnc_graph.graphs.names import UnknownGraph, resolve_graph

    try:
        if store.has_graph(given):  # any graph by its IRI: a derived layer, the vocabulary graph too
            return given
    except ValueError:
        pass  # not an IRI: a file name
    try:
        return resolve_graph(given, store.all_graphs())
    except UnknownGraph as exc:
        raise UsageProblem(str(exc)) from None
