"""One object planned as ``bench/grasp.py`` plans a row (``tests.grasp.cases.bench``), with its hold test on the
object's exact shapes (shared by the tests that pin an object the planner once failed)."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy.spatial.transform import Rotation

from schemas.descriptor import Grasp
from tasks.arrays import FloatArray
from tasks.grasp.api import plan_on_model
from tasks.grasp.execution import grasp_from_candidate
from tasks.grasp.shake import shake_test
from tests.grasp.cases.bench import row_setup, seed_cases
from tests.grasp.cases.grasp import Case, scene_cases


@dataclass(frozen=True)
class PlannedObject:
    """The planned grasp, the demonstrated palm's approach (unit, world) and position (m, world), and whether the
    grasp holds the object's exact shapes under the benchmark's hold program for that row."""

    grasp: Grasp
    approach: FloatArray
    seed_pos: FloatArray
    holds: bool


def plan_bench_scene(seed: int, name: str) -> PlannedObject:
    """The scene instance ``name`` (``"microwave seed 1"``: one of the twelve of scene seeds 0-2) planned with
    benchmark seed ``seed``, its row number its place among those twelve (the benchmark itself draws one scene seed
    per benchmark seed)."""
    cases = scene_cases(range(3))
    row = next(i for i, c in enumerate(cases) if c.name == name)
    return _planned(cases[row], seed, row)


def plan_bench_family(seed: int, name: str) -> PlannedObject:
    """The object ``name`` of ``bench/grasp.py``'s seed ``seed``, in its row there."""
    row, case = next((i, c) for i, (_, c) in enumerate(seed_cases(seed)) if c.name == name)
    return _planned(case, seed, row)


def _planned(case: Case, seed: int, row: int) -> PlannedObject:
    """``case`` planned as row ``row`` of benchmark seed ``seed``, and its hold test there."""
    model, exact, program = row_setup(case, seed, row)
    grasp = grasp_from_candidate(plan_on_model(model, case.seed_pos, case.seed_quat, np.random.default_rng(seed)))
    approach = Rotation.from_quat(case.seed_quat).as_matrix()[:, 2]
    holds = shake_test(exact, grasp, program).holds
    return PlannedObject(grasp, approach, np.asarray(case.seed_pos, dtype=np.float64), holds)
