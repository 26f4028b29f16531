"""Benchmark the eigengrasp planner against closing the hand at the demonstrated pose (same run, same seeds).

Objects: the four paper tasks as the built-in scenes (tasks.scenes, seeds 0..N-1 each: the object model sampled
as ``pbd synth`` records it, the demonstrated palm pose as the seed) and randomised objects (boxes, cylinders,
handles on a plate) whose simulated demonstration seed is a palm pose 20..60 mm off the part, facing it from above
or from the side, with a random roll and ~10° of tilt noise. For each: plan (our figure) and the baseline (the
open hand at the demonstrated pose, approach up to 30 mm, close, no search); force closure, the shake test, the
palm's distance and angle from the demonstrated palm, planning time (wall seconds with the planner's worker
processes, ``tasks.grasp.worker_pool``, and its peer: the same plan made again in one process, as before them).

The hold figure is the benchmark's own test, not the planner's: the planner checks its candidates with
``tasks.grasp.hold_check.hold_check`` (gravity down and tilted 30° to either end of the palm's x axis, x/y/z
shakes at 6.5 m/s² and a 7.5° palm turn, one cycle each, 6 s, on a fitted box or cylinder three cycles, 15 s; 5 mm /
5°) on its own object model. The benchmark shakes each grasp
(ours and the baseline's alike) on the object as it is: its exact shapes (the box or cylinder; for a scene, the
grasped part's collision shapes, its handle, lever or cap, on the scene's other shapes within 18 cm of the palm as
its mount; for a handle, bar and posts on the plate; ``cases/exact.py``: each shape one convex piece, a cylinder a
64-sided prism). The fingers close on part and mount (held static); then the part alone is the free body, and a
finger the mount stopped holds its place: a grasp must hold the part, not pinch what it is fixed to. The program is
drawn per object from a generator of its own (``hold_program``): gravity in three directions relative to the hand (world
down, then tilted 20-40° towards two random sides), in each three translations along random directions at 2-4 Hz
with 5-8 m/s² peaks and a turn of the palm of 5-10° about a random axis, three cycles each: about 16 s of shaking
against the planner's 6 s, at random peaks and directions, within 10 mm and 10°. The second hold line is the
benchmark's truth until 2026-12-01 for scenes and handles: the part sampled anew (3000 points) and cut into k-means
convex pieces, its mount a fresh scan's points or the plate's, each piece 60 points (a bar of 24 mm became four or
five flat facets around, which lock a part in the fingers that a round bar rolls out of, and seams that catch a
fingertip). The third is the former planner check (``QUICK_SHAKE``: world gravity, 4.9 m/s² peaks, 4.8 s) on the
exact shapes. The fourth is the benchmark's program on the models before that, part and mount one free body (the
scan within 15 cm of the palm; the handle with its plate), where a grasp pinching the face behind a handle counted.

``--execute`` adds the learned-execution figure: ``pbd synth`` seeds 0-9 of each scene learned
(``learn_descriptor``, grasp planned) and executed in their own instance in pybullet (``tasks.simulate``).

    .venv/bin/python bench/grasp.py [--quick] [--objects N] [--scene-seeds N] [--seed S [S ...]] [--only TEXT]
        [--execute]
"""

from __future__ import annotations

import argparse
import math
import os
import sys
import time
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import pybullet as pb
from scipy.spatial.transform import Rotation

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from schemas.descriptor import Grasp
from tasks.errors import GraspError
from tasks.grasp.api import part_near, plan_on_model
from tasks.grasp.candidate_grasp import grasp_from_candidate
from tasks.grasp.object_model import (
    ObjectModel,
    build_object_model,
    load_object,
)
from tasks.grasp.planner import PlannerParams, evaluate_pose
from tasks.grasp.shake import QUICK_SHAKE, shake_test
from tasks.grasp.worker_pool import PROCESSES_ENV, wait_idle
from tasks.hand import barrett
from tests.grasp.cases.grasp import Case, hold_program, random_cases, scene_cases

PLAN_TARGET_S = 5.0
"""The issue's planning time target, seconds per plan on 2 cores."""


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
    """One case's figures: planner and baseline force closure, hold (bench test on the exact shapes; ``old_*``: the
    planner's former check ``QUICK_SHAKE`` on them; ``pieces_*``: the bench test on the part in convex pieces;
    ``crop_*``: on part and mount as one body), offsets (mm, degrees), planning time (s, wall) with the worker
    processes and in one process (``one_*``, wall and CPU), and whether both made the same plan."""

    name: str
    fc: bool
    hold: bool
    eps: float
    dist_mm: float
    angle_deg: float
    plan_s: float
    one_s: float
    one_cpu_s: float
    same_plan: bool
    base_fc: bool
    base_hold: bool
    base_dist_mm: float
    old_hold: bool = False
    base_old_hold: bool = False
    crop_hold: bool = False
    base_crop_hold: bool = False
    pieces_hold: bool = False
    base_pieces_hold: bool = False


def _timed_plan(
    model: ObjectModel, case: Case, seed: int, *, one_process: bool = False
) -> tuple[Grasp | None, float, float]:
    """The grasp planned with an rng seeded with ``seed`` (None when planning fails), wall and CPU seconds of this
    process: with the planner's worker processes (``tasks.grasp.worker_pool``), or ``one_process`` without them
    (``PBD_GRASP_PROCESSES=1``)."""
    before = os.environ.get(PROCESSES_ENV)
    if one_process:
        os.environ[PROCESSES_ENV] = "1"
    t0 = time.perf_counter()
    c0 = time.process_time()
    try:
        grasp: Grasp | None = grasp_from_candidate(
            plan_on_model(model, case.seed_pos, case.seed_quat, np.random.default_rng(seed))
        )
    except GraspError:
        grasp = None
    finally:
        if before is None:
            os.environ.pop(PROCESSES_ENV, None)
        else:
            os.environ[PROCESSES_ENV] = before
    return grasp, time.perf_counter() - t0, time.process_time() - c0


def run_case(case: Case, seed: int, index: int, *, peer: bool = True) -> Row:
    """Plan (with the planner's own shake check; ``peer``: again in one process, timed beside it), then the
    benchmark's hold test (``hold_program`` on the case's exact shapes, both drawn from generators of the
    benchmark's own) of the plan and of the baseline."""
    part = part_near(case.points, case.seed_pos)
    approach = Rotation.from_quat(case.seed_quat).as_matrix()[:, 2]
    model = build_object_model(part, np.random.default_rng(seed), viewpoint=case.seed_pos, approach=approach)
    truth = case.truth(np.random.default_rng([seed, 3, index]))
    program = hold_program(np.random.default_rng([seed, 2, index]))
    grasp, plan_s, _ = _timed_plan(model, case, seed)
    wait_idle()  # checks the plan started ahead and did not need: not to slow the next plan
    one, one_s, one_cpu_s = _timed_plan(model, case, seed, one_process=True) if peer else (grasp, math.nan, math.nan)
    same_plan = grasp == one
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
    cut, base_cut = hold, base_hold
    if case.pieces is not None:  # a scene or a handle: also the part resampled in convex pieces, as formerly
        faceted = case.pieces(np.random.default_rng([seed, 1, index]))
        cut = bool(grasp is not None and shake_test(faceted, grasp, program).holds)
        base_cut = bool(base is not None and shake_test(faceted, base, program).holds)
    return Row(
        case.name,
        fc,
        hold,
        eps,
        dist,
        angle,
        plan_s,
        one_s,
        one_cpu_s,
        same_plan,
        base_fc,
        base_hold,
        base_dist,
        old,
        base_old,
        crop,
        base_crop,
        cut,
        base_cut,
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


def run_seed(seed: int, args: argparse.Namespace) -> list[Row]:
    """Plan and test every object of one benchmark seed; print a line per object and the seed's table."""
    n_random = args.objects if args.objects is not None else (6 if args.quick else 21)
    n_scene = args.scene_seeds if args.scene_seeds is not None else (1 if args.quick else 3)
    rng = np.random.default_rng(seed)
    scenes = scene_cases(range(n_scene))
    cases = scenes + random_cases(n_random, rng)
    rows: list[Row] = []
    n_paper = 0
    for index, case in enumerate(cases):
        if args.only is not None and args.only not in f"{index}:{case.name}":
            continue
        r = run_case(case, seed, index, peer=not args.no_peer)
        rows.append(r)
        n_paper += index < len(scenes)
        print(
            f"{index:2d} {r.name:31s} ours fc={r.fc!s:5s} hold={r.hold!s:5s} eps={r.eps:.3f} off {r.dist_mm:5.1f} mm"
            f" {r.angle_deg:5.1f} deg {r.plan_s:4.1f} s (one process {r.one_s:4.1f} s, {r.one_cpu_s:4.1f} cpu"
            f"{'' if r.same_plan else ', OTHER PLAN'}) | baseline fc={r.base_fc!s:5s}"
            f" hold={r.base_hold!s:5s} pieces {r.pieces_hold!s:5s}/{r.base_pieces_hold!s:5s}"
            f" off {r.base_dist_mm:5.1f} mm",
            flush=True,
        )
    if rows:
        _print_table(rows, n_paper, seed)
    return rows


def _print_table(rows: list[Row], n_paper: int, seed: int) -> None:
    """The figures of one seed's objects (the first ``n_paper`` are scene instances)."""
    paper = rows[:n_paper]
    other = rows[n_paper:]
    dists = np.array([r.dist_mm for r in rows])
    angles = np.array([r.angle_deg for r in rows])
    print()
    print(f"{'figure':44s} {'planner':>18s} {'baseline: close at demo':>24s}")
    for label, subset in (("scenes", paper), ("randomised objects", other), ("all", rows)):
        print(f"{'force closure, ' + label:44s} {_share(subset, 'fc'):>18s} {_share(subset, 'base_fc'):>24s}")
        held, base_held = _share(subset, "hold"), _share(subset, "base_hold")
        print(f"{'holds under the bench hold test, ' + label:44s} {held:>18s} {base_held:>24s}")
        cut, base_cut = _share(subset, "pieces_hold"), _share(subset, "base_pieces_hold")
        print(f"{'  (bench test, part in convex pieces), ' + label:44s} {cut:>18s} {base_cut:>24s}")
        old, base_old = _share(subset, "old_hold"), _share(subset, "base_old_hold")
        print(f"{'  (former shake test, same model), ' + label:44s} {old:>18s} {base_old:>24s}")
        crop, base_crop = _share(subset, "crop_hold"), _share(subset, "base_crop_hold")
        print(f"{'  (bench test, part+mount one body), ' + label:44s} {crop:>18s} {base_crop:>24s}")
    scene_names = sorted({r.name.split(" seed")[0] for r in paper})
    fc_tasks = sum(any(r.fc for r in paper if r.name.startswith(n + " seed")) for n in scene_names)
    print(f"{'paper tasks with a force closure (any seed)':44s} {f'{fc_tasks}/{len(scene_names)}':>18s}")
    print(f"{'offset from demo, median / max (mm)':44s} {f'{np.nanmedian(dists):.1f} / {np.nanmax(dists):.1f}':>18s}")
    print(f"{'angle from demo, median / max (deg)':44s} {f'{np.nanmedian(angles):.1f} / {np.nanmax(angles):.1f}':>18s}")
    _print_timing(rows, "")
    print(f"objects: {len(rows)} ({len(paper)} scene instances + {len(other)} randomised), seed {seed}")
    print(f"targets: force closure on 4/4 paper tasks, 95% hold, < {PLAN_TARGET_S:.0f} s per plan on 2 cores")


def _print_timing(rows: list[Row], label: str) -> None:
    """Planning time (wall) with the worker processes and in one process: median / max and how many within
    ``PLAN_TARGET_S``; how many plans came out the same both ways."""
    for name, times in (
        ("planning time, with workers", np.array([r.plan_s for r in rows])),
        ("planning time, one process", np.array([r.one_s for r in rows])),
        ("planning CPU, one process", np.array([r.one_cpu_s for r in rows])),
    ):
        if np.all(np.isnan(times)):
            continue
        within = int(np.sum(times <= PLAN_TARGET_S))
        figure = f"{np.median(times):.2f} / {times.max():.2f}, {within}/{len(rows)} <= {PLAN_TARGET_S:.0f} s"
        baseline = "0 (no search)" if name.endswith("workers") else ""
        print(f"{name + ' median / max (s)' + label:44s} {figure:>26s} {baseline:>16s}")
    if not all(math.isnan(r.one_s) for r in rows):
        same = sum(r.same_plan for r in rows)
        print(f"{'same plan with workers and in one process' + label:44s} {f'{same}/{len(rows)}':>26s}")


def main() -> int:
    """Run the benchmark on each seed and print the tables (and, for several seeds, the figures of them all)."""
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--quick", action="store_true", help="1 seed per scene and 6 random objects")
    parser.add_argument("--objects", type=int, default=None, help="number of randomised objects (default 21)")
    parser.add_argument("--scene-seeds", type=int, default=None, help="seeds 0..N-1 of each scene (default 3)")
    parser.add_argument(
        "--seed", type=int, nargs="+", default=[7], help="benchmark seeds (default 7; 11 and 13 were held out)"
    )
    parser.add_argument("--only", default=None, help="only the objects whose 'index:name' contains this text")
    parser.add_argument("--execute", action="store_true", help="also learn and execute pbd synth seeds 0-9")
    parser.add_argument(
        "--no-peer", action="store_true", help="do not plan again in one process (the planning time's peer)"
    )
    args = parser.parse_args()
    rows: list[Row] = []
    for seed in args.seed:
        if len(args.seed) > 1:
            print(f"== seed {seed}", flush=True)
        rows += run_seed(seed, args)
        if len(args.seed) > 1:
            print()
    if rows and len(args.seed) > 1:
        seeds = " ".join(str(s) for s in args.seed)
        print(f"{'holds under the bench hold test, seeds ' + seeds:44s} {_share(rows, 'hold'):>18s}", end="")
        print(f" {_share(rows, 'base_hold'):>24s}")
        print(f"{'  (part in convex pieces), seeds ' + seeds:44s} {_share(rows, 'pieces_hold'):>18s}", end="")
        print(f" {_share(rows, 'base_pieces_hold'):>24s}")
        _print_timing(rows, ", all seeds")
    if args.execute:
        execute_learned(range(10), args.only)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
