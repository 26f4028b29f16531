"""Benchmark the eigengrasp planner against closing the hand at the demonstrated pose (same run, same seeds).

Objects: the four paper-task parts (built-in scenes of tasks.scenes when available, otherwise proxies of the
same parts: microwave door handle, drawer handle, bottle cap, knob) and N randomised objects (boxes, cylinders,
handles on a plate). Each object gets a simulated demonstration seed: a palm pose 20..60 mm off the part,
facing it from above or from the side, with a random roll and ~10° of tilt noise. For each: plan (our figure)
and the baseline (open hand at the seed, approach up to 30 mm, close, no search); force closure, the shake
test, planning time.

    .venv/bin/python bench/grasp.py [--quick] [--objects N] [--seed S]
"""

from __future__ import annotations

import argparse
import math
import sys
import time
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import pybullet as pb
from scipy.spatial.transform import Rotation

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from schemas.descriptor import Grasp
from tasks.arrays import Points
from tasks.errors import GraspError
from tasks.grasp import barrett
from tasks.grasp.api import SHAKE_CHECKS, grasp_from_candidate, part_near, plan_on_model
from tasks.grasp.object_model import (
    ObjectModel,
    build_object_model,
    load_object,
    sample_box_surface,
    sample_cylinder_surface,
)
from tasks.grasp.planner import PlannerParams, evaluate_pose
from tasks.grasp.shake import shake_test


@dataclass
class Case:
    """One benchmark object: name, points (world, m), seed palm pose."""

    name: str
    points: Points
    seed_pos: np.ndarray
    seed_quat: np.ndarray


def _cyl(  # noqa: PLR0917 -- small sampling helper
    r: float, hh: float, n: int, rng: np.random.Generator, rot: Rotation, at: np.ndarray
) -> Points:
    pts, _ = sample_cylinder_surface(r, hh, n, rng)
    return rot.apply(pts) + at


def _box(half: list[float], n: int, rng: np.random.Generator, at: np.ndarray) -> Points:
    pts, _ = sample_box_surface(np.array(half), n, rng)
    return pts + at


def handle_on_plate(
    radius: float, length: float, standoff: float, vertical: bool, rng: np.random.Generator
) -> tuple[Points, np.ndarray]:
    """A bar handle (along z or x) standing ``standoff`` m in front (-y) of a 10 mm plate; returns points and the
    bar centre."""
    centre = np.array([0.5, 0.0, 0.5])
    axis_rot = Rotation.identity() if vertical else Rotation.from_euler("y", 90, degrees=True)
    bar = _cyl(radius, length / 2, 1500, rng, axis_rot, centre)
    post_rot = Rotation.from_euler("x", 90, degrees=True)
    ends = [centre + axis_rot.apply([0, 0, s * (length / 2 - 0.01)]) for s in (-1, 1)]
    posts = [_cyl(0.006, standoff / 2, 200, rng, post_rot, e + np.array([0, standoff / 2, 0])) for e in ends]
    plate_half = [0.03 if vertical else length / 2 + 0.03, 0.005, length / 2 + 0.03 if vertical else 0.03]
    plate = _box(plate_half, 1500, rng, centre + np.array([0, standoff + 0.005, 0]))
    return np.concatenate([bar, *posts, plate]), centre


def palm_seed(
    target: np.ndarray, approach: np.ndarray, gap: float, rng: np.random.Generator, along: np.ndarray | None = None
) -> tuple[np.ndarray, np.ndarray]:
    """A demonstrated palm pose ``gap`` m before ``target`` looking along ``approach``, ~10° tilt noise; palm x
    along ``along`` (fingers close across it, as a hand wrapping a handle; 15° roll noise), any roll when None."""
    z = approach / np.linalg.norm(approach)
    if along is None:
        helper = np.array([1.0, 0.0, 0.0]) if abs(z[0]) < 0.9 else np.array([0.0, 1.0, 0.0])
        roll = rng.uniform(-math.pi, math.pi)
    else:
        helper = np.cross(z, along)
        roll = rng.normal(0.0, math.radians(15.0))
    x = np.cross(helper, z)
    x /= np.linalg.norm(x)
    base = Rotation.from_matrix(np.stack([x, np.cross(z, x), z], axis=1))
    noise = Rotation.from_rotvec(rng.normal(0.0, math.radians(10.0), 3) * np.array([1, 1, 0]))
    rot = base * Rotation.from_euler("z", roll) * noise
    return target - rot.apply([0, 0, 1]) * gap, rot.as_quat()


def paper_cases(rng: np.random.Generator) -> list[Case]:
    """The four paper-task parts: from tasks.scenes when it exists, else proxies of the same parts."""
    cases: list[Case] = []
    down = np.array([0.0, 0.0, -1.0])
    pts, c = handle_on_plate(0.012, 0.16, 0.04, True, rng)
    pos, quat = palm_seed(c - np.array([0, 0.012, 0]), np.array([0.0, 1.0, 0.0]), 0.04, rng, np.array([0, 0, 1.0]))
    cases.append(Case("microwave-handle", pts, pos, quat))
    pts, c = handle_on_plate(0.010, 0.12, 0.035, False, rng)
    pos, quat = palm_seed(c - np.array([0, 0.010, 0]), np.array([0.0, 1.0, 0.0]), 0.04, rng, np.array([1.0, 0, 0]))
    cases.append(Case("drawer-handle", pts, pos, quat))
    bottle = _cyl(0.035, 0.09, 3000, rng, Rotation.identity(), np.array([0.5, 0.0, 0.39]))
    cap = _cyl(0.016, 0.012, 600, rng, Rotation.identity(), np.array([0.5, 0.0, 0.492]))
    neck = _cyl(0.014, 0.01, 300, rng, Rotation.identity(), np.array([0.5, 0.0, 0.475]))
    pts = np.concatenate([bottle, neck, cap])
    pos, quat = palm_seed(np.array([0.5, 0.0, 0.504]), down, 0.04, rng)
    cases.append(Case("bottle-cap", pts, pos, quat))
    knob = _cyl(0.025, 0.012, 1200, rng, Rotation.from_euler("x", 90, degrees=True), np.array([0.5, -0.012, 0.5]))
    plate = _box([0.08, 0.005, 0.08], 2000, rng, np.array([0.5, 0.005, 0.5]))
    pos, quat = palm_seed(np.array([0.5, -0.024, 0.5]), np.array([0.0, 1.0, 0.0]), 0.04, rng)
    cases.append(Case("knob", np.concatenate([knob, plate]), pos, quat))
    return cases


def random_cases(count: int, rng: np.random.Generator) -> list[Case]:
    """Randomised boxes, cylinders (upright and lying) and handles on plates with their demonstration seeds."""
    cases: list[Case] = []
    for i in range(count):
        kind = ("box", "cylinder", "handle")[i % 3]
        centre = np.array([0.5, 0.0, 0.5])
        if kind == "box":
            half = rng.uniform([0.015, 0.015, 0.02], [0.045, 0.045, 0.06])
            pts = _box(list(half), 3000, rng, centre)
            top = rng.random() < 0.5
            approach = np.array([0.0, 0.0, -1.0]) if top else np.array([0.0, 1.0, 0.0])
            face = centre + (np.array([0, 0, half[2]]) if top else np.array([0, -half[1], 0]))
            along = (
                (np.array([1.0, 0, 0]) if half[0] > half[1] else np.array([0, 1.0, 0]))
                if top
                else np.array([0, 0, 1.0])
            )
            name = f"box {2000 * half[0]:.0f}x{2000 * half[1]:.0f}x{2000 * half[2]:.0f}mm"
        elif kind == "cylinder":
            r, hh = rng.uniform(0.015, 0.04), rng.uniform(0.04, 0.09)
            lying = rng.random() < 0.5
            rot = Rotation.from_euler("y", 90, degrees=True) if lying else Rotation.identity()
            pts = _cyl(r, hh, 3000, rng, rot, centre)
            approach = np.array([0.0, 0.0, -1.0]) if lying else np.array([0.0, 1.0, 0.0])
            face = centre + (np.array([0, 0, r]) if lying else np.array([0, -r, 0]))
            along = np.array([1.0, 0, 0]) if lying else np.array([0, 0, 1.0])
            name = f"cylinder r{1000 * r:.0f} h{2000 * hh:.0f}mm {'lying' if lying else 'upright'}"
        else:
            r, length, standoff = rng.uniform(0.008, 0.016), rng.uniform(0.10, 0.18), rng.uniform(0.03, 0.05)
            vertical = rng.random() < 0.5
            pts, c = handle_on_plate(r, length, standoff, vertical, rng)
            approach = np.array([0.0, 1.0, 0.0])
            face = c - np.array([0, r, 0])
            along = np.array([0, 0, 1.0]) if vertical else np.array([1.0, 0, 0])
            name = f"handle r{1000 * r:.0f} l{1000 * length:.0f}mm {'vertical' if vertical else 'horizontal'}"
        pos, quat = palm_seed(face, approach, rng.uniform(0.02, 0.06), rng, along)
        cases.append(Case(name, pts, pos, quat))
    return cases


def baseline(model: ObjectModel, seed_pos: np.ndarray, seed_quat: np.ndarray) -> Grasp:
    """Close the open hand at the demonstrated palm pose (approach up to 30 mm), no search."""
    client = pb.connect(pb.DIRECT)
    try:
        obj = load_object(client, model)
        hand = barrett.load_hand(client)
        rot = Rotation.from_quat(seed_quat).as_matrix()
        dofs = barrett.dofs_from_eigengrasps(0.0, -4.0)
        out = evaluate_pose(client, hand, obj, model, rot, seed_pos, dofs, PlannerParams())
    finally:
        pb.disconnect(client)
    if out is None:
        return Grasp(
            "barrett", (0.0, -4.0), tuple(seed_pos), tuple(seed_quat), {"epsilon": 0.0, "force_closure": False}
        )
    pos, _, _, quality = out
    return Grasp(
        "barrett",
        (0.0, -4.0),
        (float(pos[0]), float(pos[1]), float(pos[2])),
        tuple(float(v) for v in seed_quat),  # type: ignore[arg-type]
        {"epsilon": quality.epsilon, "force_closure": quality.force_closure},
    )


def main() -> int:
    """Run the benchmark and print the table."""
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--quick", action="store_true", help="6 random objects instead of 21")
    parser.add_argument("--objects", type=int, default=None, help="number of randomised objects")
    parser.add_argument("--seed", type=int, default=7)
    args = parser.parse_args()
    n_random = args.objects if args.objects is not None else (6 if args.quick else 21)
    rng = np.random.default_rng(args.seed)
    cases = paper_cases(rng) + random_cases(n_random, rng)
    rows = []
    for case in cases:
        part = part_near(case.points, case.seed_pos)
        model = build_object_model(part, np.random.default_rng(args.seed))
        results = []
        for checks in (SHAKE_CHECKS, 0):
            t0 = time.perf_counter()
            try:
                cand = plan_on_model(
                    model, case.seed_pos, case.seed_quat, np.random.default_rng(args.seed), shake_checks=checks
                )
                grasp: Grasp | None = grasp_from_candidate(cand)
            except GraspError:
                grasp = None
            plan_s = time.perf_counter() - t0
            fc = bool(grasp is not None and grasp.quality["force_closure"])
            hold = bool(grasp is not None and shake_test(model, grasp).holds)
            eps = float(grasp.quality["epsilon"]) if grasp is not None else 0.0
            results.append((fc, hold, plan_s, eps))
        base = baseline(model, case.seed_pos, case.seed_quat)
        base_fc = bool(base.quality["force_closure"])
        base_hold = bool(shake_test(model, base).holds)
        (fc, hold, plan_s, eps), (fc0, hold0, plan0_s, _) = results
        rows.append((case.name, fc, hold, plan_s, eps, base_fc, base_hold, fc0, hold0, plan0_s))
        print(
            f"{case.name:32s} ours fc={fc!s:5s} hold={hold!s:5s} eps={eps:.3f} {plan_s:4.1f}s"
            f" | no shake check fc={fc0!s:5s} hold={hold0!s:5s} {plan0_s:4.1f}s"
            f" | baseline fc={base_fc!s:5s} hold={base_hold!s:5s}",
            flush=True,
        )
    n = len(rows)
    paper = rows[:4]

    def share(col: int) -> str:
        return f"{sum(r[col] for r in rows) / n:.0%}"

    def timing(col: int) -> str:
        t = np.array([r[col] for r in rows])
        return f"{np.median(t):.2f} / {t.max():.2f}"

    print()
    print(f"{'figure':36s} {'planner':>14s} {'planner, no shake check':>24s} {'baseline: close at demo':>24s}")
    fc_paper = [str(sum(r[c] for r in paper)) + "/4" for c in (1, 7, 5)]
    print(f"{'force closure, paper tasks':36s} {fc_paper[0]:>14s} {fc_paper[1]:>24s} {fc_paper[2]:>24s}")
    print(f"{'force closure, all objects':36s} {share(1):>14s} {share(7):>24s} {share(5):>24s}")
    print(f"{'holds under the shake test':36s} {share(2):>14s} {share(8):>24s} {share(6):>24s}")
    print(f"{'planning time median / max (s)':36s} {timing(3):>14s} {timing(9):>24s} {'0 (no search)':>24s}")
    print(f"objects: {n} ({len(paper)} paper-task parts + {n - len(paper)} randomised), seed {args.seed}")
    print("targets: force closure on 4/4 paper tasks, 95% hold, < 5 s per plan (2 cores, shared)")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
