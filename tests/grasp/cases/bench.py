"""What ``bench/grasp.py`` draws and sets up: the objects of one benchmark seed in their rows, and a row's model,
exact shapes and hold program. The benchmark and the tests that pin one of its objects both use these, so a
pinned object is the benchmark's own."""

from __future__ import annotations

import numpy as np
from scipy.spatial.transform import Rotation

from tasks.grasp.api import part_near
from tasks.grasp.object_model import ObjectModel, build_object_model
from tasks.grasp.shake import ShakeParams
from tests.grasp.cases.families import family_cases
from tests.grasp.cases.grasp import Case, hold_program, random_cases, scene_cases

SCENE_SEEDS = 1
RANDOMISED = 15
FAMILY_OBJECTS = 15
"""Per benchmark seed: instances of each of the four scenes, randomised objects, family objects (34 objects)."""


def seed_cases(seed: int, quick: bool = False) -> list[tuple[str, Case]]:
    """The objects of one benchmark seed in row order, each with its kind, all drawn from ``seed``."""
    rng = np.random.default_rng(seed)
    scene_seeds = [int(s) for s in rng.integers(0, 1000, SCENE_SEEDS)]
    scenes = scene_cases(scene_seeds)  # type: ignore[arg-type]
    randomised = random_cases(6 if quick else RANDOMISED, rng)
    families = family_cases(10 if quick else FAMILY_OBJECTS, rng)
    return [("scene", c) for c in scenes] + [("randomised", c) for c in randomised] + [("family", c) for c in families]


def row_setup(case: Case, seed: int, row: int) -> tuple[ObjectModel, ObjectModel, ShakeParams]:
    """Row ``row`` of benchmark seed ``seed``: the planner's model of the part near the demonstrated palm, the
    object's exact shapes and the row's hold program (each from a generator of its own)."""
    part = part_near(case.points, case.seed_pos)
    approach = Rotation.from_quat(case.seed_quat).as_matrix()[:, 2]
    model = build_object_model(part, np.random.default_rng(seed), viewpoint=case.seed_pos, approach=approach)
    truth = case.truth(np.random.default_rng([seed, 3, row]))
    return model, truth, hold_program(np.random.default_rng([seed, 2, row]))
