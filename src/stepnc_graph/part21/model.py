"""What the Part 21 reader yields: instances, text it could not read, the HEADER and the
sections before the DATA (:mod:`stepnc_graph.part21.reader` reads them)."""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any


@dataclass(slots=True)
class Instance:
    """One entity instance: ``#id = NAME(params);`` or a complex ``#id = (A(..) B(..));``.

    ``name`` is upper-case; for complex instances it is None and ``parts``
    holds ``(NAME, params)`` per partial entity, in file order.
    ``start``/``end`` are offsets of the instance's text in the file.
    """

    id: int
    name: str | None
    params: list[Any]
    line: int
    column: int
    start: int
    end: int
    parts: list[tuple[str, list[Any]]] | None = None
    section: int = 0  # which DATA section (0-based) holds the instance
    #: lenient mode: the syntax error of an instance that could not be read.
    #: Such an instance has no parameters; its text (``start:end``) is kept.
    unreadable: str | None = None
    #: lenient mode: the reader repaired the instance's text (a missing ';', a
    #: typographic quote, a bare enumeration), so ``start:end`` is not valid Part 21
    repaired: bool = False

    @property
    def names(self) -> list[str]:
        return [self.name] if self.name is not None else [n for n, _ in self.parts or ()]


@dataclass(frozen=True, slots=True)
class UnreadableText:
    """Lenient mode: text that is no instance the reader could name -- an instance whose
    ``#id`` is damaged (``#=A(1);``), junk between instances or sections, text after
    ``END-ISO-10303-21;`` -- kept (``start:end`` of the file) so that nothing is lost."""

    start: int
    end: int
    line: int
    column: int
    section: int  # the DATA section (0-based) it is in or follows
    reason: str  # the syntax error, as reported


@dataclass
class Header:
    """The HEADER section: every entity by upper-case name (FILE_DESCRIPTION, FILE_NAME, ...)."""

    entities: dict[str, list[Any]] = field(default_factory=dict)
    data_sections: list[list[Any]] = field(default_factory=list)
    text: str = ""  # the section verbatim, from HEADER to ENDSEC;
    #: edition 3: the DATA section openers verbatim (``DATA;``, ``DATA('a',('S'));``)
    data_section_texts: list[str] = field(default_factory=list)
    #: lenient mode repaired the opener's parameters (a bare schema name): its text is not valid
    #: Part 21, :func:`stepnc_graph.part21.format.format_value` of ``data_sections`` is
    data_section_repaired: list[bool] = field(default_factory=list)
    #: edition 3: anchors (name without <>, instance id) that name an instance
    anchors: list[tuple[str, int]] = field(default_factory=list)
    anchor_text: str = ""  # the ANCHOR section verbatim ("" when absent)
    #: edition 3: REFERENCE entries (``#12`` or ``@12``, URI without <>)
    references: list[tuple[str, str]] = field(default_factory=list)
    reference_text: str = ""  # the REFERENCE section verbatim
    signatures: list[str] = field(default_factory=list)  # SIGNATURE sections verbatim
    #: lenient mode repaired the HEADER (a bare enumeration, a typographic quote): ``text``
    #: is not valid Part 21, :func:`stepnc_graph.part21.format.format_header` of it is
    repaired: bool = False

    @property
    def schemas(self) -> list[str]:
        """FILE_SCHEMA's schema names, upper-case."""
        params = self.entities.get("FILE_SCHEMA")
        if not params or not isinstance(params[0], list):
            return []
        return [str(s).upper() for s in params[0] if isinstance(s, str)]
