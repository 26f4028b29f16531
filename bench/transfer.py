"""Benchmark: transfer of a functional axis between similar objects, against plain ICP, measured in one run.

Random shape pairs: a source model (full surface, 0.3 mm noise) and a target made of an independent sampling of
the same surface under a random similarity (scale 0.7 to 1.4, any rotation, a shift up to 0.5 m), cut to a
partial scan keeping 50 to 100 % of the surface (half by a random plane, half by a random view direction) with
0.3 mm noise. Built-in scene pairs: instance A of a scene (``tasks.scenes``: its digitizer model, 9 000
points) as the source, instance B (other sizes, placement, cap or handle) under the same random similarity,
partial scan and noise as the target; the true axes are the scenes' kinematics. A scan that keeps less than
60 % of the functional part is drawn again: no registration can place a part the scan does not show. The axes
are carried by the estimated transform and compared with the true ones: worst direction error over the chain
(degrees) and worst position error (mm, the true axis point to the carried line; rotations only).

Baselines in the same run: the paper's plain ICP (rigid, from the identity, no scale) and, to isolate what
the missing scale costs, rigid ICP started at the true pose (scene pairs: at B's placement relative to A's).

The bottle experiment (Dang & Allen: a cap-twist descriptor taken to a novel bottle, 6 degrees and 4 mm with
ICP): bottle A's cap axis carried to bottle B of another size and shape, whose true cap axis is known.

``--simulate`` (issue 6's done-criterion): ``pbd synth`` recordings of bottle instances A and B, the descriptor
learned from A's, transferred onto B's recorded object model, executed in instance B in pybullet; beside it
the paper's plain-ICP transfer, the untransferred descriptor on B and the learned one on its own instance A.

    .venv/bin/python bench/transfer.py [--quick] [--pairs N] [--scene-pairs N] [--seed N]
    .venv/bin/python bench/transfer.py --simulate [--pairs N] [--seed N] [--scene NAME]
    .venv/bin/python bench/transfer.py --families [--pairs N] [--family F] [--dev-only | --held-out-only] [--points N]
        [--occluded]
"""

from __future__ import annotations

import argparse
import sys
import time
from dataclasses import dataclass, replace
from pathlib import Path
from tempfile import TemporaryDirectory

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from bench.cases.scene_models import scene_model
from bench.cases.transfer_pairs import FAMILIES, TransferPair, make_pair
from schemas.descriptor import Descriptor, Grasp, ObjectRef, Primitive
from tasks.errors import PbdError
from tasks.ingest.api import ingest_recording
from tasks.learn.api import learn_descriptor
from tasks.learn.params import LearnParams
from tasks.recording.load import load_recording
from tasks.rotations import quat_tuple_from_matrix
from tasks.scenes.catalog import SCENE_NAMES, build_scene
from tasks.scenes.kinematics import truth_descriptor
from tasks.simulate.api import simulate_descriptor
from tasks.store import Store
from tasks.synth.record import synthesize
from tasks.transfer.api import MAX_SPREAD_DEG, MAX_SPREAD_MM, plausible_alternatives, transfer_descriptor
from tasks.transfer.axes import PlacedAxes, place_axes, placed_spread
from tasks.transfer.carry import carry_chain, carry_grasp, carry_primitive, grip_points
from tasks.transfer.clouds import bbox_diagonal, check_model, functional_mask, plain_icp
from tasks.transfer.registration import Registration, RegistrationParams, register_models
from tasks.transfer.similarity import Similarity, angle_between_deg, point_line_distance
from tests.transfer import shapes

NOISE_M = 3e-4
LARGE_FACTOR = 3
"""Cabinets and drawers (0.3 to 0.6 m) get 3x the points of the small objects (9 000 per model, about 7 mm
apart), so that their knob or handle, the only detail that breaks the box's symmetry, is sampled at all."""
PAPER_DEG, PAPER_MM = 6.0, 4.0
GOOD_DEG, GOOD_MM = 3.0, 3.0
"""A pair within these (the worst-case targets) counts as good when judging the warnings."""


@dataclass(frozen=True)
class Outcome:
    """Errors of one pair for one method."""

    deg: float
    mm: float


def axis_error(est: Similarity, truth_pos: np.ndarray, truth_dir: np.ndarray, model: shapes.ShapeModel) -> Outcome:
    """Direction error (deg) and point-to-line error (mm) of the axis carried by ``est``."""
    d = est.apply_direction(model.axis_dir)
    p = est.apply_point(model.axis_pos)
    return Outcome(angle_between_deg(d, truth_dir), point_line_distance(truth_pos, p, d) * 1e3)


def chain_error(
    est: Similarity | tuple[Similarity, ...], chain: tuple[Primitive, ...], truth: tuple[Primitive, ...]
) -> Outcome:
    """Worst direction error (deg) and worst axis position error (mm, true axis point to the carried line; NaN
    when no primitive has an axis point) over ``chain`` carried by ``est`` (one transform, or one per
    primitive), against ``truth`` (target frame)."""
    degs, mms = [], []
    per_prim = est if isinstance(est, tuple) else (est,) * len(chain)
    for prim, true, transform in zip(chain, truth, per_prim, strict=True):
        moved = carry_primitive(prim, transform)
        degs.append(angle_between_deg(np.array(moved.dir), np.array(true.dir)))
        if moved.pos is not None and true.pos is not None:
            mms.append(point_line_distance(np.array(true.pos), np.array(moved.pos), np.array(moved.dir)) * 1e3)
    return Outcome(max(degs), max(mms) if mms else float("nan"))


@dataclass(frozen=True)
class Pair:
    """One benchmark pair: source model, target scan, the true similarity between them and the chain to carry."""

    label: str
    source: np.ndarray
    target: np.ndarray
    truth: Similarity
    keep: float
    view: bool
    chain: tuple[Primitive, ...]
    """The axes to carry, source frame."""
    truth_chain: tuple[Primitive, ...]
    """The same axes on the target, target frame."""
    focus: np.ndarray
    grip: np.ndarray
    rigid_truth: Similarity
    """The true pose without scale (source -> target): for scene pairs, instance B's placement relative to A's."""


def _axis_primitive(pos: np.ndarray, direction: np.ndarray, kind: str = "rotation") -> Primitive:
    """A primitive of ``kind`` along ``direction`` whose axis passes through ``pos`` (kept for a translation too,
    to measure where its line lands)."""
    return Primitive(kind, (float(pos[0]), float(pos[1]), float(pos[2])), tuple(float(v) for v in direction), 1.0)  # type: ignore[arg-type]


def partial_target(
    rng: np.random.Generator, points: np.ndarray, normals: np.ndarray, focus: np.ndarray
) -> tuple[np.ndarray, Similarity, float, bool]:
    """A partial, noisy scan of ``points`` under a random similarity: (scan, similarity, kept fraction, view cut).

    A scan that keeps less than 60 % of the functional part is drawn again: no registration can place a part
    the scan does not show."""
    scale = float(rng.uniform(0.7, 1.4))
    truth = Similarity(scale, shapes.random_rotation(rng), rng.uniform(-0.5, 0.5, size=3))
    keep = float(rng.uniform(0.5, 1.0))
    view = bool(rng.integers(0, 2))
    radius = 0.18 * bbox_diagonal(points)
    full = functional_mask(points, focus, radius).sum()
    for _ in range(100):
        pts, _ = shapes.partial_scan(points, normals, rng, keep, view=view)
        if functional_mask(pts, focus, radius).sum() >= 0.6 * full:
            break
    return truth.apply_points(pts) + rng.normal(scale=NOISE_M, size=pts.shape), truth, keep, view


def shape_pair(rng: np.random.Generator, kind: str, points: int) -> Pair:
    """A random shape sampled twice: one sampling the source, the other the target's scan."""
    n = 2 * points * (LARGE_FACTOR if kind in {"cabinet", "drawer"} else 1)
    model = shapes.random_shape(rng, n=n, kind=kind)
    idx = rng.permutation(len(model.points))
    src_idx, tgt_idx = idx[: n // 2], idx[n // 2 :]
    source = model.points[src_idx] + rng.normal(scale=NOISE_M, size=(len(src_idx), 3))
    target, truth, keep, view = partial_target(rng, model.points[tgt_idx], model.normals[tgt_idx], model.focus)
    chain = (_axis_primitive(model.axis_pos, model.axis_dir, model.kind),)
    rigid = Similarity(1.0, truth.rotation, truth.translation)
    moved = carry_chain(chain, truth)
    # the grasped part is focus[0] (knob, handle, cap or lid): one point, as ``pbd transfer`` takes the grip from
    # the grasp, not the axis points too
    return Pair(model.name, source, target, truth, keep, view, chain, moved, model.focus, model.focus[:1], rigid)


def scene_pair(rng: np.random.Generator, scene: str, seed_a: int, seed_b: int, points: int) -> Pair:
    """Instance ``seed_a`` of a built-in scene as the source, instance ``seed_b`` (other sizes, placement,
    handle or cap) as the target's scan; the true chains from the scene kinematics."""
    a = scene_model(scene, seed_a, points, rng)
    b = scene_model(scene, seed_b, points, rng)
    source = a.points + rng.normal(scale=NOISE_M, size=a.points.shape)
    target, truth, keep, view = partial_target(rng, b.points, b.normals, b.focus)
    label = f"{scene} {seed_a}>{seed_b}"
    rigid = Similarity(1.0, truth.rotation, truth.translation).compose(b.placement.compose(a.placement.inverse()))
    moved = carry_chain(b.truth.chain, truth)
    return Pair(label, source, target, truth, keep, view, a.truth.chain, moved, a.focus, a.grip, rigid)


def placed(
    reg: Registration,
    models: tuple[np.ndarray, np.ndarray],
    chain: tuple[Primitive, ...],
    grip: np.ndarray,
) -> PlacedAxes:
    """The axes placed as ``pbd transfer`` places them after the registration ``reg`` of (source, target)."""
    source, target = check_model(models[0], "source"), check_model(models[1], "target")
    return place_axes(
        chain, source, target, best=reg.best.transform, grip=grip, threshold_m=reg.threshold_m,
        spacing_m=reg.spacing_m,
    )  # fmt: skip


def flagged(
    reg: Registration, chain: tuple[Primitive, ...], axes: PlacedAxes, models: tuple[np.ndarray, np.ndarray]
) -> str:
    """Why ``pbd transfer`` would warn ("" when it would not): ``fit`` (a poor fit: fitness, surface RMSE or
    two-way score), ``spread`` (equally good alignments placing the axes differently) and/or ``local`` (the
    model about an axis disagrees with its placement)."""
    source, target = check_model(models[0], "source"), check_model(models[1], "target")
    deg, metres = placed_spread(chain, source, target, axes, plausible_alternatives(reg))
    spread = deg > MAX_SPREAD_DEG or metres * 1e3 > MAX_SPREAD_MM
    local = bool(axes.warnings)
    return "+".join(why for why, on in (("fit", reg.poor), ("spread", spread), ("local", local)) if on)


def summary(rows: list[Outcome]) -> tuple[float, float, float, float]:
    """(median deg, worst deg, median mm, worst mm); degrees over the rows placed, mm over those with an axis
    point."""
    deg = np.array([r.deg for r in rows if np.isfinite(r.deg)] or [np.nan])
    mm = np.array([r.mm for r in rows if np.isfinite(r.mm)] or [np.nan])
    return float(np.median(deg)), float(deg.max()), float(np.median(mm)), float(mm.max())


@dataclass
class Results:
    """Per-pair outcomes of one benchmark set."""

    ours: list[Outcome]
    glob: list[Outcome]
    """The global similarity alone (before the axes are placed)."""
    icp: list[Outcome]
    icp_true: list[Outcome]
    warned: list[str]
    good: list[bool]
    cpu_s: float = 0.0


def run_set(pairs: list[tuple[int, Pair]]) -> Results:
    """Register every pair (ours, plain ICP, rigid ICP from the true pose); one printed row per pair."""
    res = Results([], [], [], [], [], [])
    for i, pair in pairs:
        t0 = time.process_time()
        try:
            reg = register_models(
                pair.source, pair.target, focus=pair.focus, grip=pair.grip, rng=np.random.default_rng(i)
            )
        except PbdError as err:  # refused outright (no alignment at a similar object's scale): no axis placed
            res.cpu_s += time.process_time() - t0
            res.ours.append(Outcome(float("nan"), float("nan")))
            res.glob.append(Outcome(float("nan"), float("nan")))
            res.warned.append(f"refused: {err}")
            res.good.append(False)
            fitness = float("nan")
        else:
            axes = placed(reg, (pair.source, pair.target), pair.chain, pair.grip)
            res.cpu_s += time.process_time() - t0
            res.ours.append(chain_error(axes.transforms, pair.chain, pair.truth_chain))
            res.glob.append(chain_error(reg.best.transform, pair.chain, pair.truth_chain))
            res.warned.append(flagged(reg, pair.chain, axes, (pair.source, pair.target)))
            res.good.append(res.ours[-1].deg <= GOOD_DEG and not res.ours[-1].mm > GOOD_MM)
            fitness = reg.best.fitness
        res.icp.append(chain_error(plain_icp(pair.source, pair.target), pair.chain, pair.truth_chain))
        rigid_true = pair.rigid_truth
        from_true = plain_icp(rigid_true.apply_points(pair.source), pair.target).compose(rigid_true)
        res.icp_true.append(chain_error(from_true, pair.chain, pair.truth_chain))
        o, c, t = res.ours[-1], res.icp[-1], res.icp_true[-1]
        print(
            f"{i:3d} {pair.label:22} {pair.truth.scale:5.2f} {pair.keep:4.2f} {'view' if pair.view else 'cut':4} | "
            f"{o.deg:8.2f} {o.mm:7.2f} {fitness:4.2f} | {c.deg:8.1f} {c.mm:7.1f} | "
            f"{t.deg:12.2f} {t.mm:6.2f} | "
            f"{time.process_time() - t0:4.1f}{f'  WARNED ({res.warned[-1]})' if res.warned[-1] else ''}",
            flush=True,
        )
    return res


def print_summary(title: str, res: Results) -> None:
    """Median and worst errors of ours and the baselines, and how the warnings fall."""
    n = len(res.ours)
    warned_good = sum(bool(w) and g for w, g in zip(res.warned, res.good, strict=True))
    missed_bad = sum(not w and not g for w, g in zip(res.warned, res.good, strict=True))
    print(
        f"\n{title}: {n} pairs, CPU {res.cpu_s / max(n, 1):.1f} s per registration; "
        f"warned {sum(map(bool, res.warned))} "
        f"({warned_good} of them within {GOOD_DEG:g} deg / {GOOD_MM:g} mm), unwarned beyond that: {missed_bad}"
    )
    print(f"{'method':38} {'median deg':>10} {'worst deg':>10} {'median mm':>10} {'worst mm':>10}")
    trusted = [o for o, w in zip(res.ours, res.warned, strict=True) if not w]
    for label, rows in (
        ("ours (similarity, functional part)", res.ours),
        ("ours, pairs without a warning", trusted or res.ours),
        ("ours, global similarity alone", res.glob),
        ("plain ICP from identity (paper)", res.icp),
        ("rigid ICP from the true pose, no scale", res.icp_true),
    ):
        med_d, max_d, med_m, max_m = summary(rows)
        print(f"{label:38} {med_d:10.2f} {max_d:10.2f} {med_m:10.2f} {max_m:10.2f}")
    print(f"{'target':38} {'< 1':>10} {'< 3':>10} {'< 1':>10} {'< 3':>10}")


def run_pairs(n_pairs: int, n_scene: int, seed: int, points: int, only: int | None = None) -> None:
    """Random shape pairs (pair i from generator (seed, i)) and built-in scene pairs (instances 2k and 2k+1 of
    each scene, offset by ``seed``), then the summaries of both and of all pairs together."""
    print(
        f"{'#':>3} {'pair':22} {'scale':>5} {'keep':>4} {'cut':4} | {'ours deg':>8} {'mm':>7} {'fit':>4} | "
        f"{'ICP deg':>8} {'mm':>7} | {'ICP@true deg':>12} {'mm':>6} | {'s':>4}"
    )
    kinds = shapes.SHAPE_KINDS
    shape_rows = [(i, shape_pair(np.random.default_rng([seed, i]), kinds[i % len(kinds)], points))
                  for i in (range(n_pairs) if only is None else [only])]  # fmt: skip
    shape_res = run_set(shape_rows)
    scene_rows = []
    for k in range(n_scene):
        for j, scene in enumerate(SCENE_NAMES):
            i = 100 + k * len(SCENE_NAMES) + j
            if only is None or only == i:
                rng = np.random.default_rng([seed, i])
                scene_rows.append((i, scene_pair(rng, scene, 1000 * seed + 2 * k, 1000 * seed + 2 * k + 1, 3 * points)))
    scene_res = run_set(scene_rows) if scene_rows else None
    if shape_rows:
        print_summary(f"random shapes (seed {seed})", shape_res)
    if scene_res is not None:
        print_summary("built-in scenes, instance A -> instance B", scene_res)
        if shape_rows:
            both = Results(
                *(
                    getattr(shape_res, f) + getattr(scene_res, f)
                    for f in ("ours", "glob", "icp", "icp_true", "warned", "good")
                )
            )
            both.cpu_s = shape_res.cpu_s + scene_res.cpu_s
            print_summary("all pairs", both)


def run_bottles(trials: int, seed: int, points: int, only: int | None = None) -> None:
    """The paper's bottle experiment: bottle A's cap axis carried to a novel bottle B."""
    bottle_a = {
        "radius": 0.035,
        "height": 0.16,
        "shoulder": 0.04,
        "neck_radius": 0.013,
        "neck": 0.02,
        "cap_radius": 0.016,
        "cap": 0.02,
    }
    bottle_b = {
        "radius": 0.03,
        "height": 0.2,
        "shoulder": 0.06,
        "neck_radius": 0.0115,
        "neck": 0.03,
        "cap_radius": 0.0145,
        "cap": 0.017,
    }
    ours: list[Outcome] = []
    icp: list[Outcome] = []
    whole: list[Outcome] = []
    glob: list[Outcome] = []
    warned = 0
    for i in range(trials) if only is None else [only]:
        rng = np.random.default_rng([seed, 1000 + i])
        a = shapes.bottle(rng, n=points, **bottle_a)
        b = shapes.bottle(rng, n=points, **bottle_b)
        source = a.points + rng.normal(scale=NOISE_M, size=a.points.shape)
        truth = Similarity(1.0, shapes.random_rotation(rng), rng.uniform(-0.5, 0.5, size=3))
        keep = float(rng.uniform(0.6, 1.0))
        pts, _ = shapes.partial_scan(b.points, b.normals, rng, keep, view=True)
        target = truth.apply_points(pts) + rng.normal(scale=NOISE_M, size=pts.shape)
        t_pos, t_dir = truth.apply_point(b.axis_pos), truth.apply_direction(b.axis_dir)
        reg = register_models(source, target, focus=a.focus, grip=a.focus, rng=rng)
        cap = (_axis_primitive(a.axis_pos, a.axis_dir),)
        axes = placed(reg, (source, target), cap, a.focus)
        ours.append(axis_error(axes.transforms[0], t_pos, t_dir, a))
        glob.append(axis_error(reg.best.transform, t_pos, t_dir, a))
        warned += bool(flagged(reg, cap, axes, (source, target)))
        reg_w = register_models(source, target, focus=a.focus, params=RegistrationParams(whole=True), rng=rng)
        whole.append(axis_error(reg_w.best.transform, t_pos, t_dir, a))
        icp.append(axis_error(plain_icp(source, target), t_pos, t_dir, a))
    print()
    print(
        f"bottle experiment: cap axis of bottle A (r 35 mm, h 230 mm) carried to bottle B (r 30 mm, h 290 mm, "
        f"cap r 14.5 mm), {len(ours)} poses, scans keeping 60-100 %; warned (functional): {warned}"
    )
    print(f"{'method':38} {'median deg':>10} {'worst deg':>10} {'median mm':>10} {'worst mm':>10}")
    for label, rows in (
        ("ours (functional part: the cap)", ours),
        ("ours, global similarity alone", glob),
        ("ours, whole model (global alone)", whole),
        ("plain ICP from identity", icp),
    ):
        med_d, max_d, med_m, max_m = summary(rows)
        print(f"{label:38} {med_d:10.2f} {max_d:10.2f} {med_m:10.2f} {max_m:10.2f}")
    print(f"{'paper (ICP, Dang & Allen)':38} {PAPER_DEG:10.2f} {'':>10} {PAPER_MM:10.2f}")


@dataclass(frozen=True)
class SimOutcome:
    """One recorded transfer A -> B executed in instance B: axis errors against B's truth and three executions."""

    error: Outcome
    """The transferred (learned) chain against B's true chain: learning and transfer errors together."""
    registration_error: Outcome
    """A's true chain carried by the registration against B's: the transfer's own error."""
    scale: float
    warned: bool
    ours: str
    replanned: str
    """The transfer with ``--replan-grasp`` (the grasp planned anew on B's model), executed in B."""
    icp: str
    untransferred: str
    own: str
    """The learned descriptor executed in its own instance A (what the transfer can at best keep)."""


def _execute(desc: Descriptor, scene: str, seed: int) -> str:
    """``success`` or why not: the descriptor executed in instance ``seed`` of ``scene``."""
    try:
        result = simulate_descriptor(desc, scene=scene, rng=np.random.default_rng(seed))
    except PbdError as err:
        return f"refused: {str(err)[:60]}"
    return "success" if result.success else f"failed: {'; '.join(result.notes)[:60] or 'extent not reached'}"


def simulate_pair(scene: str, seed_a: int, seed_b: int, work: Path) -> SimOutcome:
    """Issue 6's done-criterion for one pair: ``pbd synth`` instances A and B, learn A, transfer to B's recorded
    object model (as ``pbd transfer D --to B.mcap``), execute in instance B; the paper's plain-ICP transfer and
    the untransferred descriptor executed there too."""
    store = Store(work / "store")
    recs = []
    for s in (seed_a, seed_b):
        path = work / f"{scene}-{s}.mcap"
        if not path.exists():
            synthesize(scene, s, path)
        recs.append(load_recording(store, ingest_recording(path, store).recording_id))
    source = learn_descriptor(recs[0], LearnParams(), rng=np.random.default_rng(seed_a))
    src_pts = np.asarray(recs[0].object_model, dtype=np.float64)
    tgt_pts = np.asarray(recs[1].object_model, dtype=np.float64)
    target = ObjectRef(scene, None, len(tgt_pts))
    result = transfer_descriptor(source, src_pts, tgt_pts, target, rng=np.random.default_rng(seed_b))
    replanned = transfer_descriptor(
        source, src_pts, tgt_pts, target, replan_grasp=True, rng=np.random.default_rng(seed_b)
    ).descriptor
    truth = truth_descriptor(build_scene(scene, seed_b)).chain
    truth_a = truth_descriptor(build_scene(scene, seed_a)).chain
    truth_desc_a = truth_descriptor(build_scene(scene, seed_a))
    axes = placed(result.registration, (src_pts, tgt_pts), truth_a, grip_points(truth_desc_a, src_pts))
    registration_error = chain_error(axes.transforms, truth_a, truth)
    moved = result.descriptor.chain
    same = [p.kind for p in moved] == [t.kind for t in truth]
    error = chain_error(Similarity.identity(), moved, truth) if same else Outcome(float("inf"), float("inf"))
    icp = plain_icp(src_pts, tgt_pts)
    grasp = carry_grasp(source.grasp, icp) if source.grasp is not None else None
    by_icp = replace(result.descriptor, chain=carry_chain(source.chain, icp), grasp=grasp)
    return SimOutcome(
        error,
        registration_error,
        result.registration.best.transform.scale,
        result.poor,
        _execute(result.descriptor, scene, seed_b),
        _execute(replanned, scene, seed_b),
        _execute(by_icp, scene, seed_b),
        _execute(source, scene, seed_b),
        _execute(source, scene, seed_a),
    )


def run_simulation(n_pairs: int, seed: int, scene: str = "bottle") -> None:
    """Pairs (A, B) = (seed + 2k, seed + 2k + 1) of ``scene``: transfer the learned descriptor and execute it."""
    print(
        f"{'A':>4} {'B':>4} | {'deg':>5} {'mm':>6} {'reg deg':>7} {'mm':>6} {'scale':>5} | {'ours on B':28} | "
        f"{'re-planned on B':20} | "
        f"{'plain ICP on B':28} | "
        f"{'untransferred on B':20} | learned, on A"
    )
    rows: list[SimOutcome] = []
    with TemporaryDirectory() as tmp:
        for k in range(n_pairs):
            a, b = seed + 2 * k, seed + 2 * k + 1
            row = simulate_pair(scene, a, b, Path(tmp))
            rows.append(row)
            print(
                f"{a:4d} {b:4d} | {row.error.deg:5.2f} {row.error.mm:6.2f} {row.registration_error.deg:7.2f} "
                f"{row.registration_error.mm:6.2f} {row.scale:5.3f} | {row.ours[:28]:28} | {row.replanned[:20]:20} | "
                f"{row.icp[:28]:28} | {row.untransferred[:20]:20} | {row.own[:40]}{'  WARNED' if row.warned else ''}",
                flush=True,
            )
    med_d, max_d, med_m, max_m = summary([r.error for r in rows])
    print(
        f"\n{scene} A -> B (pbd synth instances, learned from A's recording, transferred to B's recorded model, "
        f"executed in instance B): axis {med_d:.2f} deg / {med_m:.2f} mm median, {max_d:.2f} / {max_m:.2f} worst"
    )
    med_d, max_d, med_m, max_m = summary([r.registration_error for r in rows])
    print(
        f"  registration alone (A's true axis carried, against B's): {med_d:.2f} deg / {med_m:.2f} mm median, "
        f"{max_d:.2f} / {max_m:.2f} worst; warned {sum(r.warned for r in rows)}"
    )
    for label, key, where in (
        ("ours", "ours", "B"),
        ("ours, grasp re-planned", "replanned", "B"),
        ("plain ICP (paper)", "icp", "B"),
        ("untransferred", "untransferred", "B"),
        ("learned descriptor", "own", "A (its own instance)"),
    ):
        wins = sum(getattr(r, key) == "success" for r in rows)
        print(f"  {label:22} executes on {where}: {wins}/{len(rows)}")


FAMILY_DEV_SEEDS = tuple(range(6))
"""Development pairs of every family (``bench/cases/transfer_pairs.py``): the only pairs constants are tried on."""
FAMILY_HELDOUT_SEEDS = tuple(range(1000, 1020))
"""Held-out pairs of every family: run and printed, never tuned on."""
TARGET_MEDIAN = (1.0, 1.0)
TARGET_MAX = (3.0, 3.0)
"""Issue 31's bounds on the transferred axis (degrees, mm), median and worst, beyond the learned axis's error."""


def family_descriptor(pair: TransferPair) -> Descriptor:
    """The demonstrated object's descriptor with its true axis as the learned one (isolating the registration)
    and the hand 80 mm out from the grasped part, palm facing it."""
    src = pair.source
    approach = -src.approach
    side = np.cross(approach, [1.0, 0.0, 0.0] if abs(approach[0]) < 0.9 else [0.0, 1.0, 0.0])
    side /= np.linalg.norm(side)
    palm = np.column_stack([side, np.cross(approach, side), approach])
    wrist = src.grip + 0.08 * src.approach
    extent = 1.0 if src.kind == "rotation" else 0.2
    prim = Primitive(src.kind, tuple(float(v) for v in src.axis_pos), tuple(float(v) for v in src.axis_dir), extent,
                     fit={"pos_std_m": 0.0, "dir_std_rad": 0.0})  # type: ignore[arg-type]  # fmt: skip
    grasp = Grasp("barrett", (0.0, 0.0), tuple(float(v) for v in wrist), quat_tuple_from_matrix(palm))  # type: ignore[arg-type]
    return Descriptor(
        name=f"{pair.family}-{pair.seed}",
        action="open",
        object=ObjectRef(pair.family, None, len(src.points)),
        grasp=grasp,
        chain=(prim,),
        recording_id="0" * 16,
        parameters={},
        code_version="bench",
    )


@dataclass(frozen=True)
class FamilyRow:
    """One family pair: ours (errors, refused or not) and plain ICP's errors."""

    family: str
    ours: Outcome
    refused: bool
    why: str
    icp: Outcome
    sigma: Outcome = Outcome(float("nan"), float("nan"))
    """The registration's one-sigma uncertainty of the axis ours placed (degrees, mm; NaN when nothing was
    placed), whether written or refused: the error over it shows how well the sigma is calibrated."""


def family_error(prim: Primitive, pair: TransferPair) -> Outcome:
    """Direction error (deg) and point-to-line error (mm; NaN for a translation) of a carried primitive."""
    deg = angle_between_deg(np.array(prim.dir), pair.target_axis_dir)
    if prim.kind != "rotation" or prim.pos is None:
        return Outcome(deg, float("nan"))
    return Outcome(deg, point_line_distance(pair.target_axis_pos, np.array(prim.pos), np.array(prim.dir)) * 1e3)


def run_family_pair(pair: TransferPair) -> FamilyRow:
    """Transfer the pair's descriptor as ``pbd transfer`` does, and carry it by plain ICP (the paper)."""
    desc = family_descriptor(pair)
    target = ObjectRef(f"{pair.family}-novel", None, len(pair.target))
    sigma = Outcome(float("nan"), float("nan"))
    try:
        result = transfer_descriptor(
            desc, pair.source.points, pair.target, target, rng=np.random.default_rng(pair.seed)
        )
    except PbdError as err:
        ours, refused, why = Outcome(float("nan"), float("nan")), True, str(err)
    else:
        prim = result.descriptor.chain[0]
        ours, refused = family_error(prim, pair), result.poor
        why = "; ".join(result.reasons) if refused else ""
        pos_std, dir_std = prim.fit.get("registration_pos_std_m"), prim.fit.get("registration_dir_std_rad")
        sigma = Outcome(
            float(np.degrees(dir_std)) if isinstance(dir_std, float) else float("nan"),
            pos_std * 1e3 if isinstance(pos_std, float) and prim.kind == "rotation" else float("nan"),
        )
    icp = family_error(carry_primitive(desc.chain[0], plain_icp(pair.source.points, pair.target)), pair)
    return FamilyRow(pair.family, ours, refused, why, icp, sigma)


def _within(o: Outcome) -> bool:
    return o.deg <= TARGET_MAX[0] and not o.mm > TARGET_MAX[1]


def print_family_summary(title: str, rows: list[FamilyRow]) -> None:
    """Per family: ours over the pairs written (exit 0), refusals, wrong answers written; plain ICP over all."""
    print(f"\n{title}")
    print(
        f"{'family':10} {'pairs':>5} {'refused':>7} {'wrong':>5} | {'ours med deg':>12} {'max':>6} {'med mm':>7} "
        f"{'max':>6} | {'ICP med deg':>11} {'max':>6} {'med mm':>7} {'max':>6}"
    )
    for family in [*FAMILIES, "all"]:
        sel = [r for r in rows if family in {"all", r.family}]
        if not sel:
            continue
        written = [r.ours for r in sel if not r.refused]
        wrong = sum(not _within(o) for o in written)
        md, xd, mm_, xm = summary(written) if written else (float("nan"),) * 4
        id_, ixd, imm, ixm = summary([r.icp for r in sel])
        print(
            f"{family:10} {len(sel):5d} {len(sel) - len(written):7d} {wrong:5d} | {md:12.2f} {xd:6.2f} {mm_:7.2f} "
            f"{xm:6.2f} | {id_:11.1f} {ixd:6.1f} {imm:7.1f} {ixm:6.1f}"
        )
    print(f"{'target':10} {'':5} {'':7} {0:5d} | {'<= 1':>12} {'<= 3':>6} {'<= 1':>7} {'<= 3':>6}")
    print_calibration(rows)


def _sigma_decides(row: FamilyRow) -> bool:
    """The pair was written, or refused for the axis's sigma alone (not for a poor or ambiguous fit)."""
    return all(why.startswith("uncertain registration") for why in row.why.split("; ") if why)


def print_calibration(rows: list[FamilyRow]) -> None:
    """Error over the reported one-sigma of the pairs whose axis ours placed (written or refused), and of those
    where the sigma alone decides: for a calibrated sigma the position ratio (2-D, across the axis) is
    Rayleigh-like (median 1.18, 95 % under 2.45); a pair in another mode (a flipped or slid fit) is outside
    what a sigma describes and is refused by the other checks."""
    for label, part in (("position (mm)", "mm"), ("direction (deg)", "deg")):
        for which, sel in (("placed", rows), ("sigma decides", [r for r in rows if _sigma_decides(r)])):
            ratio = np.array(
                [getattr(r.ours, part) / getattr(r.sigma, part) for r in sel if getattr(r.sigma, part) > 0]
            )
            ratio = ratio[np.isfinite(ratio)]
            if not len(ratio):
                continue
            q = np.percentile(ratio, [10, 50, 90])
            print(
                f"error / sigma, {label}, {which}: {len(ratio)} pairs, 10/50/90 % {q[0]:.2f} / {q[1]:.2f} / "
                f"{q[2]:.2f}, max {ratio.max():.2f}; over 3: {int((ratio > 3.0).sum())}"
            )


def run_families(
    seeds: tuple[int, ...],
    title: str,
    families: tuple[str, ...],
    points: int | None = None,
    *,
    occluded: bool = False,
) -> list[FamilyRow]:
    """Every family's pairs of ``seeds``: one printed row per pair, then the summary; ``points``: surface samples
    of each full model instead of the family's default, ``occluded``: models and scans without what the object
    hides from their views (``make_pair``)."""
    if points is not None:
        title = f"{title}, {points} points per model"
    if occluded:
        title = f"{title}, occluded scans"
    print(f"\n{title}: seeds {', '.join(map(str, seeds))}")
    print(
        f"{'family':10} {'seed':>5} {'stretch':>14} {'keep':>4} {'v':>1} {'tilt':>4} | {'ours deg':>8} {'mm':>6} "
        f"{'':7} | {'sig deg':>7} {'mm':>6} | {'ICP deg':>7} {'mm':>6} | {'s':>4}"
    )
    rows = []
    for seed in seeds:
        for family in families:
            pair = make_pair(family, seed, points, occluded=occluded)
            t0 = time.process_time()
            row = run_family_pair(pair)
            rows.append(row)
            stretch = "x".join(f"{v:.2f}" for v in pair.stretch)
            status = "REFUSED" if row.refused else ("ok" if _within(row.ours) else "WRONG")
            print(
                f"{family:10} {seed:5d} {stretch:>14} {pair.keep:4.2f} {pair.views:1d} {pair.tilt_deg:4.1f} | "
                f"{row.ours.deg:8.2f} {row.ours.mm:6.2f} {status:7} | {row.sigma.deg:7.2f} {row.sigma.mm:6.2f} | "
                f"{row.icp.deg:7.1f} {row.icp.mm:6.1f} | "
                f"{time.process_time() - t0:4.1f}{'  ' + row.why[:150] if row.why else ''}",
                flush=True,
            )
    print_family_summary(f"{title} (ours over the transfers written; wrong: written beyond 3 deg / 3 mm)", rows)
    return rows


def main() -> None:
    """Parse the flags and run both parts."""
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--quick", action="store_true", help="10 pairs and 3 bottle poses")
    parser.add_argument("--pairs", type=int, default=None)
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--only", type=int, default=None, help="run pair (and bottle pose) number N only")
    parser.add_argument("--scene-pairs", type=int, default=None, help="pairs per built-in scene (default 5)")
    parser.add_argument("--simulate", action="store_true", help="only the recorded bottle A -> B pairs in pybullet")
    parser.add_argument("--scene", default="bottle", help="scene of --simulate (default bottle)")
    parser.add_argument("--families", action="store_true", help="issue 31's families: development and held-out pairs")
    parser.add_argument("--family", choices=FAMILIES, action="append", help="only this family (repeatable)")
    parser.add_argument("--held-out-only", action="store_true", help="with --families: the held-out part alone")
    parser.add_argument("--dev-only", action="store_true", help="with --families: the development part alone")
    parser.add_argument(
        "--extra-seeds", metavar="A-B", help="with --families: further development pairs A..B only (not held out)"
    )
    parser.add_argument(
        "--points", type=int, help="with --families: surface samples of each full model (another draw of each pair)"
    )
    parser.add_argument(
        "--occluded",
        action="store_true",
        help="with --families: the model and the scan leave out what the object hides from their views",
    )
    args = parser.parse_args()
    if args.families:
        families = tuple(args.family or FAMILIES)
        if args.extra_seeds is not None:
            first, last = (int(v) for v in args.extra_seeds.split("-"))
            extra = tuple(range(first, last + 1))
            if set(extra) & set(FAMILY_HELDOUT_SEEDS):
                parser.error("--extra-seeds: the held-out seeds 1000-1019 are not development pairs")
            run_families(extra, "further development pairs", families, args.points, occluded=args.occluded)
            return
        count = 1 if args.quick else args.pairs
        dev, held_out = FAMILY_DEV_SEEDS[:count], FAMILY_HELDOUT_SEEDS[:count]
        if args.only is not None:
            run_families((args.only,), "chosen pair", families, args.points, occluded=args.occluded)
            return
        if not args.held_out_only:
            run_families(dev, "development pairs", families, args.points, occluded=args.occluded)
        if not args.dev_only:
            run_families(held_out, "held-out pairs", families, args.points, occluded=args.occluded)
        return
    if args.simulate:
        run_simulation(args.pairs or (3 if args.quick else 10), args.seed, args.scene)
        return
    pairs = args.pairs if args.pairs is not None else (10 if args.quick else 40)
    scene_pairs = args.scene_pairs if args.scene_pairs is not None else (1 if args.quick else 5)
    run_pairs(pairs, scene_pairs, args.seed, 3000, args.only)
    run_bottles(3 if args.quick else 10, args.seed, 5000, args.only)


if __name__ == "__main__":
    main()
