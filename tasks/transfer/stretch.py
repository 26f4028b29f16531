"""A similarity with a stretch along the source's box axes: for objects of the same design in other proportions.

A novel cabinet may be wider but not deeper than the demonstrated one; no similarity maps one onto the other,
and a hinge on the door's edge lands beside the true one by the difference of the half-widths. The stretched
map is

    x_target = S(c + V diag(f) V^T (x - c))

with ``S`` the registration's similarity, ``V`` (3, 3) the source's box axes (columns: its minimal oriented
bounding box, open3d), ``c`` the source's centroid and ``f`` (3,) stretch factors. ``stretch_icp`` refines the
rotation, translation and factors by point-to-plane ICP (the similarity's own scale stays, so the factors carry
the proportions); factors the target's scan does not constrain stay at 1 by a small ridge. The planes are the
source model's (its normals carried by the map), not the scan's: normals estimated on a scan with 1-2 mm noise
tilt by several degrees at random, and on a flat face those tilts read as information along the face, which the
face does not give (a door front seen without its hinge side would pin the hinge across the door). The scan's
normals only decide which pairs face the same way. Each primitive is then carried by the similarity that agrees
with the stretched map at its axis (``local_similarity``). Lengths in metres.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
import open3d as o3d
from scipy.spatial import cKDTree

from tasks.arrays import FloatArray, Points, Vector3
from tasks.transfer.face_misfit import bias_cov
from tasks.transfer.face_normals import plane_holds
from tasks.transfer.pairing import nearest_compatible
from tasks.transfer.similarity import Similarity, rotation_onto

MAX_STRETCH = 1.5
"""Stretch factors stay within 1/1.5 .. 1.5: a similar object's proportions differ by at most half again along
any of its axes (beyond that it is another design, whose functional part a stretched fit cannot be trusted on)."""
MAX_STEP = 0.05
"""Largest relative change of a factor per iteration (keeps a poor start from running away)."""
NORMAL_COS = math.cos(math.radians(30.0))
"""Paired normals must agree within 30 degrees (beyond, the pair joins a face to another face)."""
CORRELATED_POINTS = 4.0
"""Neighbouring pairs share their error (a depth scanner's noise is smooth over a pixel or two, so a point and
its nearest neighbours err together): the residuals count as one independent observation per 2 x 2 pairs."""
NEAREST_SLACK = 0.25
NEAREST_K = 8
"""A pair counts only when its source point's plane is, within this fraction of the final correspondence distance,
the nearest of the planes of the ``NEAREST_K`` source points nearest its target point: the back face of a thin
part (a door leaf, a drawer front) faces the same way, unsigned, as the front one the scan shows, and would pull
it in. The slack is the final distance's even while the early, wider stages search (a fraction of 4 times it
exceeds a 30-40 mm leaf's thickness, and a leaf's back face paired with its front squeezes the leaf flat)."""
POINT_WEIGHT = 0.3
"""Weight of the point-to-point components beside the point-to-plane residual."""
RIDGE = 1e-2
"""Weight of the pull of each factor's change towards 0, as a fraction of the data's own weight along it:
directions the scan does not show keep their proportions."""


@dataclass(frozen=True)
class Stretched:
    """x_target = similarity(centre + axes diag(factors) axes^T (x - centre)); source frame in, target out."""

    similarity: Similarity
    axes: FloatArray
    """(3, 3) unit columns: the source's box axes (source frame)."""
    factors: FloatArray
    """(3,) stretch along each column of ``axes`` (1: the similarity alone)."""
    centre: Vector3
    """(3,) source-frame centre of the stretch, metres."""

    def linear(self) -> FloatArray:
        """The (3, 3) stretch V diag(f) V^T (source frame)."""
        out: FloatArray = self.axes @ np.diag(self.factors) @ self.axes.T
        return out

    def stretch_points(self, points: Points) -> Points:
        """(n, 3) source points (metres) stretched, still in the source frame (before the similarity)."""
        out: Points = self.centre + (points - self.centre) @ self.linear().T
        return out

    def stretch_normals(self, normals: Points) -> Points:
        """(n, 3) unit surface normals (source frame) of the stretched surface: turned by the inverse stretch."""
        turned = normals @ np.linalg.inv(self.linear())
        out: Points = turned / np.maximum(np.linalg.norm(turned, axis=1, keepdims=True), 1e-12)
        return out

    def apply_points(self, points: Points) -> Points:
        """Map (n, 3) source points (metres) into the target frame."""
        return self.similarity.apply_points(self.stretch_points(points))

    def carry_line(self, pos: Vector3, direction: Vector3) -> tuple[Vector3, Vector3]:
        """The image of the line through ``pos`` along ``direction``: (point, unit direction), target frame."""
        moved = self.similarity.apply_point(self.centre + self.linear() @ (pos - self.centre))
        return moved, self.similarity.apply_direction(self.linear() @ direction)


def box_axes(points: Points, normals: Points | None = None) -> FloatArray:
    """(3, 3) unit columns: the axes of the minimal oriented bounding box of ``points`` (open3d), turned onto the
    directions the model's faces face when ``normals`` ((n, 3) unit, unsigned) are given (``face_frame``)."""
    cloud = o3d.geometry.PointCloud()
    cloud.points = o3d.utility.Vector3dVector(np.ascontiguousarray(points, dtype=np.float64))
    rot = np.asarray(cloud.get_minimal_oriented_bounding_box().R, dtype=np.float64)
    u, _, vt = np.linalg.svd(rot)
    out: FloatArray = u @ vt
    return out if normals is None else face_frame(normals, out)


SMOOTH_NN = 24
SMOOTH_ROUNDS = 2
"""Model normals are taken from the face most of their 24 nearest neighbours lie on, then averaged over the
neighbours facing the same way (within ``FACE_COS``), twice: on a face the sampling noise (a few degrees per
normal) averages out, and at an edge a normal fitted across both faces (20-40 degrees off either) joins one of
them. Tilts like these would read as information along a flat face (``line_spread``)."""


def smoothed_normals(points: Points, normals: Points) -> Points:
    """(n, 3) unit normals of the model ``points`` (metres) from their estimated ``normals`` (unit, unsigned):
    per point, the neighbour normal (of ``SMOOTH_NN``) that most neighbours agree with within ``FACE_COS``, then
    ``SMOOTH_ROUNDS`` averages over the neighbours agreeing with it."""
    k = min(SMOOTH_NN, len(points))
    _, nbr = cKDTree(points).query(points, k=k)
    near = np.asarray(normals, dtype=np.float64)[nbr]  # (n, k, 3)
    agree = np.abs(np.einsum("nij,nkj->nik", near, near)) >= FACE_COS  # (n, k, k)
    out: Points = near[np.arange(len(points)), agree.sum(axis=2).argmax(axis=1)]
    for _ in range(SMOOTH_ROUNDS):
        near = out[nbr]
        cos = np.einsum("nkj,nj->nk", near, out)
        weight = (np.abs(cos) >= FACE_COS) * np.sign(cos)
        summed = np.einsum("nk,nkj->nj", weight, near)
        out = summed / np.maximum(np.linalg.norm(summed, axis=1, keepdims=True), 1e-12)
    return out


FACE_COS = math.cos(math.radians(20.0))
"""A normal within 20 degrees of a box axis counts as a face facing along it (a face's normals scatter by a few
degrees with the scan noise; a bevel or a cylinder's side at 45 degrees stays out)."""
FACE_ROUNDS = 10


def face_frame(normals: Points, start: FloatArray) -> FloatArray:
    """(3, 3) orthonormal columns near ``start`` that the model's face normals ((n, 3) unit, unsigned) line up
    with best (the normals within ``FACE_COS`` of an axis, orthogonal Procrustes, repeated): the object's own
    box axes. A minimal bounding box is tilted by what sticks out of a flat object (a lever on each face of a door
    leaf tilts it by 3 degrees, the leaf's thickness traded for its height), and a stretch along a tilted axis
    shears the object. ``start`` when too few normals face along the axes."""
    frame = start
    for _ in range(FACE_ROUNDS):
        cos = normals @ frame  # (n, 3)
        k = np.abs(cos).argmax(axis=1)
        best = cos[np.arange(len(cos)), k]
        face = np.abs(best) >= FACE_COS
        if int(face.sum()) < 12:
            return start
        signed = normals[face] * np.sign(best[face])[:, None]
        b = signed.T @ np.eye(3)[k[face]]  # sum of n_i e_k(i)^T
        u, _, vt = np.linalg.svd(b)
        turned: FloatArray = u @ vt
        if np.allclose(turned, frame, atol=1e-9):
            break
        frame = turned
    return frame


def _skew(w: Vector3) -> FloatArray:
    return np.array([[0.0, -w[2], w[1]], [w[2], 0.0, -w[0]], [-w[1], w[0], 0.0]])


def _small_rotation(w: Vector3) -> FloatArray:
    """Rotation of angle |w| about w (Rodrigues)."""
    angle = float(np.linalg.norm(w))
    if angle < 1e-15:
        return np.eye(3)
    k = _skew(w / angle)
    out: FloatArray = np.eye(3) + math.sin(angle) * k + (1.0 - math.cos(angle)) * k @ k
    return out


def _linear_system(
    current: Stretched,
    p: Points,
    q: Points,
    n: Points,
    *,
    along: FloatArray,
    huber: float,
    plane_weight: FloatArray | None = None,
    point_weight: float = POINT_WEIGHT,
) -> tuple[FloatArray, FloatArray, FloatArray]:
    """Rows, residuals and robust weights of one linearised step: each pair's point-to-plane residual (``n``:
    the carried source normals, unit, target frame; times ``plane_weight``, 0 where the model's normal states no
    plane: ``face_normals``) and, at
    ``point_weight`` (default ``POINT_WEIGHT``), its three point-to-point components (which see a face's edge,
    where the planes do not; none at 0).
    Unknowns: small rotation about the pairs' centroid (3), translation (3), relative factor changes (3)."""
    centre = p.mean(axis=0)
    sim = current.similarity
    turned_axes = sim.rotation @ current.axes  # target-frame box axes
    d_stretch = sim.scale * current.factors * along  # (m, 3): d p / d sigma_k = d_stretch[:, k] * turned_axes[:, k]
    d = p - centre
    plane = np.hstack([np.cross(d, n), n, d_stretch * (n @ turned_axes)])
    plane_res = np.einsum("ij,ij->i", n, q - p)
    if plane_weight is not None:
        plane, plane_res = plane * plane_weight[:, None], plane_res * plane_weight
    rows, res = [plane], [plane_res]
    for j in range(3 if point_weight > 0.0 else 0):
        e = np.zeros(3)
        e[j] = 1.0
        rot_j = np.cross(d, e)
        rows.append(point_weight * np.hstack([rot_j, np.tile(e, (len(p), 1)), d_stretch * turned_axes[j]]))
        res.append(point_weight * (q - p)[:, j])
    a, residual = np.vstack(rows), np.concatenate(res)
    w = np.minimum(1.0, huber / np.maximum(np.abs(residual), 1e-12))
    return a, residual, w


def carried_normals(current: Stretched, source_normals: Points) -> Points:
    """(n, 3) unit normals of the source surface mapped by ``current`` (a linear map turns normals by its
    inverse transpose; target frame)."""
    turned = source_normals @ (current.similarity.rotation @ np.linalg.inv(current.linear())).T
    out: Points = turned / np.maximum(np.linalg.norm(turned, axis=1, keepdims=True), 1e-12)
    return out


def _matched(
    current: Stretched,
    source: Points,
    source_normals: Points,
    *,
    target_normals: Points,
    tree: cKDTree,
    dist_m: float,
    slack_m: float,
) -> tuple[Points, Points, np.ndarray, np.ndarray]:
    """The moved source and its carried normals, the indices of the target points paired with them, and which
    pairs count: the nearest scan point within ``dist_m`` whose normal agrees within ``NORMAL_COS``
    (``pairing``), whose own nearest model surface is the pair's within ``slack_m`` (``NEAREST_SLACK``)."""
    moved = current.apply_points(source)
    turned = carried_normals(current, source_normals)
    idx, ok = nearest_compatible(tree, moved, turned, target_normals, dist_m=dist_m, min_cos=NORMAL_COS)
    if not ok.any():
        return moved, turned, idx, ok
    q = tree.data[idx[ok]]
    _, near = cKDTree(moved).query(q, k=min(NEAREST_K, len(moved)))
    near = near.reshape(len(q), -1)
    gap = np.abs(np.einsum("ikj,ikj->ik", turned[near], q[:, None, :] - moved[near]))  # to each neighbour's plane
    own = np.abs(np.einsum("ij,ij->i", turned[ok], q - moved[ok]))
    ok[ok] &= own <= gap.min(axis=1) + slack_m
    return moved, turned, idx, ok


def stretch_icp(
    source: Points,
    target: Points,
    target_normals: Points,
    start: Stretched,
    max_distance_m: float,
    *,
    source_normals: Points,
    iterations: int = 30,
    free_stretch: bool = True,
    final_m: float | None = None,
    point_weight: float = POINT_WEIGHT,
) -> Stretched:
    """Refine ``start`` by point-to-plane ICP over rotation, translation and (``free_stretch``) the three
    stretch factors; source (n, 3) and target (m, 3) metres, ``source_normals`` (n, 3) and ``target_normals``
    (m, 3) unit (unsigned). The residuals lie along the carried source normals; a model point pairs only with
    scan points whose normals agree (``_matched``): a face the scan missed would pull the model's edges in.
    ``final_m``: the last stage's
    correspondence distance, which sets the nearest-surface slack (``NEAREST_SLACK``; default ``max_distance_m``).
    ``point_weight``: the point-to-point components' weight (``_linear_system``). ``start`` when too few pairs
    match."""
    tree = cKDTree(target)
    current = start
    huber = max_distance_m / 3.0
    limit = math.log(MAX_STRETCH)
    along = (source - start.centre) @ start.axes  # (n, 3): coordinates along the box axes
    unknowns = 9 if free_stretch else 6
    slack = NEAREST_SLACK * (max_distance_m if final_m is None else final_m)
    for _ in range(iterations):
        moved, turned, idx, ok = _matched(
            current,
            source,
            source_normals,
            target_normals=target_normals,
            tree=tree,
            dist_m=max_distance_m,
            slack_m=slack,
        )
        if int(ok.sum()) < 12:
            return current
        p, q, n = moved[ok], target[idx[ok]], turned[ok]
        a, residual, w = _linear_system(current, p, q, n, along=along[ok], huber=huber, point_weight=point_weight)
        a = a[:, :unknowns]
        normal = (a * w[:, None]).T @ a
        ridge = np.zeros(unknowns)
        if free_stretch:
            ridge[6:] = RIDGE * np.trace(normal[6:, 6:]) / 3.0 + 1e-12
        try:
            x = np.linalg.solve(normal + np.diag(ridge) + 1e-12 * np.eye(unknowns), (a * w[:, None]).T @ residual)
        except np.linalg.LinAlgError:
            return current
        centre = p.mean(axis=0)
        sigma = np.clip(x[6:], -MAX_STEP, MAX_STEP) if free_stretch else np.zeros(3)
        factors = np.exp(np.clip(np.log(current.factors * (1.0 + sigma)), -limit, limit))
        rot = _small_rotation(np.asarray(x[:3], dtype=np.float64))
        delta = Similarity(1.0, rot, centre + x[3:6] - rot @ centre)
        current = Stretched(delta.compose(current.similarity), current.axes, factors, current.centre)
        if np.linalg.norm(x[:3]) < 1e-7 and np.linalg.norm(x[3:6]) < 1e-8 and np.abs(sigma).max() < 1e-6:
            break
    return current


def across_std(cov: FloatArray) -> float:
    """The RMS sigma over the two directions across an axis of ``cov`` ((3, 3), across the axis only)."""
    return math.sqrt(max(float(np.trace(cov)) / 2.0, 0.0))


def worst_std(cov: FloatArray) -> float:
    """The sigma of ``cov`` ((3, 3)) in its worst-placed direction."""
    return math.sqrt(max(float(np.linalg.eigvalsh(cov)[-1]), 0.0))


@dataclass(frozen=True)
class FitSpread:
    """How well a fit pins a carried line: standard deviations from the fit's residuals (target frame)."""

    pos_std_m: float
    """RMS displacement of the carried axis point across the axis, one sigma, metres."""
    dir_std_rad: float
    """RMS turn of the carried direction, one sigma, radians."""
    rms_m: float
    """RMS point-to-plane residual of the pairs, metres."""
    pairs: int
    pos_cov: FloatArray | None = None
    """(3, 3) covariance of the carried axis point across the axis, metres squared (its trace over 2 is
    ``pos_std_m`` squared, before any widening); None when no pair informs."""
    bias_cov: FloatArray | None = None
    """(3, 3) covariance across the axis of the placement's systematic error from faces whose pairs lie off to
    one side (``face_misfit``), metres squared; in ``pos_cov`` only once ``axis_fit.with_bias`` added it."""
    factor_cov: FloatArray | None = None
    """(3, 3) covariance of the fit's relative stretch factors (along its box axes), when they were free."""

    def scaled_cov(self) -> FloatArray | None:
        """``pos_cov`` scaled to the (possibly widened) ``pos_std_m``; None without one."""
        if self.pos_cov is None or not math.isfinite(self.pos_std_m):
            return None
        own = max(across_std(self.pos_cov), 1e-15)
        out: FloatArray = self.pos_cov * (self.pos_std_m / own) ** 2
        return out

    @property
    def misfit_std_m(self) -> float:
        """The faces' systematic misfit (``bias_cov``) in its worst direction across the axis, metres (0: none)."""
        return 0.0 if self.bias_cov is None else worst_std(self.bias_cov)

    @property
    def worst_pos_std_m(self) -> float:
        """The sigma of the axis point in its worst-placed direction across the axis, metres (``pos_std_m`` times
        the square root of two without a covariance: both directions as loose as the two together)."""
        cov = self.scaled_cov()
        if cov is None:
            return self.pos_std_m * math.sqrt(2.0)
        return worst_std(cov)


def line_jacobians(
    fitted: Stretched, line: tuple[Vector3, Vector3], centre: Vector3, *, unknowns: int = 9
) -> tuple[FloatArray, FloatArray]:
    """(3, unknowns) Jacobians of the carried line's point and unit direction (target frame; ``line``: point and
    direction, source frame) with respect to a step of ``stretch_icp`` from ``fitted``: a small rotation about
    ``centre`` (target frame), a translation, and with ``unknowns`` 9 the relative changes of the three factors.
    A factor along an axis the line is tilted from turns the direction as well as moving the point."""
    pos, direction = line
    moved_pos, moved_dir = fitted.carry_line(pos, direction)
    jac = np.zeros((3, unknowns))
    jac[:, :3] = -_skew(moved_pos - centre)
    jac[:, 3:6] = np.eye(3)
    jac_dir = np.zeros((3, unknowns))
    jac_dir[:, :3] = -_skew(moved_dir)
    if unknowns > 6:
        turned_axes = fitted.similarity.rotation @ fitted.axes
        jac[:, 6:] = fitted.similarity.scale * fitted.factors * ((pos - fitted.centre) @ fitted.axes) * turned_axes
        across = np.eye(3) - np.outer(moved_dir, moved_dir)
        stretched = float(np.linalg.norm(fitted.linear() @ direction))
        jac_dir[:, 6:] = across @ (fitted.factors * (direction @ fitted.axes) * turned_axes) / stretched
    return jac, jac_dir


def line_spread(
    fitted: Stretched,
    source: Points,
    source_normals: Points,
    *,
    target: Points,
    target_normals: Points,
    dist_m: float,
    line: tuple[Vector3, Vector3],
    free_stretch: bool = True,
    plane_weight: FloatArray | None = None,
    model: tuple[Points, Points] | None = None,
    start_pos_std_m: float | None = None,
    held_factor_cov: FloatArray | None = None,
) -> FitSpread:
    """The covariance of ``fitted``'s unknowns carried to the line (point, unit direction; source frame): the
    inverse of the pairs' information over the residual variance (``CORRELATED_POINTS`` pairs counting as one)
    plus what the fit knows before the pairs: where its start put the model (a translation within
    ``start_pos_std_m``; by default the correspondence distance ``dist_m``, and with a free stretch what a stretch
    up to ``MAX_STRETCH`` moves the pairs, their RMS reach times log 1.5: the start is a similarity, and where the
    scan shows no face a similar object's may lie that far off, as a door leaf's unscanned underside leaves its
    height, and its lever's, unmeasured), turns moving the pairs by at most ``dist_m``, factors within
    ``MAX_STRETCH``. The information comes from the carried source normals; a direction no pair
    constrains (a hinge on a face the scan lacks) keeps the prior's sigma, not none. ``plane_weight``: (n,) per
    source point, 0 where its normal states no plane (a border between faces, ``face_normals``): such pairs
    inform nothing. ``model``: the whole model's points and normals (source frame; ``source`` is among them):
    a pair informs only where the model about it lies on its plane, over the pair's offset along it, within the
    model's own noise (``face_normals.plane_holds``).

    ``held_factor_cov``: for a fit without a free stretch, the (3, 3) covariance of the relative stretch factors
    it holds at another fit's values (``fitted``'s factors, axes and centre: the whole model's). The rigid fit
    follows an error in them (it balances its pairs about the stretched part), so the line moves by the error
    times its total derivative, through the fit's own response (``-info_tt^-1 info_tf``) and directly."""
    tree = cKDTree(target)
    moved, turned, idx, ok = _matched(
        fitted,
        source,
        source_normals,
        target_normals=target_normals,
        tree=tree,
        dist_m=dist_m,
        slack_m=NEAREST_SLACK * dist_m,
    )
    unknowns = 9 if free_stretch else 6
    if int(ok.sum()) < 12:
        return FitSpread(float("inf"), float("inf"), float("inf"), int(ok.sum()))
    if plane_weight is not None:
        ok &= plane_weight > 0.0
        if int(ok.sum()) < 12:
            return FitSpread(float("inf"), float("inf"), float("inf"), int(ok.sum()))
    if model is not None:
        ok[ok] &= _planes_hold(fitted, model, source[ok], p=moved[ok], q=target[idx[ok]], n=turned[ok])
        if int(ok.sum()) < 12:
            return FitSpread(float("inf"), float("inf"), float("inf"), int(ok.sum()))
    p, q, n = moved[ok], target[idx[ok]], turned[ok]
    along = (source[ok] - fitted.centre) @ fitted.axes
    weight = None if plane_weight is None else plane_weight[ok]
    a, residual, w = _linear_system(fitted, p, q, n, along=along, huber=dist_m / 3.0, plane_weight=weight)
    plane_rows = len(p)
    rms = float(np.sqrt(np.mean(residual[:plane_rows] ** 2)))
    a = a[:plane_rows]  # the planes' information (the point terms see the sampling, not the surface)
    full = (a * w[:plane_rows, None]).T @ a / CORRELATED_POINTS / max(rms, 1e-9) ** 2
    info = full[:unknowns, :unknowns]
    centre = p.mean(axis=0)
    reach = float(np.sqrt(np.mean(((p - centre) ** 2).sum(axis=1))))
    if start_pos_std_m is None:
        start_pos_std_m = max(dist_m, reach * math.log(MAX_STRETCH)) if free_stretch else dist_m
    prior = np.full(unknowns, 1.0 / start_pos_std_m**2)  # translations
    prior[:3] = (reach / dist_m) ** 2  # rotations: a turn moving the pairs by dist_m
    prior[6:] = 1.0 / math.log(MAX_STRETCH) ** 2
    cov = np.linalg.inv(info + np.diag(prior))
    pos, direction = line
    moved_dir = fitted.carry_line(pos, direction)[1]
    jac9, jac_dir9 = line_jacobians(fitted, line, centre, unknowns=9)
    jac, jac_dir = jac9[:, :unknowns], jac_dir9[:, :unknowns]
    across = np.eye(3) - np.outer(moved_dir, moved_dir)
    cov_pos = across @ jac @ cov @ jac.T @ across
    turn = jac_dir @ cov @ jac_dir.T
    if held_factor_cov is not None and not free_stretch:
        response = -cov @ full[:6, 6:]  # (6, 3): how the rigid fit follows a change of the held factors
        total, total_dir = jac9[:, :6] @ response + jac9[:, 6:], jac_dir9[:, :6] @ response + jac_dir9[:, 6:]
        cov_pos = cov_pos + across @ total @ held_factor_cov @ total.T @ across
        turn = turn + total_dir @ held_factor_cov @ total_dir.T
    bias = bias_cov(
        source[ok],
        source_normals[ok],
        n,
        np.einsum("ij,ij->i", n, q - p),
        direction=moved_dir,
        rms_m=rms,
        correlated=CORRELATED_POINTS,
    )
    return FitSpread(
        across_std(cov_pos),
        float(np.sqrt(max(np.trace(turn), 0.0) / 2.0)),
        rms,
        int(ok.sum()),
        cov_pos,
        bias,
        np.asarray(cov[6:, 6:], dtype=np.float64) if free_stretch else None,
    )


def _planes_hold(
    fitted: Stretched, model: tuple[Points, Points], source: Points, *, p: Points, q: Points, n: Points
) -> np.ndarray:
    """(m,) bool: each pair's model plane holds over the pair's offset along it (``face_normals.plane_holds``;
    ``model``: the whole model's points and normals, source frame). ``source``: the pairs' model points (source
    frame); ``p``, ``q``, ``n``: moved, paired scan points and carried normals (target frame)."""
    points, normals = model
    tree = cKDTree(points)
    _, at = tree.query(source)
    gap = q - p
    lateral = np.linalg.norm(gap - n * np.einsum("ij,ij->i", gap, n)[:, None], axis=1)
    size = fitted.similarity.scale * float(np.prod(fitted.factors)) ** (1.0 / 3.0)
    return plane_holds(points, normals, tree, np.asarray(at, dtype=np.intp), lateral / size)


def local_similarity(stretched: Stretched, pos: Vector3, direction: Vector3) -> Similarity:
    """The similarity that carries the line through ``pos`` along unit ``direction`` (source frame) as
    ``stretched`` does: the similarity's rotation turned so the direction follows the stretch, its scale times
    the factors' geometric mean, and the point landing where the stretch puts it."""
    sim = stretched.similarity
    moved_pos, moved_dir = stretched.carry_line(pos, direction)
    rotation = rotation_onto(sim.rotation @ direction, moved_dir) @ sim.rotation
    scale = sim.scale * float(np.prod(stretched.factors)) ** (1.0 / 3.0)
    return Similarity(scale, rotation, moved_pos - scale * rotation @ pos)


STRETCH_POINTS = 3000
"""Source points (a random subset of the model) the stretched fit uses."""


def fit_stretch(
    sample: tuple[Points, Points],
    target: Points,
    target_normals: Points,
    best: Similarity,
    threshold_m: float,
    *,
    axes: FloatArray,
    centre: Vector3,
) -> Stretched:
    """The stretched fit of the source points and normals ``sample`` onto ``target`` from the registration's
    ``best`` similarity along the source's box ``axes`` about ``centre`` (metres; the correspondence distance
    shrinks from 4 to 1 ``threshold_m``)."""
    current = Stretched(best, axes, np.ones(3), centre)
    for dist in (4.0 * threshold_m, 2.0 * threshold_m, threshold_m):
        current = stretch_icp(
            sample[0],
            target,
            target_normals,
            current,
            dist,
            source_normals=sample[1],
            final_m=threshold_m,
        )
    return current
