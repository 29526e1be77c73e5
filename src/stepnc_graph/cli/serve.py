"""`stepnc-graph serve`: the store as a SPARQL 1.1 endpoint (Oxigraph's own server)."""

from __future__ import annotations

from pathlib import Path

import click

from stepnc_graph.cli.common import err, escape, out, reports_errors, store_option


@click.command("serve")
@store_option
@click.option("--host", default="127.0.0.1", show_default=True,
              help="Interface to listen on. Anything but loopback exposes the store to the network: it must be "
                   "asked for, and a warning is printed.")
@click.option("--port", default=7878, show_default=True, type=click.IntRange(0, 65535), help="0: any free port.")
@click.option("--writable", is_flag=True,
              help="Accept SPARQL Update and Graph Store writes (holds the store's writer lock; changes are "
                   "published when serve stops). Prints a warning.")
@click.option("--timeout", default=60, show_default=True, type=click.IntRange(1), help="Query timeout, seconds.")
@click.option("--max-bytes", default=100 << 20, show_default=True, type=click.IntRange(1),
              help="Refuse (507) a result larger than this.")
@click.option("--max-request-bytes", default=16 << 20, show_default=True, type=click.IntRange(1),
              help="Refuse (413) a request whose body is larger than this.")
@click.option("--union-default-graph/--no-union-default-graph", default=True, show_default=True,
              help="A query without a dataset of its own (no FROM, no default-graph-uri) sees every graph as its "
                   "default graph, as `stepnc-graph query` runs the library: any library query sent as written "
                   "gets the rows `stepnc-graph query` gives. --no-union-default-graph: only the (empty) default "
                   "graph; then use GRAPH ?g { ... }.")
@click.option("--allow-service", is_flag=True,
              help="Run SERVICE clauses (and LOAD in updates): the server then sends requests to any URL a "
                   "client names. Refused (403) otherwise. Prints a warning.")
@click.option("--allow-host", "allow_hosts", multiple=True, metavar="NAME",
              help="A host name clients may use besides localhost and IP addresses, e.g. a reverse proxy's "
                   "(repeatable). Other names are refused (421) against DNS rebinding.")
@reports_errors
def serve_cmd(store_path: Path | None, host: str, port: int, writable: bool, timeout: int, max_bytes: int,
              max_request_bytes: int, union_default_graph: bool, allow_service: bool,
              allow_hosts: tuple[str, ...]) -> None:
    """Serve the store as a SPARQL 1.1 Protocol endpoint for other tools and browsers.

    Read-only and bound to 127.0.0.1 by default: queries at /query, graphs at
    /store?graph=IRI (Graph Store Protocol, GET), updates refused with 403.
    SERVICE is refused (403), and so are requests naming another host (421)
    or sent by another site's web page (403). A result is sent once it is
    complete: an error or the timeout is an error status, never a cut 200.
    New loads into the store are served as soon as they are published. Stop
    with Ctrl-C or SIGTERM; the store is left as it was.
    """
    from stepnc_graph.server.serve import Endpoint, is_loopback
    from stepnc_graph.store import default_store_path

    if not is_loopback(host):
        err.print(f"[yellow]warning:[/] listening on {escape(host)}: anyone who can reach it can read the store"
                  + (" and change it" if writable else ""))
    if writable:
        err.print("[yellow]warning:[/] --writable: SPARQL Update and Graph Store writes are accepted; loads wait "
                  "until serve stops")
    if allow_service:
        err.print("[yellow]warning:[/] --allow-service: SERVICE clauses make this server send requests to any URL "
                  "a client names")
    endpoint = Endpoint(store_path or default_store_path(), host, port, writable=writable, timeout=timeout,
                        max_bytes=max_bytes, union_default_graph=union_default_graph,
                        max_request_bytes=max_request_bytes, allow_service=allow_service, allow_hosts=allow_hosts)
    endpoint.start()
    out.print(f"serving {escape(str(endpoint.store.resolve()))} at {endpoint.url}/query "
              f"({'read-write' if writable else 'read-only'}; Ctrl-C stops)", highlight=False)
    endpoint.serve_forever()
