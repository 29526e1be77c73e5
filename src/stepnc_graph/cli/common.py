"""What every command module shares: consoles, exit codes, error output, store options.

The CLI is the only part of stepnc-graph that prints. Each command group is a
module of this package that calls the Python API; this module holds the few
pieces they all need, so the commands stay thin and print errors alike.
"""

from __future__ import annotations

import json
import sys
import warnings
from collections.abc import Callable
from pathlib import Path
from typing import TYPE_CHECKING, Any, NoReturn, TypeVar, cast

import click

if TYPE_CHECKING:
    from rich.console import Console

    from stepnc_graph.store import GraphStore

EXIT_OK, EXIT_NONCONFORMING, EXIT_BAD_INPUT = 0, 1, 2


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
            from rich.console import Console

            self._console = Console(stderr=self._stderr, highlight=False, soft_wrap=True)
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
    """Print Python warnings (a stale compiled model, say) as ``warning: ...`` lines on stderr."""

    def show(message: Warning | str, category: type[Warning], filename: str, lineno: int,
             file: Any = None, line: str | None = None) -> None:
        err.print(f"[yellow]warning:[/] {message}", markup=True, highlight=False)

    warnings.showwarning = show


def fail_input(exc: Exception, fmt: str = "text") -> NoReturn:
    """Report a positioned input error (or several) and exit 2."""
    from stepnc_graph.schema import SchemaErrors

    errors = exc.errors if isinstance(exc, SchemaErrors) else [exc]
    if fmt == "json":
        click.echo(json.dumps({"ok": False, "errors": [e.asdict() for e in errors]}, indent=2))  # type: ignore[attr-defined]
    else:
        err.print(f"[bold red]error:[/] {exc}", markup=True)
    sys.exit(EXIT_BAD_INPUT)


root_option = click.option(
    "--root", type=click.Path(file_okay=False, path_type=Path), default=None,
    help="Project root holding ontology/express/ (default: this checkout, or the installed data).")

_store_options = [
    click.option("--store", "store_path", type=click.Path(file_okay=False, path_type=Path), default=None,
                  help="Store directory (default: $STEPNC_GRAPH_STORE, else ./.stepnc-graph)."),
    click.option("--memory", is_flag=True, help="Use a throw-away in-memory store."),
]

F = TypeVar("F", bound=Callable[..., Any])


def with_store(f: F) -> F:
    """Add the --store / --memory options every store command shares."""
    for option in reversed(_store_options):
        f = option(f)
    return f


def open_store(store_path: Path | None, memory: bool) -> GraphStore:
    """The store the options name; a store that cannot be opened exits 2 with a message."""
    from stepnc_graph.api import open_store as api_open_store
    from stepnc_graph.store import StoreError

    try:
        return api_open_store(store_path, memory)
    except StoreError as exc:
        err.print(f"[bold red]error:[/] {exc}")
        sys.exit(EXIT_BAD_INPUT)
