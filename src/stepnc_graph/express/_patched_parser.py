"""A narrow fix of the `express-schema` parser for two ISO 10303-11 constructs.

Why this exists (measured on the reference schemas, see ``bench/express_parse.py``):
`express-schema` 1.0.2 parses IFC4 and AP238 AIM but stops on

* the substring index ``SELF.name[1:8]`` (ISO 10303-11 12.5.3 / 12.6.1 index
  qualifier with two indices) -- AP203e2 MIM, and
* a group reference used on its own, ``USEDIN(SELF\\presentation_area, '')``
  (ISO 10303-11 12.7.4) -- AP214e3.

Both live in the postfix loop of one private method. We subclass the library's
parser and override that method; the body below is the library's own code
(MIT licence, Copyright (c) Marko Ristin) with the two branches marked
``CHANGED (stepnc-graph)``. Everything else -- lexer, statements, declarations --
is the library's. The dependency is pinned below 1.1 because this touches a
private class; ``tests/test_express_parser.py`` fails loudly if it drifts.
"""

# mypy: ignore-errors
# ruff: noqa

from __future__ import annotations

import copy
from typing import Final, Optional

import express_schema.lex as lex
import express_schema.parse as _ep


class IndexRangeExpr(_ep.Node):
    """``source[index_1 : index_2]``: a substring or sub-aggregate."""

    source: Final[_ep.Expr]
    index_1: Final[_ep.Expr]
    index_2: Final[_ep.Expr]

    def __init__(self, position: lex.Position, source, index_1, index_2) -> None:
        super().__init__(position)
        self.source = source
        self.index_1 = index_1
        self.index_2 = index_2


class GroupRef(_ep.Node):
    """``source\\entity`` on its own: the partial entity value of a supertype."""

    source: Final[_ep.Expr]
    group_qualifier: Final[lex.Identifier]

    def __init__(self, position: lex.Position, source, group_qualifier) -> None:
        super().__init__(position)
        self.source = source
        self.group_qualifier = group_qualifier


class PatchedParser(_ep._Parser):
    """The library parser with the two postfix fixes described above."""

    @_ep._affect_parsing_stack
    @_ep._ensure_parse_result_coincides_with_last_parsed_token_and_errors
    def _parse_primary_or_unary(self) -> Optional[_ep.Expr]:
        if len(self.errors) > 0:
            return None

        result: _ep.Expr

        if (token := self._peek_in_kind_set(_ep._Parser._UNARY_OP_KIND_SET)) is not None:
            position = _ep._Parser._position_from_token(token)
            self._tape.move_by(1)

            operand = self._parse_primary_or_unary()
            if operand is None:
                return None

            result = _ep.UnaryExpr(
                position=position,
                op=_ep._Parser._UNARY_OP_FROM_KIND[token.kind],
                operand=operand,
            )

        elif self._peek_kind(lex.TokenKind.LPAR) is not None:
            self._tape.move_by(1)

            expr = self._parse_expr()
            if expr is None:
                return None

            result = expr

            token = self._nibble_kind(lex.TokenKind.RPAR)
            if token is None:
                return None

            self._last_parsed_token = token

        elif self._peek_kind(lex.TokenKind.LSQ) is not None:
            aggregate_literal = self._parse_aggregate_literal()
            if aggregate_literal is None:
                return None

            result = aggregate_literal

        elif (token := self._peek_kind(lex.TokenKind.LCRLY)) is not None:
            position = _ep._Parser._position_from_token(token)

            self._tape.move_by(1)

            # NOTE (mristin):
            # We explicitly disallow binding of relational operators.
            relational_precedence, relational_associativity = (
                _ep._Parser._BINARY_PRECEDENCE_MAP[lex.TokenKind.LT]
            )
            assert relational_associativity is _ep._Associativity.NONASSOCIATIVE

            above_relational_precedence = relational_precedence + 1

            left = self._parse_expr(min_precedence=above_relational_precedence)

            if left is None:
                return None

            token = self._nibble_in_kind_set(_ep._Parser._INTERVAL_OP_KIND_SET)
            if token is None:
                return None

            left_to_center = _ep._Parser._INTERVAL_OP_FROM_KIND[token.kind]

            center = self._parse_expr(min_precedence=above_relational_precedence)
            if center is None:
                return None

            token = self._nibble_in_kind_set(_ep._Parser._INTERVAL_OP_KIND_SET)
            if token is None:
                return None

            center_to_right = _ep._Parser._INTERVAL_OP_FROM_KIND[token.kind]

            right = self._parse_expr(min_precedence=above_relational_precedence)
            if right is None:
                return None

            token = self._nibble_kind(lex.TokenKind.RCRLY)
            if token is None:
                return None

            self._last_parsed_token = token

            result = _ep.Interval(
                position=position,
                left=left,
                left_to_center=left_to_center,
                center=center,
                center_to_right=center_to_right,
                right=right,
            )

        elif (token := self._peek_kind(lex.TokenKind.QUERY)) is not None:
            position = _ep._Parser._position_from_token(token)

            self._tape.move_by(1)

            if self._nibble_kind(lex.TokenKind.LPAR) is None:
                return None

            token = self._nibble_kind(lex.TokenKind.IDENTIFIER)
            if token is None:
                return None

            variable = lex.Identifier(token.text)

            if self._nibble_kind(lex.TokenKind.LT_STAR) is None:
                return None

            aggregate = self._parse_expr()
            if aggregate is None:
                return None

            if self._nibble_kind(lex.TokenKind.PIPE) is None:
                return None

            predicate = self._parse_expr()
            if predicate is None:
                return None

            token = self._nibble_kind(lex.TokenKind.RPAR)
            if token is None:
                return None

            self._last_parsed_token = token

            result = _ep.QueryExpr(
                position=position,
                variable=variable,
                aggregate=aggregate,
                predicate=predicate,
            )

        elif self._peek_in_kind_set(_ep._Parser._LITERAL_KIND_SET) is not None:
            literal = self._parse_literal()
            if literal is None:
                return None

            result = literal

        elif (token := self._peek_kind(lex.TokenKind.SELF)) is not None:
            self._tape.move_by(1)
            self._last_parsed_token = token

            result = _ep.Self(position=_ep._Parser._position_from_token(token))

        elif (token := self._peek_kind(lex.TokenKind.IDENTIFIER)) is not None:
            self._tape.move_by(1)
            self._last_parsed_token = token

            result = _ep.NameRef(
                position=_ep._Parser._position_from_token(token),
                identifier=lex.Identifier(token.text),
            )

        else:
            token = self._tape.token()
            if token is None:
                self._emit_error(
                    "Unexpected end of input when parsing a primary "
                    "or unary expression"
                )
            else:
                self._emit_error(
                    f"Unexpected token {token.kind.name!r} "
                    f"when parsing a primary or unary expression: {token.text!r}"
                )

            return None

        # NOTE (mristin):
        # We handle the postfix operators first since they have precedence over
        # any other binary operator.
        while True:
            if self._peek_kind(lex.TokenKind.LPAR) is not None:
                # This is a call as the postfix starts with a "(".

                args = self._parse_argument_list()
                if args is None:
                    return None

                assert (
                    self._last_parsed_token is not None
                    and self._last_parsed_token.kind is lex.TokenKind.RPAR
                )
                result = _ep.Call(position=result.position, callee=result, args=args)
            elif self._peek_kind(lex.TokenKind.LSQ) is not None:
                self._tape.move_by(1)

                # This is an index access as the postfix starts with a "[".
                index_expr = self._parse_expr()
                if index_expr is None:
                    return None

                # CHANGED (stepnc-graph): ISO 10303-11 12.6.1 allows a second
                # index, ``s[i:j]``; the library stops at the colon.
                upper_expr: Optional[_ep.Expr] = None
                if self._peek_kind(lex.TokenKind.COLON) is not None:
                    self._tape.move_by(1)
                    upper_expr = self._parse_expr()
                    if upper_expr is None:
                        return None

                token = self._nibble_kind(lex.TokenKind.RSQ)
                if token is None:
                    return None

                self._last_parsed_token = token
                if upper_expr is None:
                    result = _ep.IndexExpr(
                        position=result.position, source=result, index=index_expr
                    )
                else:
                    result = IndexRangeExpr(
                        position=result.position,
                        source=result,
                        index_1=index_expr,
                        index_2=upper_expr,
                    )

            elif self._peek_kind(lex.TokenKind.DOT) is not None:
                # This is an attribute reference.
                self._tape.move_by(1)

                attribute_token = self._nibble_kind(lex.TokenKind.IDENTIFIER)
                if attribute_token is None:
                    return None

                self._last_parsed_token = attribute_token
                result = _ep.AttributeRef(
                    position=copy.copy(result.position),
                    source=result,
                    identifier=lex.Identifier(attribute_token.text),
                )

            elif self._peek_kind(lex.TokenKind.BACKSLASH) is not None:
                # This is a cast as the postfix starts with a "\".
                self._tape.move_by(1)

                group_qualifier = self._nibble_kind(lex.TokenKind.IDENTIFIER)
                if group_qualifier is None:
                    return None

                # CHANGED (stepnc-graph): ISO 10303-11 12.7.4 allows a group
                # reference on its own (``SELF\\point``, passed to USEDIN or
                # TYPEOF); the library insisted on a following ``.attribute``.
                if self._peek_kind(lex.TokenKind.DOT) is None:
                    self._last_parsed_token = group_qualifier
                    result = GroupRef(
                        position=result.position,
                        source=result,
                        group_qualifier=lex.Identifier(group_qualifier.text),
                    )
                    continue
                self._tape.move_by(1)

                attribute_token = self._nibble_kind(lex.TokenKind.IDENTIFIER)
                if attribute_token is None:
                    return None

                self._last_parsed_token = attribute_token
                result = _ep.QualifiedAttributeRef(
                    position=result.position,
                    source=result,
                    group_qualifier=lex.Identifier(group_qualifier.text),
                    attribute=lex.Identifier(attribute_token.text),
                )

            else:
                break

        return result


def parse_tokens(tokens: "list[lex.Token]") -> "tuple[Optional[_ep.Schema], Optional[list[_ep.Error]]]":
    """Like ``express_schema.parse.parse_tokens`` but with :class:`PatchedParser`."""
    tokens = [t for t in tokens if t.kind is not lex.TokenKind.COMMENT]
    parser = PatchedParser(tape=_ep._TokenTape(tokens))
    schema = parser.parse_schema()
    if parser.errors:
        return None, list(parser.errors)
    return schema, None
