"""The mapper's N-Triples terms are written as Oxigraph writes them back.

A replacement (store.GraphStore) compares the text the loader wrote with lines the store
dumps; a term written in another form of the same value would make an unchanged line look
changed (deleted and inserted again: correct, but paid for).
"""

from __future__ import annotations

import pyoxigraph as ox
from hypothesis import given, strategies as st

from stepnc_graph.mapping import ntriples as T


def _written_back(obj: str) -> str:
    """The object term of a one-triple document after a round through an Oxigraph store."""
    store = ox.Store()
    store.load(f"<http://s> <http://p> {obj} .\n".encode(), ox.RdfFormat.N_TRIPLES)
    line = store.dump(format=ox.RdfFormat.N_TRIPLES, from_graph=ox.DefaultGraph()).decode()
    return line[len("<http://s> <http://p> "):-len(" .\n")]


@given(st.floats(allow_nan=False, allow_infinity=False))
def test_a_double_is_written_as_the_store_writes_it(value: float) -> None:
    assert _written_back(T.double(value)) == T.double(value)


def test_doubles_written_positionally() -> None:
    assert T.double(6.0) == f'"6"^^{T.T_DOUBLE}'
    assert T.double(-0.0) == f'"-0"^^{T.T_DOUBLE}'
    assert T.double(1e-7) == f'"0.0000001"^^{T.T_DOUBLE}'
    assert T.double(1.25e20) == f'"125000000000000000000"^^{T.T_DOUBLE}'
    assert T.double(float("inf")) == f'"INF"^^{T.T_DOUBLE}'
    # halfway between two shortest forms: away from zero, as Rust (Python's repr takes the even one)
    assert T.double(562949953421312.25) == f'"562949953421312.3"^^{T.T_DOUBLE}'
    assert T.double(-562949953421312.25) == f'"-562949953421312.3"^^{T.T_DOUBLE}'
    assert T.double(562949953421312.75) == f'"562949953421312.8"^^{T.T_DOUBLE}'
    assert T.double(0.25) == f'"0.25"^^{T.T_DOUBLE}'


@given(st.text())
def test_a_string_is_written_as_the_store_writes_it(value: str) -> None:
    assert _written_back(T.string(value)) == T.string(value)
