"""Rotation fit (Section III): plane by the smallest scatter eigenvector, circle in the plane (Kåsa algebraic
start), then a joint geometric least-squares refinement of one axis for every marker of a rigid part.

Each marker m keeps its own radius r_m and height h_m along the axis; all share the axis direction and a
point on it. The residuals are (radial distance - r_m, axial coordinate - h_m) per sample, metres, under a
robust soft-L1 loss with scale ``loss_scale_m`` (or the radial residuals' own spread, when wider). The axis
uncertainty comes from the Gauss-Newton covariance.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy.optimize import OptimizeResult, least_squares

from tasks.arrays import FloatArray, Points, Vector3
from tasks.fit.geometry import nearest_on_axis, net_change, perpendicular_basis, unit
from tasks.fit.noise import MAD_TO_SIGMA

MAX_FIT_SAMPLES = 600
"""Samples per marker used by the geometric refinement (evenly thinned beyond this; the fit barely moves)."""
LINE_LIKE_RADIUS_RATIO = 20.0
"""A circle whose radius exceeds this many times the samples' spread sweeps under 3 degrees: a line, whose
geometric refinement would only chase the radius to infinity; the algebraic fit is kept."""
MAX_EVALUATIONS = 60
"""Residual evaluations of one geometric refinement (it converges in a few Gauss-Newton steps)."""
LOSS_SCALE_SIGMAS = 3.0
"""Soft-L1 loss scale in residual sigmas: residuals within it count as in least squares, beyond it as outliers.
When the radial residuals' robust spread exceeds the sensor noise (a handle that slips, a door that sags), the scale
follows the spread, so model misfit is averaged like noise instead of trimmed (which biases the radius)."""


@dataclass(frozen=True)
class CircleFit:
    """A circle in 3-D: centre (m), unit normal, radius (m), rms distance (m) of the samples to it."""

    centre: Vector3
    normal: Vector3
    radius: float
    rms_m: float
    eigenvalues: tuple[float, float, float]


@dataclass(frozen=True)
class RotationFit:
    """One axis for a rigid part: point on the axis nearest the samples' centroid, unit direction (positive
    rotation by the right-hand rule), swept angle (rad, >= 0, unwrapped), per-marker radii (m), residual rms (m),
    direction and position standard deviations (rad, m)."""

    pos: Vector3
    dir: Vector3
    angle_rad: float
    radii: tuple[float, ...]
    rms_m: float
    dir_std_rad: float
    pos_std_m: float
    rss: float
    n: int


def circle_from_points_algebraic(points: Points) -> CircleFit:
    """Kåsa algebraic circle fit in the best plane of (n, 3) points (the paper's circle fit)."""
    centroid = points.mean(axis=0)
    q = points - centroid
    evals, evecs = np.linalg.eigh(q.T @ q / len(q))
    normal = evecs[:, 0]
    basis = evecs[:, 1:]
    u = q @ basis
    design = np.column_stack([2.0 * u, np.ones(len(u))])
    rhs = (u**2).sum(axis=1)
    sol, *_ = np.linalg.lstsq(design, rhs, rcond=None)
    centre2 = sol[:2]
    radius = float(np.sqrt(max(sol[2] + centre2 @ centre2, 0.0)))
    centre = centroid + basis @ centre2
    radial = np.linalg.norm(u - centre2, axis=1) - radius
    rms = float(np.sqrt(np.mean(radial**2 + (q @ normal) ** 2)))
    ev = np.sort(np.maximum(evals, 0.0))[::-1]
    return CircleFit(centre, unit(normal), radius, rms, (float(ev[0]), float(ev[1]), float(ev[2])))


def _thin(points: Points, limit: int) -> Points:
    """Every k-th sample so that at most ``limit`` remain."""
    if len(points) <= limit:
        return points
    idx = np.linspace(0, len(points) - 1, limit).round().astype(np.int64)
    return points[idx]


def angles_about(points: Points, axis_point: Vector3, axis_dir: Vector3) -> FloatArray:
    """Unwrapped angles (rad) of points about the axis, right-hand rule about ``axis_dir``."""
    e1, e2 = perpendicular_basis(axis_dir)
    q = points - axis_point
    ang: FloatArray = np.unwrap(np.arctan2(q @ e2, q @ e1))
    return ang


def fit_rotation(
    tracks: list[Points],
    loss_scale_m: float,
    *,
    algebraic_only: bool = False,
    start: tuple[Vector3, Vector3] | None = None,
    fixed_dir: bool = False,
) -> RotationFit:
    """Fit one rotation axis to the (n_m, 3) tracks of the markers of one rigid part (metres, world frame).

    With ``algebraic_only`` (the paper's baseline) the axis is the algebraic circle fit of the first track.
    ``start`` (axis point, direction), e.g. the screw axis of the part's orientations (``tasks.fit.rigid``), is
    refined too and the better of the two refinements is kept: a short noisy arc misleads the algebraic start.
    With ``fixed_dir`` only the axis point and radii are refined from ``start``, whose direction is kept.
    """
    if fixed_dir and start is not None:
        thin = [_thin(t, MAX_FIT_SAMPLES) for t in tracks]
        d, o, radii, std, _ = _refine(thin, np.asarray(start[0], dtype=np.float64), unit(start[1]), loss_scale_m, 0)
        return _finish(tracks, o, d, radii, std)
    circles = [circle_from_points_algebraic(t) for t in tracks]
    weights = np.array([c.eigenvalues[1] * len(t) for c, t in zip(circles, tracks, strict=True)])
    best = int(np.argmax(weights))
    d0 = circles[best].normal
    normals = np.array([c.normal * (1.0 if float(np.dot(c.normal, d0)) >= 0 else -1.0) for c in circles])
    if not algebraic_only:
        d0 = unit((normals * weights[:, None]).sum(axis=0))
    o0 = circles[best].centre
    span = max(float(np.ptp(t, axis=0).max()) for t in tracks)
    if algebraic_only or (start is None and not circles[best].radius < LINE_LIKE_RADIUS_RATIO * span):
        return _finish(tracks, o0, d0, [c.radius for c in circles], None)
    thin = [_thin(t, MAX_FIT_SAMPLES) for t in tracks]
    starts = [(o0, d0)] if circles[best].radius < LINE_LIKE_RADIUS_RATIO * span else []
    if start is not None:
        starts.append((np.asarray(start[0], dtype=np.float64), unit(start[1])))
    d, o, radii, std, _ = min((_refine(thin, so, sd, loss_scale_m, 2) for so, sd in starts), key=lambda r: r[4])
    return _finish(tracks, o, d, radii, std)


def _refine(
    thin: list[Points], o0: Vector3, d0: Vector3, loss_scale_m: float, n_dir: int
) -> tuple[Vector3, Vector3, list[float], tuple[float, float], float]:
    """Geometric least squares of one axis (point, direction; ``n_dir`` 0 keeps ``d0``), per-marker radii;
    the direction and position std (rad, m; direction std nan when kept) and the robust cost."""

    e1, e2 = perpendicular_basis(d0)
    m = len(thin)
    r0 = []
    h0 = []
    for t in thin:
        q = t - o0
        h = q @ d0
        r0.append(float(np.median(np.linalg.norm(q - np.outer(h, d0), axis=1))))
        h0.append(float(np.median(h)))

    k = n_dir + 2  # parameters of the axis: direction tilt (0 or 2), point shift (2)

    def unpack(x: FloatArray) -> tuple[Vector3, Vector3]:
        d = unit(d0 + x[0] * e1 + x[1] * e2) if n_dir else d0
        o = o0 + x[n_dir] * e1 + x[n_dir + 1] * e2
        return d, o

    def residuals(x: FloatArray) -> FloatArray:
        d, o = unpack(x)
        parts = []
        for i, t in enumerate(thin):
            q = t - o
            h = q @ d
            radial = np.linalg.norm(q - np.outer(h, d), axis=1)
            parts.append(radial - x[k + i])
            parts.append(h - x[k + m + i])
        return np.concatenate(parts)

    def solve(x_start: FloatArray, scale_m: float) -> OptimizeResult:
        return least_squares(
            residuals,
            x_start,
            loss="soft_l1",
            f_scale=max(scale_m, 1e-6),
            x_scale="jac",
            max_nfev=MAX_EVALUATIONS,
            tr_solver="lsmr",
        )

    sol = solve(np.concatenate([np.zeros(k), r0, h0]), loss_scale_m)
    res = residuals(sol.x)
    starts = np.cumsum([0] + [2 * len(t) for t in thin[:-1]])
    radial = np.concatenate([res[i : i + len(t)] for i, t in zip(starts, thin, strict=True)])
    spread = LOSS_SCALE_SIGMAS * MAD_TO_SIGMA * float(np.median(np.abs(radial)))
    if spread > loss_scale_m:
        sol = solve(sol.x, spread)
    d, o = unpack(sol.x)
    res = residuals(sol.x)
    dof = max(len(res) - len(sol.x), 1)
    s2 = float(res @ res) / dof
    jac = sol.jac
    try:
        cov = np.linalg.inv(jac.T @ jac) * s2
        dir_std = float(np.sqrt(max(cov[0, 0] + cov[1, 1], 0.0))) if n_dir else float("nan")
        pos_std = float(np.sqrt(max(cov[n_dir, n_dir] + cov[n_dir + 1, n_dir + 1], 0.0)))
    except np.linalg.LinAlgError:
        dir_std = pos_std = float("inf")
    return d, o, [float(r) for r in sol.x[k : k + m]], (dir_std, pos_std), float(sol.cost)


def _finish(
    tracks: list[Points], axis_point: Vector3, axis_dir: Vector3, radii: list[float], std: tuple[float, float] | None
) -> RotationFit:
    """Signs, swept angle, residuals and the axis point nearest the centroid."""
    nets = []
    wts = []
    rss = 0.0
    n = 0
    for t, r in zip(tracks, radii, strict=True):
        ang = angles_about(t, axis_point, axis_dir)
        nets.append(net_change(ang))
        wts.append(max(r, 1e-9) * len(t))
        q = t - axis_point
        h = q @ axis_dir
        radial = np.linalg.norm(q - np.outer(h, axis_dir), axis=1) - r
        rss += float(np.sum(radial**2 + (h - np.median(h)) ** 2))
        n += len(t)
    net = float(np.average(nets, weights=wts))
    d = axis_dir if net >= 0 else -axis_dir
    centroid = np.concatenate(tracks).mean(axis=0)
    pos = nearest_on_axis(centroid, axis_point, d)
    dir_std, pos_std = std if std is not None else (float("nan"), float("nan"))
    return RotationFit(
        pos=pos,
        dir=unit(d),
        angle_rad=abs(net),
        radii=tuple(radii),
        rms_m=float(np.sqrt(rss / max(n, 1))),
        dir_std_rad=dir_std,
        pos_std_m=pos_std,
        rss=rss,
        n=n,
    )
