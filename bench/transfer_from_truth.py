"""Diagnostic: the axis fits of the family benchmark started from the true pose.

For each pair of ``bench/cases/transfer_pairs.py``, ``axis_fit.fit_axes`` (the stretched fit of the whole model,
then the axis neighbourhood's fit) is started from the similarity that maps the demonstrated object onto the
novel one (exact for pairs stretched by one factor; the factors' geometric mean for the others). What it prints
is how far the fits move the axis from the truth when the global registration has nothing to get wrong: the
whole model's placement and the placed one (mm, deg), the reported one-sigma, and the stretch factors found
against the true ones (object axes x, y, z), and the whole model's own sigma at the axis, with the model's plane
normals and weights (``face_normals``) and with the smoothed normals, every pair informing. For hinged boxes
(cabinet, microwave) it also counts the scan's points on the door's edge face through the hinge (object frame:
within 4 mm of the hinge's side plane, 4-30 mm behind the door's front) and how many of their estimated normals lie
within ``stretch.NORMAL_COS`` of that face's normal: only those pairs count in the stretched fit. For a lever it
also measures what the protrusion alone (the lever, spindle and rose standing off the leaf) gives: the model's and
the scan's points standing more than ``PROTRUSION_SIGMAS`` noise sigmas off the leaf's plane within
``PROTRUSION_RADIUS_M`` of the spindle, and a point-to-plane fit of the scan's protrusion onto the model's across
the spindle (the leaf's plane fixes the rest), with the generator's exact normals, from the true placement and from
starts 10 mm off it: its error and its one-sigma (``protrusion_fit``), the best the protrusion's shape can do.

    OMP_NUM_THREADS=1 PYTHONPATH=. .venv/bin/python bench/transfer_from_truth.py [--family F] [--seeds 0 1 2]
        [--points N] [--protrusion-only]

``--points`` samples each full model with N points instead of the benchmark's (another pair per seed: the draws
after the sampling differ); ``--protrusion-only`` prints only the levers' protrusion lines.
"""

from __future__ import annotations

import argparse
import sys
from functools import partial
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from scipy.spatial import cKDTree

from bench.cases.transfer_pairs import FAMILIES, SOURCE_NOISE_M, TransferPair, make_pair
from bench.transfer import FAMILY_DEV_SEEDS, family_descriptor
from tasks.transfer.axis_fit import fit_axes
from tasks.transfer.carry import grip_points
from tasks.transfer.clouds import median_spacing
from tasks.transfer.face_normals import model_normals
from tasks.transfer.registration import RegistrationParams, prepare_target, surface_normals
from tasks.transfer.similarity import Similarity, angle_between_deg, point_line_distance
from tasks.transfer.stretch import (
    CORRELATED_POINTS,
    NORMAL_COS,
    STRETCH_POINTS,
    Stretched,
    line_spread,
    smoothed_normals,
)


def whole_sigmas(
    pair: TransferPair,
    whole: Stretched,
    line: tuple[np.ndarray, np.ndarray],
    fine_normals: np.ndarray,
    threshold: float,
) -> tuple[float, float]:
    """The whole model's position sigma at ``line`` (metres) from the sample ``fit_axes`` used, with the smoothed
    normals and every pair informing, and with the model's plane normals, weights and plane check
    (``face_normals``)."""
    points = pair.source.points
    smoothed = smoothed_normals(points, surface_normals(points, median_spacing(points)))
    model = model_normals(smoothed)
    pick = np.random.default_rng(pair.seed).permutation(len(points))[:STRETCH_POINTS]  # as fit_axes draws it
    out = []
    for normals, weight in ((smoothed, None), (model.normals, model.plane_weight[pick])):
        spread = line_spread(
            whole,
            points[pick],
            normals[pick],
            target=pair.target,
            target_normals=fine_normals,
            dist_m=threshold,
            line=line,
            plane_weight=weight,
            model=None if weight is None else (points, model.normals),
        )
        out.append(spread.pos_std_m)
    return out[0], out[1]


EDGE_FACE_M = 0.004
"""A scan point lies on the hinge side's plane when within 4 mm of it (object frame, before the stretch: a
cabinet's door edge is 3 mm inside the body's side) ..."""
DOOR_DEPTH_M = 0.03
"""... and on the door's edge face when 4-30 mm behind the door's front (doors are 18-22 mm thick)."""


def edge_face_normals(pair: TransferPair, normals: np.ndarray) -> tuple[int, int]:
    """Scan points on the door's edge face through the hinge, and how many of their ``normals`` ((m, 3) unit,
    unsigned, scan frame) lie within ``NORMAL_COS`` of its true normal."""
    obj = pair.scan_in_object_frame()
    hinge = pair.source.axis_pos
    behind = obj[:, 1] - hinge[1]
    on_face = (np.abs(obj[:, 0] - hinge[0]) < EDGE_FACE_M) & (behind > EDGE_FACE_M) & (behind < DOOR_DEPTH_M)
    true_normal = pair.rotation @ (np.array([1.0, 0.0, 0.0]) / pair.stretch)
    true_normal /= np.linalg.norm(true_normal)
    agree = np.abs(normals[on_face] @ true_normal) >= NORMAL_COS
    return int(on_face.sum()), int(agree.sum())


PROTRUSION_SIGMAS = 4.0
"""A point stands off the leaf when more than 4 noise sigmas off its plane (a Gaussian excursion beyond that: 3e-5,
under one of the few hundred leaf points about the spindle) ..."""
PROTRUSION_RADIUS_M = 0.15
"""... and within 150 mm of the spindle across it (the lever's arm reaches 120 mm from it, the rose 27 mm)."""
PROTRUSION_DIST_M = 0.02
"""Pairs of the protrusion's fit: a scan point and its nearest model point within 20 mm (a few scan spacings)."""
PROTRUSION_STARTS_M = 0.01
"""The fit also starts this far off the true placement along each direction across the spindle."""


def protrusion(points: np.ndarray, pos: np.ndarray, direction: np.ndarray, noise_m: float) -> np.ndarray:
    """(n,) bool: ``points`` standing more than ``PROTRUSION_SIGMAS`` x ``noise_m`` off the plane through ``pos``
    normal to unit ``direction`` (towards it), within ``PROTRUSION_RADIUS_M`` of the line (one frame, metres)."""
    rel = points - pos
    off = rel @ direction
    across = np.linalg.norm(rel - np.outer(off, direction), axis=1)
    out: np.ndarray = (off > PROTRUSION_SIGMAS * noise_m) & (across < PROTRUSION_RADIUS_M)
    return out


def protrusion_fit(
    scan: np.ndarray, model: np.ndarray, normals: np.ndarray, shift: np.ndarray, *, direction: np.ndarray
) -> tuple[np.ndarray, float]:
    """Point-to-plane fit of ``scan`` (m, 3) onto ``model`` (n, 3) with unit ``normals``, the model moved by a
    translation across unit ``direction`` from ``shift`` (3,): the translation found and its one-sigma RMS over
    the two directions across (metres; residual variance, ``CORRELATED_POINTS`` pairs counting as one)."""
    basis = np.linalg.svd(np.eye(3) - np.outer(direction, direction))[0][:, :2]
    tree = cKDTree(model)
    t = shift.copy()
    sigma = float("inf")
    for _ in range(50):
        dist, idx = tree.query(scan - t, distance_upper_bound=PROTRUSION_DIST_M)
        ok = np.isfinite(dist)
        if ok.sum() < 3:
            return t, float("inf")
        n = normals[idx[ok]]
        residual = ((scan[ok] - model[idx[ok]] - t) * n).sum(axis=1)
        jac = n @ basis
        info = jac.T @ jac
        if np.linalg.eigvalsh(info)[0] < 1e-9:
            return t, float("inf")
        step = np.linalg.solve(info, jac.T @ residual)
        t = t + basis @ step
        cov = np.linalg.inv(info) * CORRELATED_POINTS * float(np.mean(residual**2))
        sigma = float(np.sqrt(np.trace(cov) / 2.0))
        if np.linalg.norm(step) < 1e-6:
            break
    return t, sigma


def protrusion_line(pair: TransferPair) -> str:
    """The protrusion's counts and fits for a lever pair (source frame; the scan mapped back through the true
    similarity, so the true spindle lies where the novel object's stretch puts it)."""
    src = pair.source
    scale = float(np.prod(pair.stretch)) ** (1.0 / 3.0)
    scan = (pair.target - pair.shift) @ pair.rotation / scale
    true_pos = src.axis_pos * pair.stretch / scale
    model_mask = protrusion(src.points, src.axis_pos, src.axis_dir, SOURCE_NOISE_M)
    scan_mask = protrusion(scan, true_pos, src.axis_dir, pair.noise_m)
    truth = true_pos - src.axis_pos
    basis = np.linalg.svd(np.eye(3) - np.outer(src.axis_dir, src.axis_dir))[0][:, :2]
    scan_part, model_part = scan[scan_mask], src.points[model_mask]
    fit = partial(protrusion_fit, scan_part, model_part, src.normals[model_mask], direction=src.axis_dir)
    found, sigma = fit(truth)
    error_mm = float(np.linalg.norm(found - truth)) * 1e3
    worst_mm = 0.0
    for offset in ((1.0, 0.0), (-1.0, 0.0), (0.0, 1.0), (0.0, -1.0)):
        found, _ = fit(truth + basis @ np.array(offset) * PROTRUSION_STARTS_M)
        worst_mm = max(worst_mm, float(np.linalg.norm(found - truth)) * 1e3)
    return (
        f"protrusion: model {int(model_mask.sum()):3d} pts, scan {int(scan_mask.sum()):3d} pts | "
        f"fit from the truth {error_mm:5.1f} mm, sigma {sigma * 1e3:6.2f} mm | from 10 mm off: worst {worst_mm:5.1f} mm"
    )


def run(family: str, seed: int, *, points: int | None = None, protrusion_only: bool = False) -> None:
    """Print one pair's fits from the true pose (``points``: model samples instead of the benchmark's;
    ``protrusion_only``: only a lever's protrusion line)."""
    pair = make_pair(family, seed, points)
    if protrusion_only:
        if family == "lever":
            print(f"{family:10} {seed:5d} | {protrusion_line(pair)}", flush=True)
        return
    desc = family_descriptor(pair)
    fine = prepare_target(pair.target, RegistrationParams())
    scale = float(np.prod(pair.stretch)) ** (1.0 / 3.0)
    truth = Similarity(scale, pair.rotation, pair.shift)
    fits = fit_axes(
        desc.chain,
        pair.source.points,
        pair.target,
        best=truth,
        grip=grip_points(desc, pair.source.points),
        threshold_m=fine.threshold,
        spacing_m=fine.spacing,
        rng=np.random.default_rng(seed),
    )
    prim, fit = desc.chain[0], fits.axes[0]
    pos, direction = np.asarray(prim.pos, dtype=np.float64), np.asarray(prim.dir, dtype=np.float64)
    whole_pos, whole_dir = fits.whole.carry_line(pos, direction)
    start = fits.starts[0]
    placed_pos, placed_dir = start.apply_point(pos), start.apply_direction(direction)
    along = np.abs(fits.whole.axes).argmax(axis=0)  # the object axis each box axis runs along
    factors = np.full(3, np.nan)
    factors[along] = fits.whole.factors
    edge = ""
    if family in {"cabinet", "microwave"}:
        seen, agreeing = edge_face_normals(pair, fine.normals)
        edge = f" | edge face {seen:3d} pts, normals within 30 deg {agreeing:3d}"
    whole_mm = point_line_distance(pair.target_axis_pos, whole_pos, whole_dir) * 1e3
    placed_mm = point_line_distance(pair.target_axis_pos, placed_pos, placed_dir) * 1e3
    sig_smoothed, sig_planes = whole_sigmas(pair, fits.whole, (pos, direction), fine.normals, fine.threshold)
    found = " ".join(f"{f:5.3f}" for f in factors)
    true = " ".join(f"{f:5.3f}" for f in pair.stretch / scale)
    print(
        f"{family:10} {seed:5d} | whole {whole_mm:6.2f} mm "
        f"{angle_between_deg(whole_dir, pair.target_axis_dir):5.2f} deg sigma {sig_planes * 1e3:5.2f} mm "
        f"(smoothed {sig_smoothed * 1e3:5.2f}) | placed {placed_mm:6.2f} mm "
        f"{angle_between_deg(placed_dir, pair.target_axis_dir):5.2f} deg "
        f"({'neighbourhood' if fit.local else 'whole model':13}) | sigma {fit.spread.pos_std_m * 1e3:5.2f} mm | "
        f"factors {found} true {true}{edge}",
        flush=True,
    )
    if family == "lever":
        print(f"{'':10} {'':5} | {protrusion_line(pair)}", flush=True)


def main() -> None:
    """Parse the flags and print every chosen pair."""
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--family", choices=FAMILIES, action="append", help="only this family (repeatable)")
    parser.add_argument("--seeds", type=int, nargs="+", default=list(FAMILY_DEV_SEEDS))
    parser.add_argument("--points", type=int, help="surface samples of each full model (default: the benchmark's)")
    parser.add_argument("--protrusion-only", action="store_true", help="only the lever's protrusion line")
    args = parser.parse_args()
    for family in args.family or FAMILIES:
        for seed in args.seeds:
            run(family, seed, points=args.points, protrusion_only=args.protrusion_only)


if __name__ == "__main__":
    main()
