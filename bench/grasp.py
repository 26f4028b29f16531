"""Benchmark the eigengrasp planner against closing the hand at the demonstrated pose (same run, same seeds).

Objects: the four paper tasks as the built-in scenes (tasks.scenes, seeds 0..N-1 each: the object model sampled
as ``pbd synth`` records it, the demonstrated palm pose as the seed) and randomised objects (boxes, cylinders,
handles on a plate) whose simulated demonstration seed is a palm pose 20..60 mm off the part, facing it from above
or from the side, with a random roll and ~10° of tilt noise. For each: plan (our figure) and the baseline (the
open hand at the demonstrated pose, approach up to 30 mm, close, no search); force closure, the shake test, the
palm's distance and angle from the demonstrated palm, planning time (wall and CPU seconds).

The hold figure is the benchmark's own test, not the planner's: the planner checks its candidates with
``tasks.grasp.api.hold_check`` (gravity down and tilted 30° to either end of the palm's x axis, x/y/z shakes at 6.5
m/s² and a 7.5° palm turn, one cycle each, 6 s, 5 mm / 5°) on its own object model. The benchmark shakes each grasp
(ours and the baseline's alike) on an independent model of the object (the exact box or cylinder primitive; for a
scene, the grasped part, its handle, lever or cap, sampled anew from the scene's shapes, and as its mount the rest
of a fresh scan within 15 cm of the palm; a handle sampled anew, its plate the mount), each cut into its own convex
pieces. The fingers close on part and mount (held static); then the part alone is the free body, and a finger the
mount stopped holds its place: a grasp must hold the part, not pinch what it is fixed to. The program is drawn
per object from a generator of its own (``hold_program``): gravity in three directions relative to the hand (world
down, then tilted 20-40° towards two random sides), in each three translations along random directions at 2-4 Hz
with 5-8 m/s² peaks and a turn of the palm of 5-10° about a random axis, three cycles each: about 16 s of shaking
against the planner's 6 s, at random peaks and directions, within 10 mm and 10°. The second hold line is the former
planner check (``QUICK_SHAKE``: world gravity, 4.9 m/s² peaks, 4.8 s) on the same independent models. The third
is the benchmark's program on the former models of scenes and handles, part and mount one free body (the scan
within 15 cm of the palm; the handle with its plate), where a grasp pinching the face behind a handle counted.

``--execute`` adds the learned-execution figure: ``pbd synth`` seeds 0-9 of each scene learned
(``learn_descriptor``, grasp planned) and executed in their own instance in pybullet (``tasks.simulate``).

    .venv/bin/python bench/grasp.py [--quick] [--objects N] [--scene-seeds N] [--seed S] [--only TEXT] [--execute]
"""

from __future__ import annotations

import argparse
import math
import sys
import time
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import pybullet as pb
from scipy.spatial import cKDTree
from scipy.spatial.transform import Rotation

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from schemas.descriptor import Grasp
from tasks.arrays import Points
from tasks.errors import GraspError
from tasks.grasp import barrett
from tasks.grasp.api import grasp_from_candidate, part_near, plan_on_model
from tasks.grasp.object_model import (
    ObjectModel,
    PrimitiveShape,
    build_object_model,
    labelled_model,
    load_object,
    sample_box_surface,
    sample_cylinder_surface,
)
from tasks.grasp.planner import PlannerParams, evaluate_pose
from tasks.grasp.shake import QUICK_SHAKE, Motion, ShakeParams, shake_test
from tasks.scenes.scene import Scene
from tasks.scenes.surface import WorldShape, model_shapes, sample_shapes

Resample = Callable[[np.random.Generator], ObjectModel]
"""An independent model of a benchmark object for the hold test, from a generator of the benchmark's own."""


@dataclass
class Case:
    """One benchmark object: name, points (world, m), seed palm pose, and its independent model for the hold
    test (``Resample``; for a scene or a handle, the part with its mount known); ``as_one``: the part and its
    mount as one free body (the benchmark's former model of scenes and handles)."""

    name: str
    points: Points
    seed_pos: np.ndarray
    seed_quat: np.ndarray
    truth: Resample
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
            held = _part_resample(scene, grasped_shapes(scene), palm)
            cases.append(Case(f"{name} seed {seed}", pts, palm, orientation, held, rescan))
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


def grasped_shapes(scene: Scene) -> list[WorldShape]:
    """The collision shapes (world, at the demonstration's start) of what the hand holds: the grasp link's shapes
    no longer than ``PART_MAX_EXTENT_M`` (the microwave's and the sliding door's bar handle, the door's lever with
    its rose, the bottle's cap)."""

    def extent(shape: WorldShape) -> float:
        if shape.kind == "cylinder":
            return max(2.0 * shape.size[0], shape.size[1])
        return 2.0 * shape.size[0] if shape.kind == "sphere" else max(shape.size)

    shapes = [s for s in model_shapes(scene) if s.link == scene.grasp_link and extent(s) <= PART_MAX_EXTENT_M]
    if not shapes:
        msg = f"scene {scene.name}: no shape of grasp link {scene.grasp_link} is {PART_MAX_EXTENT_M} m or shorter"
        raise ValueError(msg)
    return shapes


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
        cases.append(Case(name, pts, pos, quat, truth, as_one if kind == "handle" else None))
    return cases


def _primitive(shape: PrimitiveShape, points: Points) -> Resample:
    """The exact box or cylinder (``shape``) as the hold test's model (its points only give centre and radius)."""

    def make(rng: np.random.Generator) -> ObjectModel:
        del rng
        return build_object_model(points, np.random.default_rng(0), primitive=shape, normals=np.zeros_like(points))

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


def baseline(model: ObjectModel, seed_pos: np.ndarray, seed_quat: np.ndarray) -> Grasp | None:
    """Close the open hand (spread 0) at the demonstrated palm pose (approach up to 30 mm), no search."""
    client = pb.connect(pb.DIRECT)
    try:
        obj = load_object(client, model)
        hand = barrett.load_hand(client)
        rot = Rotation.from_quat(seed_quat).as_matrix()
        out = evaluate_pose(client, hand, obj, model, rot, seed_pos, 0.0, PlannerParams())
    finally:
        pb.disconnect(client)
    if out is None:
        return None
    pos, _, _, quality = out
    return Grasp(
        "barrett",
        (barrett.spread_amplitude(0.0), barrett.CLOSE_AMPLITUDE),
        (float(pos[0]), float(pos[1]), float(pos[2])),
        tuple(float(v) for v in seed_quat),  # type: ignore[arg-type]
        {"epsilon": quality.epsilon, "force_closure": quality.force_closure},
    )


def offset_from(grasp: Grasp, seed_pos: np.ndarray, seed_quat: np.ndarray) -> tuple[float, float]:
    """Distance (mm) and angle (degrees) of a grasp's palm from the demonstrated palm."""
    dist = 1000.0 * float(np.linalg.norm(np.array(grasp.wrist_position) - seed_pos))
    turn = Rotation.from_quat(seed_quat).inv() * Rotation.from_quat(grasp.wrist_orientation)
    return dist, math.degrees(float(turn.magnitude()))


@dataclass
class Row:
    """One case's figures: planner and baseline force closure, hold (bench test; ``old_*``: the planner's former
    check ``QUICK_SHAKE`` on the same independent model), offsets (mm, degrees), time (s)."""

    name: str
    fc: bool
    hold: bool
    eps: float
    dist_mm: float
    angle_deg: float
    plan_s: float
    plan_cpu_s: float
    base_fc: bool
    base_hold: bool
    base_dist_mm: float
    old_hold: bool = False
    base_old_hold: bool = False
    crop_hold: bool = False
    base_crop_hold: bool = False


def run_case(case: Case, seed: int, index: int) -> Row:
    """Plan (with the planner's own shake check), then the benchmark's hold test (``hold_program`` on the case's
    independent model, both drawn from generators of the benchmark's own) of the plan and of the baseline."""
    part = part_near(case.points, case.seed_pos)
    approach = Rotation.from_quat(case.seed_quat).as_matrix()[:, 2]
    model = build_object_model(part, np.random.default_rng(seed), viewpoint=case.seed_pos, approach=approach)
    truth = case.truth(np.random.default_rng([seed, 1, index]))
    program = hold_program(np.random.default_rng([seed, 2, index]))
    t0 = time.perf_counter()
    c0 = time.process_time()
    try:
        cand = plan_on_model(model, case.seed_pos, case.seed_quat, np.random.default_rng(seed))
        grasp: Grasp | None = grasp_from_candidate(cand)
    except GraspError:
        grasp = None
    plan_s = time.perf_counter() - t0
    plan_cpu_s = time.process_time() - c0
    base = baseline(model, case.seed_pos, case.seed_quat)
    fc = bool(grasp is not None and grasp.quality["force_closure"])
    hold = bool(grasp is not None and shake_test(truth, grasp, program).holds)
    dist, angle = offset_from(grasp, case.seed_pos, case.seed_quat) if grasp is not None else (math.nan, math.nan)
    base_fc = bool(base is not None and base.quality["force_closure"])
    base_hold = bool(base is not None and shake_test(truth, base, program).holds)
    base_dist = offset_from(base, case.seed_pos, case.seed_quat)[0] if base is not None else math.nan
    eps = float(grasp.quality["epsilon"]) if grasp is not None else 0.0
    old = bool(grasp is not None and shake_test(truth, grasp, QUICK_SHAKE).holds)
    base_old = bool(base is not None and shake_test(truth, base, QUICK_SHAKE).holds)
    crop, base_crop = hold, base_hold
    if case.as_one is not None:  # a scene or a handle: also part and mount as one free body, as formerly
        cropped = case.as_one(np.random.default_rng([seed, 1, index]))
        crop = bool(grasp is not None and shake_test(cropped, grasp, program).holds)
        base_crop = bool(base is not None and shake_test(cropped, base, program).holds)
    return Row(
        case.name,
        fc,
        hold,
        eps,
        dist,
        angle,
        plan_s,
        plan_cpu_s,
        base_fc,
        base_hold,
        base_dist,
        old,
        base_old,
        crop,
        base_crop,
    )


def _share(rows: list[Row], field: str) -> str:
    hits = sum(bool(getattr(r, field)) for r in rows)
    return f"{hits}/{len(rows)} ({hits / max(len(rows), 1):.0%})"


def execute_learned(seeds: range, only: str | None) -> None:
    """Learn ``pbd synth`` seeds of each scene (grasp planned) and execute each in its own instance; prints per
    scene how many succeed and how many of the planned grasps are force closures."""
    import tempfile

    from tasks.errors import PbdError
    from tasks.ingest.api import ingest_recording
    from tasks.learn.api import learn_descriptor
    from tasks.learn.params import LearnParams
    from tasks.recording.load import load_recording
    from tasks.scenes.catalog import SCENE_NAMES, build_scene
    from tasks.simulate.execute import execute
    from tasks.simulate.scenes import scene_setup_for
    from tasks.store import Store
    from tasks.synth.record import synthesize

    total = closures = runs = 0
    with tempfile.TemporaryDirectory() as folder:
        store = Store(Path(folder) / "store")
        for name in SCENE_NAMES:
            ok = fc = n = 0
            for seed in seeds:
                if only is not None and only not in f"{name} seed {seed}":
                    continue
                n += 1
                try:
                    path = synthesize(name, seed, Path(folder) / f"{name}-{seed}.mcap")
                    rec = load_recording(store, ingest_recording(path, store).recording_id)
                    desc = learn_descriptor(rec, LearnParams(), rng=np.random.default_rng(0))
                    fc += bool(desc.grasp is not None and desc.grasp.quality.get("force_closure"))
                    result = execute(desc, scene_setup_for(build_scene(name, seed)))
                    ok += result.success
                    note = "" if result.success else " FAILED"
                except PbdError as err:
                    note = f" FAILED: {err}"
                print(f"learned {name} seed {seed}: executes{note}", flush=True)
            print(f"learned and executed, {name}: {ok}/{n} succeed, {fc}/{n} force closure", flush=True)
            total, closures, runs = total + ok, closures + fc, runs + n
    print(f"learned and executed, all: {total}/{runs} succeed, {closures}/{runs} force closure")


def main() -> int:
    """Run the benchmark and print the table."""
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--quick", action="store_true", help="1 seed per scene and 6 random objects")
    parser.add_argument("--objects", type=int, default=None, help="number of randomised objects (default 21)")
    parser.add_argument("--scene-seeds", type=int, default=None, help="seeds 0..N-1 of each scene (default 3)")
    parser.add_argument("--seed", type=int, default=7)
    parser.add_argument("--only", default=None, help="only the objects whose 'index:name' contains this text")
    parser.add_argument("--execute", action="store_true", help="also learn and execute pbd synth seeds 0-9")
    args = parser.parse_args()
    n_random = args.objects if args.objects is not None else (6 if args.quick else 21)
    n_scene = args.scene_seeds if args.scene_seeds is not None else (1 if args.quick else 3)
    rng = np.random.default_rng(args.seed)
    scenes = scene_cases(range(n_scene))
    cases = scenes + random_cases(n_random, rng)
    rows: list[Row] = []
    n_paper = 0
    for index, case in enumerate(cases):
        if args.only is not None and args.only not in f"{index}:{case.name}":
            continue
        r = run_case(case, args.seed, index)
        rows.append(r)
        n_paper += index < len(scenes)
        print(
            f"{index:2d} {r.name:31s} ours fc={r.fc!s:5s} hold={r.hold!s:5s} eps={r.eps:.3f} off {r.dist_mm:5.1f} mm"
            f" {r.angle_deg:5.1f} deg {r.plan_s:4.1f} s ({r.plan_cpu_s:3.1f} cpu) | baseline fc={r.base_fc!s:5s}"
            f" hold={r.base_hold!s:5s}"
            f" off {r.base_dist_mm:5.1f} mm",
            flush=True,
        )
    if not rows:
        if args.execute:
            execute_learned(range(10), args.only)
        return 0
    paper = rows[:n_paper]
    other = rows[n_paper:]
    times = np.array([r.plan_s for r in rows])
    cpu = np.array([r.plan_cpu_s for r in rows])
    dists = np.array([r.dist_mm for r in rows])
    angles = np.array([r.angle_deg for r in rows])
    print()
    print(f"{'figure':44s} {'planner':>18s} {'baseline: close at demo':>24s}")
    for label, subset in (("scenes", paper), ("randomised objects", other), ("all", rows)):
        print(f"{'force closure, ' + label:44s} {_share(subset, 'fc'):>18s} {_share(subset, 'base_fc'):>24s}")
        held, base_held = _share(subset, "hold"), _share(subset, "base_hold")
        print(f"{'holds under the bench hold test, ' + label:44s} {held:>18s} {base_held:>24s}")
        old, base_old = _share(subset, "old_hold"), _share(subset, "base_old_hold")
        print(f"{'  (former shake test, same model), ' + label:44s} {old:>18s} {base_old:>24s}")
        crop, base_crop = _share(subset, "crop_hold"), _share(subset, "base_crop_hold")
        print(f"{'  (bench test, part+mount one body), ' + label:44s} {crop:>18s} {base_crop:>24s}")
    scene_names = sorted({r.name.split(" seed")[0] for r in paper})
    fc_tasks = sum(any(r.fc for r in paper if r.name.startswith(n + " seed")) for n in scene_names)
    print(f"{'paper tasks with a force closure (any seed)':44s} {f'{fc_tasks}/{len(scene_names)}':>18s}")
    print(f"{'offset from demo, median / max (mm)':44s} {f'{np.nanmedian(dists):.1f} / {np.nanmax(dists):.1f}':>18s}")
    print(f"{'angle from demo, median / max (deg)':44s} {f'{np.nanmedian(angles):.1f} / {np.nanmax(angles):.1f}':>18s}")
    timing = f"{np.median(times):.2f} / {times.max():.2f}"
    print(f"{'planning time median / max (s)':44s} {timing:>18s} {'0 (no search)':>24s}")
    cpu_timing = f"{np.median(cpu):.2f} / {cpu.max():.2f}"
    print(f"{'planning CPU time median / max (s)':44s} {cpu_timing:>18s}")
    print(f"objects: {len(rows)} ({len(paper)} scene instances + {len(other)} randomised), seed {args.seed}")
    print("targets: force closure on 4/4 paper tasks, 95% hold, < 5 s per plan (2 cores, shared)")
    if args.execute:
        execute_learned(range(10), args.only)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
