"""Errors of the EXPRESS front end."""

from __future__ import annotations

from stepnc_graph.core.errors import PositionedSyntaxError


class ExpressSyntaxError(PositionedSyntaxError):
    """An EXPRESS schema text that does not parse."""
