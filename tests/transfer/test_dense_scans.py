"""A denser scan than the family benchmark's is no licence for a confident wrong axis: the transfer of a lever,
whose model the whole leaf's stretched fit leaves a few per cent off the object's proportions, is refused or
placed within the bound, and its sigma covers its error."""

from __future__ import annotations

import pytest

from bench.cases.transfer_pairs import make_pair
from bench.transfer import run_family_pair


@pytest.mark.slow
def test_a_lever_scanned_four_times_as_densely_is_not_written_wrong() -> None:
    row = run_family_pair(make_pair("lever", 0, points=80_000))  # a development pair: 219 points of its protrusion
    assert row.refused or (row.ours.deg <= 3.0 and row.ours.mm <= 3.0)
    assert row.ours.mm < 3.0 * row.sigma.mm  # 5.2 mm off: the pairs' scatter alone says 0.7 mm
