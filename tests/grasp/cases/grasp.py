"""The benchmark objects of ``bench/grasp.py``: the four paper scenes and randomised boxes, cylinders and handles on
plates, each with its demonstrated palm seed, an independent model for the hold test (``Case.truth``) and the
benchmark's hold program (``hold_program``), all drawn from generators of the benchmark's own."""

from __future__ import annotations

import functools
import math
from collections.abc import Callable
from dataclasses import dataclass

import numpy as np
from scipy.spatial import cKDTree
from scipy.spatial.transform import Rotation

from tasks.arrays import Points
from tasks.grasp.api import part_near
from tasks.grasp.object_model import ObjectModel, build_object_model
from tasks.grasp.primitive_fit import PrimitiveShape
from tasks.grasp.shake import Motion, ShakeParams
from tasks.scenes.scene import Scene
from tasks.scenes.surface import WorldShape, model_shapes, sample_shapes
from tests.grasp.cases.exact import distance_to, exact_model, handle_shapes, labelled_model, primitive_model
from tests.grasp.surface_sampling import sample_box_surface, sample_cylinder_surface

Resample = Callable[[np.random.Generator], ObjectModel]
"""An independent model of a benchmark object for the hold test, from a generator of the benchmark's own."""


@dataclass
class Case:
    """One benchmark object: name, points (world, m), seed palm pose, and its model for the hold test (``truth``,
    ``Resample``: the exact shapes; for a scene or a handle, the part's exact shapes on their mount's,
    ``exact.exact_model``); for a scene or a handle also ``pieces``: the part sampled anew and cut into convex
    pieces, its mount a fresh scan's or the plate's (the benchmark's truth until 2026-12-01), and ``as_one``: the
    part and its mount as one free body (the one before)."""

    name: str
    points: Points
    seed_pos: np.ndarray
    seed_quat: np.ndarray
    truth: Resample
    pieces: Resample | None = None
    as_one: Resample | None = None


def _cyl(  # noqa: PLR0917 -- small sampling helper
    r: float, hh: float, n: int, rng: np.random.Generator, rot: Rotation, at: np.ndarray
) -> Points:
    pts, _ = sample_cylinder_surface(r, hh, n, rng)
    out: Points = np.asarray(rot.apply(pts) + at, dtype=np.float64)
    return out


def _box(half: list[float], n: int, rng: np.random.Generator, at: np.ndarray) -> Points:
    pts, _ = sample_box_surface(np.array(half), n, rng)
    out: Points = np.asarray(pts + at, dtype=np.float64)
    return out


PLATE_POINTS = 1500
"""Surface points of a handle's plate (the last of ``handle_on_plate``'s points)."""


def handle_on_plate(
    radius: float, length: float, standoff: float, vertical: bool, rng: np.random.Generator
) -> tuple[Points, np.ndarray]:
    """A bar handle (along z or x) standing ``standoff`` m in front (-y) of a 10 mm plate; returns points (the
    plate's ``PLATE_POINTS`` last) and the bar centre."""
    centre = np.array([0.5, 0.0, 0.5])
    axis_rot = Rotation.identity() if vertical else Rotation.from_euler("y", 90, degrees=True)
    bar = _cyl(radius, length / 2, 1500, rng, axis_rot, centre)
    post_rot = Rotation.from_euler("x", 90, degrees=True)
    ends = [centre + axis_rot.apply([0, 0, s * (length / 2 - 0.01)]) for s in (-1, 1)]
    posts = [_cyl(0.006, standoff / 2, 200, rng, post_rot, e + np.array([0, standoff / 2, 0])) for e in ends]
    plate_half = [0.03 if vertical else length / 2 + 0.03, 0.005, length / 2 + 0.03 if vertical else 0.03]
    face = _box(plate_half, PLATE_POINTS, rng, centre + np.array([0, standoff + 0.005, 0]))
    return np.concatenate([bar, *posts, face]), centre


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


def scene_cases(seeds: range) -> list[Case]:
    """The four paper tasks as the built-in scenes (tasks.scenes), seeded instances: the object model sampled as
    ``pbd synth`` records it (``scan_object_model``: 8192 points, half within 15 cm of the demonstrated palm, with
    the model generator ``pbd synth`` uses), the seed the scene's demonstrated palm pose."""
    from tasks.scenes.catalog import SCENE_NAMES, build_scene
    from tasks.scenes.kinematics import truth_descriptor
    from tasks.synth.record import OBJECT_MODEL_POINTS
    from tasks.synth.scan import scan_object_model

    cases: list[Case] = []
    for name in SCENE_NAMES:
        for seed in seeds:
            scene = build_scene(name, seed)
            grasp = truth_descriptor(scene).grasp
            assert grasp is not None
            model_rng = np.random.default_rng(np.random.SeedSequence(seed).spawn(3)[2])
            pts = scan_object_model(scene, OBJECT_MODEL_POINTS, model_rng)
            palm = np.array(grasp.wrist_position)

            def rescan(rng: np.random.Generator, scene: object = scene, palm: np.ndarray = palm) -> ObjectModel:
                fresh = scan_object_model(scene, OBJECT_MODEL_POINTS, rng)  # type: ignore[arg-type]
                return build_object_model(part_near(fresh, palm), rng, viewpoint=palm)

            orientation = np.array(grasp.wrist_orientation)
            shapes = model_shapes(scene)
            part = grasped_shapes(scene, shapes)
            held = _part_resample(scene, part, palm)
            exact = _exact_scene(shapes, part, palm)
            cases.append(Case(f"{name} seed {seed}", pts, palm, orientation, exact, held, rescan))
    return cases


MOUNT_GAP_M = 0.004
"""Scan points farther than this from the grasped part's surface are its mount."""
PART_POINTS = 3000
"""Surface points of a scene's grasped part sampled for the hold test's model."""
PART_MAX_EXTENT_M = 0.3
"""A shape of the grasp link no longer than this is part of the grasped part (a handle's bar and posts, a lever, a
cap); longer ones are the door or panel the handle is fixed to."""


def _part_resample(scene: Scene, shapes: list[WorldShape], palm: np.ndarray) -> Resample:
    """The grasped part's shapes sampled anew (``PART_POINTS``), and as its mount the rest of a fresh scan within
    15 cm of the palm (points over 4 mm from the part), each cut into its own convex pieces."""
    from tasks.synth.record import OBJECT_MODEL_POINTS
    from tasks.synth.scan import scan_object_model

    def make(rng: np.random.Generator) -> ObjectModel:
        held = sample_shapes(shapes, PART_POINTS, rng)
        around = part_near(scan_object_model(scene, OBJECT_MODEL_POINTS, rng), palm)
        gap, _ = cKDTree(held).query(around)
        return labelled_model(held, around[gap > MOUNT_GAP_M], rng, viewpoint=palm)

    return make


MOUNT_REACH_M = 0.18
"""Shapes of the scene (other than the grasped part's) within this of the demonstrated palm are the exact model's
mount (the scan crop of ``part_near`` reaches 15 cm from the point nearest the palm)."""


def _exact_scene(shapes: list[WorldShape], part: list[WorldShape], palm: np.ndarray) -> Resample:
    """The grasped part's exact shapes (``part``, some of the scene's ``shapes``) on the scene's other shapes near the
    palm (``exact.exact_model``)."""
    mount = [s for s in shapes if all(s is not p for p in part) and distance_to(s, palm) <= MOUNT_REACH_M]
    return lambda rng: exact_model(part, mount, rng)


def grasped_shapes(scene: Scene, shapes: list[WorldShape] | None = None) -> list[WorldShape]:
    """The collision shapes (world, at the demonstration's start) of what the hand holds: the grasp link's shapes
    no longer than ``PART_MAX_EXTENT_M`` (the microwave's and the sliding door's bar handle, the door's lever with
    its rose, the bottle's cap), taken from ``shapes`` (the scene's ``model_shapes``, built when None)."""

    def extent(shape: WorldShape) -> float:
        if shape.kind == "cylinder":
            return max(2.0 * shape.size[0], shape.size[1])
        return 2.0 * shape.size[0] if shape.kind == "sphere" else max(shape.size)

    every = model_shapes(scene) if shapes is None else shapes
    part = [s for s in every if s.link == scene.grasp_link and extent(s) <= PART_MAX_EXTENT_M]
    if not part:
        msg = f"scene {scene.name}: no shape of grasp link {scene.grasp_link} is {PART_MAX_EXTENT_M} m or shorter"
        raise ValueError(msg)
    return part


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
            shape = PrimitiveShape("box", (float(half[0]), float(half[1]), float(half[2])), (0.5, 0.0, 0.5))
            truth = _primitive(shape, pts)
        elif kind == "cylinder":
            r, hh = rng.uniform(0.015, 0.04), rng.uniform(0.04, 0.09)
            lying = rng.random() < 0.5
            rot = Rotation.from_euler("y", 90, degrees=True) if lying else Rotation.identity()
            pts = _cyl(r, hh, 3000, rng, rot, centre)
            approach = np.array([0.0, 0.0, -1.0]) if lying else np.array([0.0, 1.0, 0.0])
            face = centre + (np.array([0, 0, r]) if lying else np.array([0, -r, 0]))
            along = np.array([1.0, 0, 0]) if lying else np.array([0, 0, 1.0])
            name = f"cylinder r{1000 * r:.0f} h{2000 * hh:.0f}mm {'lying' if lying else 'upright'}"
            q = rot.as_quat()
            shape = PrimitiveShape(
                "cylinder", (r, hh, 0.0), (0.5, 0.0, 0.5), (float(q[0]), float(q[1]), float(q[2]), float(q[3]))
            )
            truth = _primitive(shape, pts)
        else:
            r, length, standoff = rng.uniform(0.008, 0.016), rng.uniform(0.10, 0.18), rng.uniform(0.03, 0.05)
            vertical = rng.random() < 0.5
            pts, c = handle_on_plate(r, length, standoff, vertical, rng)
            approach = np.array([0.0, 1.0, 0.0])
            face = c - np.array([0, r, 0])
            along = np.array([0, 0, 1.0]) if vertical else np.array([1.0, 0, 0])
            name = f"handle r{1000 * r:.0f} l{1000 * length:.0f}mm {'vertical' if vertical else 'horizontal'}"
            truth = _handle_resample(r, length, standoff, vertical)
            as_one = _handle_resample(r, length, standoff, vertical, plate=True)
        pos, quat = palm_seed(face, approach, rng.uniform(0.02, 0.06), rng, along)
        if kind == "handle":
            part, mount = handle_shapes(r, length, standoff, vertical)
            exact = functools.partial(exact_model, part, mount)
            cases.append(Case(name, pts, pos, quat, exact, truth, as_one))
        else:
            cases.append(Case(name, pts, pos, quat, truth))
    return cases


def _primitive(shape: PrimitiveShape, points: Points) -> Resample:
    """The exact box or cylinder (``shape``) as the hold test's model (its points only give centre and radius)."""

    def make(rng: np.random.Generator) -> ObjectModel:
        del rng
        return primitive_model(points, shape)

    return make


def _handle_resample(radius: float, length: float, standoff: float, vertical: bool, plate: bool = False) -> Resample:
    """The same handle on its plate sampled anew and cut into its own convex pieces: the plate its mount (an
    obstacle when the fingers close, not part of the free body), or part of the free body when ``plate``."""

    def make(rng: np.random.Generator) -> ObjectModel:
        pts, centre = handle_on_plate(radius, length, standoff, vertical, rng)
        view = centre - np.array([0.0, 0.1, 0.0])
        if plate:
            return build_object_model(pts, rng, viewpoint=view)
        return labelled_model(pts[:-PLATE_POINTS], pts[-PLATE_POINTS:], rng, viewpoint=view)

    return make


def hold_program(rng: np.random.Generator) -> ShakeParams:
    """The benchmark's hold test (see the module docstring): gravity world down, then twice tilted 20-40° from it
    towards a random side (the part carried at other attitudes of the hand); in each, three translations (random
    directions, 2-4 Hz, peak acceleration 5-8 m/s²) and a turn of the palm about a random axis (1.5-2.5 Hz,
    amplitude 5-10°, so 10-20° of swing), three cycles each."""
    gravity = [(0.0, 0.0, -9.81)]
    for _ in range(2):
        azimuth = float(rng.uniform(0.0, 2.0 * math.pi))
        tilt = math.radians(float(rng.uniform(20.0, 40.0)))
        down = np.array([math.sin(tilt) * math.cos(azimuth), math.sin(tilt) * math.sin(azimuth), -math.cos(tilt)])
        gravity.append(_scaled(down, 9.81))
    motions: list[Motion] = []
    for _ in range(3):
        direction = _unit(rng.normal(size=3))
        f = float(rng.uniform(2.0, 4.0))
        peak = float(rng.uniform(5.0, 8.0))
        motions.append(Motion(direction, peak / (2.0 * math.pi * f) ** 2, f, 3.0))
    axis = _unit(rng.normal(size=3))
    turn = math.radians(float(rng.uniform(5.0, 10.0)))
    motions.append(Motion(axis, turn, float(rng.uniform(1.5, 2.5)), 3.0, turn=True))
    return ShakeParams(gravity=tuple(gravity), motions=tuple(motions))


def _unit(v: np.ndarray) -> tuple[float, float, float]:
    return _scaled(v, 1.0)


def _scaled(v: np.ndarray, length: float) -> tuple[float, float, float]:
    u = length * v / np.linalg.norm(v)
    return (float(u[0]), float(u[1]), float(u[2]))
