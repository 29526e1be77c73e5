"""Reading an embedded Oxigraph database: the read calls of the store contract, shared by the store
on disk and the one in memory (:mod:`.embedded`). Every call goes through :attr:`OxigraphReads._db`,
which refuses use of a closed store, or of one whose rollback could not reopen its database."""

from __future__ import annotations

from collections.abc import Iterator
from pathlib import Path
from typing import TYPE_CHECKING, Any

import pyoxigraph as ox

from stepnc_graph.core.naming import STAGING
from stepnc_graph.store.batches import count_in
from stepnc_graph.store.errors import StoreError
from stepnc_graph.store.kept_graph import graph_from_kept

if TYPE_CHECKING:
    from stepnc_graph.store.kept import KeptTexts
    from stepnc_graph.store.transaction import Transaction


class OxigraphReads:
    """The reads of an Oxigraph database held in ``_store`` (None: closed, for ``_closed_because``)."""

    _store: ox.Store | None
    _closed_because: str | None
    _tx: Transaction
    _kept: KeptTexts

    @property
    def _db(self) -> ox.Store:
        if self._store is None:
            raise StoreError(self._closed_because or "the store is closed")
        return self._store

    @property
    def server(self) -> None:
        """None: the embedded Oxigraph database answers (see :meth:`Store.server`)."""
        return None

    def all_graphs(self) -> list[str]:
        """Every named graph but staging ones: with the vocabulary and the derived layers."""
        return sorted(g.value for g in self._db.named_graphs()
                      if isinstance(g, ox.NamedNode) and not g.value.startswith(STAGING))

    def has_graph(self, graph: str) -> bool:
        return self._db.contains_named_graph(ox.NamedNode(graph))

    def query(self, sparql: str, **kwargs: Any) -> Any:
        return self._db.query(sparql, **kwargs)

    def count(self, graph: str | None = None) -> int:
        """Quads in ``graph`` (all quads for None), counted by Oxigraph."""
        return len(self._db) if graph is None else count_in(self._db, graph)

    def quads(self, graph: str | None = None) -> Iterator[ox.Quad]:
        return iter(self._db.quads_for_pattern(None, None, None, ox.NamedNode(graph) if graph else None))

    def quads_for_pattern(self, subject: Any, predicate: Any, obj: Any, graph: Any = None) -> Iterator[ox.Quad]:
        """Oxigraph's ``quads_for_pattern``, for readers (unlike :attr:`oxigraph`, it keeps the
        kept texts of a writer valid)."""
        return iter(self._db.quads_for_pattern(subject, predicate, obj, graph))

    def kept_text(self, graph: str, path: Path, store_labels: bool = True) -> bool:
        """Write ``graph`` to ``path`` as N-Triples from the text its last load kept, when the store
        kept one that describes the graph as it is read now (:func:`~stepnc_graph.store.kept_graph.graph_from_kept`:
        a fraction of a dump's cost); False, and nothing to use, when it did not (in memory, after
        a write outside a load, a damaged file)."""
        kept = self._tx.readable_kept().get(graph)
        return kept is not None and graph_from_kept(self._db, graph, self._kept.path(kept), kept.lines, path,
                                                    store_labels)

    def dump(self, fmt: ox.RdfFormat, graph: str | None = None, prefixes: dict[str, str] | None = None) -> bytes:
        kwargs: dict[str, Any] = {}
        if graph is not None:
            kwargs["from_graph"] = ox.NamedNode(graph)
        if prefixes and fmt in (ox.RdfFormat.TURTLE, ox.RdfFormat.TRIG):
            kwargs["prefixes"] = prefixes
        out = self._db.dump(None, fmt, **kwargs)
        return out if out is not None else b""

    @property
    def oxigraph(self) -> ox.Store:
        """The underlying pyoxigraph store (the embedded stores say what writes through it mean)."""
        return self._db

    def rdflib_dataset(self) -> Any:
        """An rdflib ``Dataset`` over the same data (oxrdflib), for rdflib/pySHACL users."""
        import rdflib
        from oxrdflib.store import OxigraphStore

        return rdflib.Dataset(store=OxigraphStore(store=self.oxigraph))
