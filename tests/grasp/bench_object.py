"""One of ``bench/grasp.py``'s randomised objects planned as the benchmark plans it, with its exact model and hold
program (shared by the tests that pin a benchmark object the planner once failed)."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy.spatial.transform import Rotation

from schemas.descriptor import Grasp
from tasks.arrays import FloatArray
from tasks.grasp.api import part_near, plan_on_model
from tasks.grasp.execution import grasp_from_candidate
from tasks.grasp.object_model import build_object_model
from tasks.grasp.shake import shake_test
from tests.grasp.cases.families import family_cases
from tests.grasp.cases.grasp import Case, hold_program, random_cases, scene_cases

SCENE_ROWS = 12
"""The benchmark's rows before its randomised objects: three seeds of each of the four scenes."""


@dataclass(frozen=True)
class PlannedObject:
    """The planned grasp, the demonstrated palm's approach (unit, world) and position (m, world), and whether the
    grasp holds the object's exact shapes under the benchmark's hold program for that row."""

    grasp: Grasp
    approach: FloatArray
    seed_pos: FloatArray
    holds: bool


def plan_bench_object(seed: int, name: str) -> PlannedObject:
    """Plan the benchmark's randomised object ``name`` of benchmark seed ``seed`` (21 objects) as ``bench/grasp.py``
    does and shake the grasp on its exact shapes with the row's program."""
    cases = random_cases(21, np.random.default_rng(seed))
    index = next(i for i, c in enumerate(cases) if c.name == name)
    return _planned(cases[index], seed, SCENE_ROWS + index)


def plan_bench_scene(seed: int, name: str) -> PlannedObject:
    """Plan the benchmark's scene instance ``name`` (``"microwave seed 1"``: scene seeds 0-2) as ``bench/grasp.py``
    does with benchmark seed ``seed`` and shake the grasp on its exact shapes with the row's program."""
    cases = scene_cases(range(SCENE_ROWS // 4))
    row = next(i for i, c in enumerate(cases) if c.name == name)
    return _planned(cases[row], seed, row)


def plan_bench_family(seed: int, name: str) -> PlannedObject:
    """Plan the family object ``name`` of ``bench/grasp.py``'s seed ``seed`` as it does (one scene seed, 15 randomised
    and 15 family objects drawn in turn from one generator) and shake the grasp on its exact shapes with its program."""
    rng = np.random.default_rng(seed)
    rng.integers(0, 1000, 1)  # the scene seed: four scene rows
    randomised = random_cases(15, rng)
    cases = family_cases(15, rng)
    index = next(i for i, c in enumerate(cases) if c.name == name)
    return _planned(cases[index], seed, 4 + len(randomised) + index)


def _planned(case: Case, seed: int, row: int) -> PlannedObject:
    """``case`` planned as ``bench/grasp.py``'s run for ``seed`` plans its row ``row``, and its hold test there."""
    part = part_near(case.points, case.seed_pos)
    approach = Rotation.from_quat(case.seed_quat).as_matrix()[:, 2]
    model = build_object_model(part, np.random.default_rng(seed), viewpoint=case.seed_pos, approach=approach)
    grasp = grasp_from_candidate(plan_on_model(model, case.seed_pos, case.seed_quat, np.random.default_rng(seed)))
    exact = case.truth(np.random.default_rng([seed, 3, row]))
    holds = shake_test(exact, grasp, hold_program(np.random.default_rng([seed, 2, row]))).holds
    return PlannedObject(grasp, approach, np.asarray(case.seed_pos, dtype=np.float64), holds)
