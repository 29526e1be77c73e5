"""The vocabulary as Python: the generated term namespaces, the p21 terms, EXPRESS types as RDF values.

``STEPNC`` and ``P21`` (rdflib ``DefinedNamespace`` classes of :mod:`.terms`, generated) are
imported on first use: rdflib costs a tenth of a second, and loading a program never needs it::

    from stepnc_graph.vocabulary import STEPNC
    STEPNC["machining_operation.its_tool"]      # a typo raises AttributeError
"""

from __future__ import annotations

from typing import TYPE_CHECKING, Any

if TYPE_CHECKING:
    from stepnc_graph.vocabulary.terms import P21, STEPNC

__all__ = ["P21", "STEPNC"]


def __getattr__(name: str) -> Any:
    if name in __all__:
        from stepnc_graph.vocabulary import terms

        return getattr(terms, name)
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")
