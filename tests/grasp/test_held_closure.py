"""The planner's last resort before a grasp that does not hold (``hold_budget.held_closure``): a grasp that held
under the hold check without a force closure at the planner's friction, judged at the check's own contact friction
(``hold_budget.HELD_MU``), its qualities recorded with that friction."""

from __future__ import annotations

import math

import numpy as np
import pytest

from tasks.grasp.candidate_grasp import grasp_from_candidate
from tasks.grasp.hold_budget import HELD_MU, held_closure
from tasks.grasp.quality import DEFAULT_MU
from tests.grasp.bench_object import plan_bench_object
from tests.grasp.lying_cylinder import closed_above, lying_cylinder


def test_held_closure_records_the_friction_it_was_found_at() -> None:
    cylinder = lying_cylinder()
    cand = closed_above(cylinder, 0.01)  # no static force closure; squeezed, one at the planner's friction
    assert not cand.quality.force_closure and cand.quality.mu == DEFAULT_MU
    found = held_closure([cand], cylinder)
    assert found is not None and found.quality.force_closure
    assert found.quality.mu == HELD_MU
    assert grasp_from_candidate(found).quality["mu"] == HELD_MU
    np.testing.assert_array_equal(found.position, cand.position)  # the pose the hold check tested
    assert held_closure([closed_above(cylinder, 0.15)], cylinder) is None  # the fingers close on nothing


@pytest.mark.slow
def test_benchmark_cylinder_held_only_without_closure_at_the_planners_friction() -> None:
    """The benchmark's upright cylinder r20 (seed 7): of its near grasps the one that holds under the planner's
    check has no force closure at 0.5, even squeezed; at the check's friction it has one, and it holds the exact
    cylinder under the benchmark's test."""
    planned = plan_bench_object(7, "cylinder r20 h168mm upright")
    grasp = planned.grasp
    assert grasp.quality["force_closure"] is True and grasp.quality["mu"] == HELD_MU
    assert grasp.quality["epsilon"] > 0.0
    assert math.degrees(grasp.quality["demo_angle_rad"]) == pytest.approx(15.0, abs=0.5)
    assert planned.holds
