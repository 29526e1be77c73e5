"""The W3C SHACL test suite (vendored in tests/w3c-shacl): every approved test, as pySHACL runs it.

A test passes when stepnc-graph's report has the expected ``sh:conforms`` and the same results
(focus node, path, severity, component, source shape, value; blank nodes by structure), or, for
an ``sht:Failure`` test, when the engine refuses the shapes graph as SHACL requires. A test the
engine cannot pass must be an exact refusal listed in :data:`REFUSED` (and in docs/validation.md),
never a silent wrong answer.
"""

from __future__ import annotations

import pytest

from w3c_shacl import PENDING, Case, cases, run_case

#: tests the engine refuses (UnsupportedShapes), with the reason its message gives: none today
REFUSED: dict[str, str] = {}

CASES = cases()


def test_the_whole_approved_suite_is_here() -> None:
    """120 approved tests: 98 SHACL Core, 22 SHACL-SPARQL (the suite's README)."""
    assert len(CASES) == 120
    assert sum(c.name.startswith("core/") for c in CASES) == 98
    assert sum(c.failure for c in CASES) == 7


@pytest.mark.parametrize("case", CASES, ids=lambda c: c.name)
def test_w3c_case(case: Case) -> None:
    if case.name in PENDING:
        pytest.skip(PENDING[case.name])
    outcome = run_case(case)
    if case.name in REFUSED:
        assert outcome.status == "refused" and REFUSED[case.name] in outcome.detail, outcome.detail
        return
    assert outcome.status == "pass", outcome.detail
