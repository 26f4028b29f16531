"""Where a flat face's edge puts an axis that runs along it: the boundary of the face, measured in the scan.

A door's hinge runs along an edge of its front face (at the edge, or a few millimetres beyond it where the door is
inset in its frame). Point-to-plane pairs pin the hinge across the face's plane, but where the scan lacks the
door's edge face nothing they hold pins it along the face: the front face slides over itself
(``stretch.line_spread`` leaves that direction its prior). The front face itself ends at the hinge, though: its
scan points stop there. So, for each flat face of the model whose edge the axis runs along:

- **in the model** the face's points near the axis (on its plane, within ``BAND_SIGMAS`` of its noise) are
  projected onto the direction across the axis in the face's plane, pointing into the face, and the edge is
  located there (``edge_location``);
- **in the scan** the same is done about the face as the fit carries it, in a window about where the fit puts the
  edge;
- the two give one more measurement of the axis across itself, with its own variance, combined with the fit's
  covariance by their information (a Kalman update); when the two contradict each other beyond
  ``AGREEMENT_SIGMAS`` the fit's placement stays and its sigma is widened to cover the disagreement.

The edge is located by maximum likelihood: along the across-axis coordinate s the face's points are uniform for s
above the edge s0 and absent below it, blurred by the noise (a normal CDF step), plus a line of points at the edge
itself (the neighbouring face seen edge-on within the band: a door's edge face), all within a window. Lengths in
metres; frames as stated.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from scipy.special import ndtr

from tasks.arrays import FloatArray, Points, Vector3
from tasks.fit.noise import MAD_TO_SIGMA
from tasks.transfer.face_normals import ModelNormals
from tasks.transfer.stretch import MAX_STRETCH, Stretched, carried_normals

MAX_GAP_M = 0.010
"""An axis runs along a face's edge when it lies within 10 mm of it, across and in depth (an inset door's hinge is
2-4 mm beyond its front face's edge, a knuckle hinge's pin up to 10 mm)."""
FACE_DEG = 20.0
"""A model normal within 20 degrees of a face's belongs to it (a face's smoothed normals scatter by a few degrees)."""
MAX_AXIS_DEG = 10.0
"""A face runs along the axis when its normal is within 10 degrees of square to it."""
BAND_SIGMAS = 2.0
"""Points within two noise sigmas of the face's plane are the face's (95 % of them; a parallel face behind, a door
frame 18 mm back, stays out)."""
MIN_FACE_POINTS = 40
"""A face's edge is located from at least this many points in its window (fewer: a strip the scan hardly shows)."""
MIN_WINDOW_M = 0.015
"""The scan's edge is looked for at least 15 mm either side of where the fit puts it (several noise sigmas)."""
WINDOW_SIGMAS = 4.0
"""... and within four of the fit's sigmas across the axis, up to half the face's width."""
MARGIN_M = 0.010
"""Points within 10 mm of the face's ends along the axis are left out (the corners where other edges meet)."""
AGREEMENT_SIGMAS = 3.0
"""The edge and the fit are independent estimates: beyond three combined sigmas apart they contradict each other."""
MIN_WIDTH_M = 0.020
"""A face reaches at least 20 mm in from its edge (twice ``MAX_GAP_M``): a face, not a strip or a bevel."""
ONE_SIDED = 0.05
"""A face the axis bounds lies on one side of it: at most 5 % of its points about the axis beyond (noise, a
neighbouring face's border)."""
MIN_NOISE_M = 1e-4
"""A face's points are never taken as blurred by less than 0.1 mm (the finest scanner noise pbd meets)."""
PROFILE_STEP_M = 1e-4
"""The edge's likelihood is profiled on a 0.1 mm grid about its best value (a tenth of a fine scan's noise)..."""
PROFILE_REACH_M = 0.008
"""... at least 8 mm either way, and five noise sigmas (beyond where a located edge's profile has risen by 4.5)."""
PROFILE_RISE = 4.5
"""The edge's sigma is a third of how far its profile likelihood reaches, on its wider side, before it rises by 4.5
(three sigmas): a step's likelihood is lopsided and heavier-tailed than a parabola (a chance gap in the points by
the edge moves it further in than a stray point moves it out), which the width at a rise of a half understates."""
EDGE_STRIP_SIGMAS = 3.0
"""A neighbouring face meeting the edge lies within three noise sigmas of it, across."""
STRIP_M = 0.008
"""Its points are counted over the first 8 mm behind the band (within a door's or panel's thickness)."""


@dataclass(frozen=True)
class EdgeLocation:
    """A face's edge along the across-axis coordinate: where, how surely, from how many points."""

    offset_m: float
    std_m: float
    points: int
    line_mass_m: float
    """The line of points at the edge, in metres of face (a neighbouring face seen edge-on within the band)."""


@dataclass(frozen=True)
class ModelEdge:
    """A flat face of the model whose edge an axis runs along (source frame)."""

    normal: Vector3
    """(3,) unit face normal."""
    across: Vector3
    """(3,) unit direction in the face's plane, square to the axis, pointing into the face."""
    depth_m: float
    """The face's plane's offset from the axis point along ``normal``."""
    edge: EdgeLocation
    """The edge's offset from the axis point along ``across``."""
    along_m: tuple[float, float]
    """The face's extent along the axis about the axis point (margins taken off)."""
    width_m: float
    """The face's extent along ``across`` from its edge."""
    noise_m: float


@dataclass(frozen=True)
class EdgeUpdate:
    """How one face's edge moved an axis (target frame)."""

    shift: Vector3
    """(3,) metres added to the fit's placement of the axis point."""
    cov: FloatArray
    """(3, 3) the placement's covariance across the axis after the update."""
    measured_m: float
    """The edge's offset from the fit's prediction along the face, metres."""
    std_m: float
    """That measurement's sigma."""
    agrees: bool


def _int_ndtr(x: FloatArray | float) -> FloatArray:
    """The integral of the standard normal CDF from minus infinity to ``x``."""
    x = np.asarray(x, dtype=np.float64)
    out: FloatArray = x * ndtr(x) + np.exp(-0.5 * x * x) / math.sqrt(2.0 * math.pi)
    return out


def step_nll(s: FloatArray, edge: float, mass: float, blur: float, window: tuple[float, float]) -> float:
    """Negative log-likelihood of ``s`` under a blurred step at ``edge`` plus a line of ``mass`` at it."""
    lo, hi = window
    x = (s - edge) / blur
    density = ndtr(x) + mass * np.exp(-0.5 * x * x) / (math.sqrt(2.0 * math.pi) * blur)
    total = blur * float(_int_ndtr((hi - edge) / blur) - _int_ndtr((lo - edge) / blur))
    total += mass * float(ndtr((hi - edge) / blur) - ndtr((lo - edge) / blur))
    return float(-np.log(np.maximum(density, 1e-300)).sum() + len(s) * math.log(max(total, 1e-300)))


def edge_location(s: FloatArray, window: tuple[float, float], blur_m: float, mass_m: float) -> EdgeLocation | None:
    """The edge of the points ``s`` ((n,) metres across the axis, the face on the high side) within ``window``,
    blurred by ``blur_m`` (one sigma), with a line of ``mass_m`` (metres of face) at it: the maximum-likelihood
    edge, and its sigma from the profile likelihood (``PROFILE_RISE``). None with fewer than
    ``MIN_FACE_POINTS`` in the window."""
    lo, hi = window
    s = s[(s >= lo) & (s <= hi)]
    coarse = np.arange(lo + blur_m, hi - blur_m, max(blur_m, PROFILE_STEP_M))
    if len(s) < MIN_FACE_POINTS or len(coarse) == 0:
        return None
    values = np.array([step_nll(s, e, mass_m, blur_m, window) for e in coarse])
    start = float(coarse[int(values.argmin())])
    steps = math.ceil(max(PROFILE_REACH_M, 5.0 * blur_m) / PROFILE_STEP_M)
    fine = start + PROFILE_STEP_M * np.arange(-steps, steps + 1)
    fine = fine[(fine > lo) & (fine < hi)]
    profile = np.array([step_nll(s, e, mass_m, blur_m, window) for e in fine])
    best = int(profile.argmin())
    rise = profile - profile[best]
    inside = fine[rise <= PROFILE_RISE]
    half = max(float(fine[best] - inside.min()), float(inside.max() - fine[best]), PROFILE_STEP_M)
    if rise[0] <= PROFILE_RISE or rise[-1] <= PROFILE_RISE:  # no such rise within the grid: the edge is loose
        half = max(half, 0.5 * float(fine[-1] - fine[0]))
    return EdgeLocation(float(fine[best]), max(half / 3.0, PROFILE_STEP_M), len(s), mass_m)


def locate_edge(s: FloatArray, depth: FloatArray, window: tuple[float, float], noise_m: float) -> EdgeLocation | None:
    """The edge of a face from its points' ``s`` (across the axis, the face on the high side) and ``depth`` (off
    its plane), both (n,) metres, within ``window``; ``noise_m``: the points' noise (one sigma). The face's points
    are those within ``BAND_SIGMAS`` of the plane. The line at the edge is measured, not fitted (a fitted line
    would trade against the edge): where a neighbouring face meets the edge it runs on behind the band, and its
    points per metre of depth there give how many of them fall in the band, next to the face's own per metre
    across."""
    band = np.abs(depth) <= BAND_SIGMAS * noise_m
    first = edge_location(s[band], window, noise_m, 0.0)
    if first is None:
        return None
    at_edge = np.abs(s - first.offset_m) <= EDGE_STRIP_SIGMAS * noise_m
    behind = max(
        int(
            (at_edge & (sign * depth > BAND_SIGMAS * noise_m) & (sign * depth <= BAND_SIGMAS * noise_m + STRIP_M)).sum()
        )
        for sign in (-1.0, 1.0)
    )
    inner_lo = first.offset_m + EDGE_STRIP_SIGMAS * noise_m
    face_per_m = int((band & (s >= inner_lo) & (s <= window[1])).sum()) / max(window[1] - inner_lo, 1e-6)
    in_band = float(_int_ndtr(BAND_SIGMAS) - _int_ndtr(-BAND_SIGMAS))  # depths within the band, in noise sigmas
    mass = behind / STRIP_M * noise_m * in_band / max(face_per_m, 1e-9)
    return edge_location(s[band], window, noise_m, min(mass, window[1] - window[0]))


def _plane_noise(depth: FloatArray) -> tuple[float, float]:
    """The plane's offset (median) and its points' noise (scaled median absolute deviation) from ``depth``."""
    centre = float(np.median(depth))
    return centre, max(MAD_TO_SIGMA * float(np.median(np.abs(depth - centre))), MIN_NOISE_M)


def model_edges(
    source: Points, model: ModelNormals, *, line: tuple[Vector3, Vector3], radius_m: float
) -> list[ModelEdge]:
    """The flat faces of the model (``source`` (n, 3) and its normals, ``face_normals``: a face's normals are one
    of its face directions) whose edge the axis runs along (``line``: its point and unit direction): their normals
    within ``MAX_AXIS_DEG`` of square to it, their plane and their edge within ``MAX_GAP_M`` of it, looked for among
    the points within ``radius_m`` of the axis."""
    pos, direction = line
    normals = model.normals
    rel = source - pos
    along = rel @ direction
    lateral = rel - np.outer(along, direction)
    flat = (np.abs(normals @ model.directions.T) >= math.cos(math.radians(model.flat_deg))).any(axis=1)
    near = (np.einsum("ij,ij->i", lateral, lateral) <= radius_m**2) & (model.plane_weight > 0.0) & flat
    near &= np.abs(normals @ direction) <= math.sin(math.radians(MAX_AXIS_DEG))
    face_cos = math.cos(math.radians(FACE_DEG))
    out: list[ModelEdge] = []
    left = near.copy()
    while int(left.sum()) >= MIN_FACE_POINTS:
        cand = normals[left]
        seeds = cand[:: max(1, len(cand) // 200)]
        seed = seeds[int((np.abs(cand @ seeds.T) >= face_cos).sum(axis=0).argmax())]
        member = np.abs(normals @ seed) >= face_cos
        left &= ~member
        normal = seed - (seed @ direction) * direction
        normal /= np.linalg.norm(normal)
        edge = _model_edge(rel, along, near=member & near, member=member, normal=normal, direction=direction)
        if edge is not None:
            out.append(edge)
    return out


def _model_edge(
    rel: Points,
    along: FloatArray,
    *,
    near: np.ndarray,
    member: np.ndarray,
    normal: Vector3,
    direction: Vector3,
) -> ModelEdge | None:
    """The face of normal ``normal`` through the points ``near`` (about the axis; ``member``: all the model's
    points with that normal; ``rel``: points relative to the axis point) when the axis runs along its edge."""
    depth = rel @ normal
    on_gap = near & (np.abs(depth) <= MAX_GAP_M)
    if int(on_gap.sum()) < MIN_FACE_POINTS:
        return None
    plane, noise = _plane_noise(depth[on_gap])
    on = member & (np.abs(depth - plane) <= max(BAND_SIGMAS * noise, 1e-3))
    across = np.cross(direction, normal)
    s = rel @ across
    if np.median(s[on & near]) < 0.0:
        across = -across
        s = -s
    face = on & (s >= -MAX_GAP_M - BAND_SIGMAS * noise)
    beyond = on & near & ~face
    if int(face.sum()) < MIN_FACE_POINTS or int(beyond.sum()) > ONE_SIDED * int((on & near).sum()):
        return None  # the face runs on past the axis: the axis crosses it, it does not bound it
    width = float(np.quantile(s[face], 0.99))
    if width < MIN_WIDTH_M:
        return None
    window = (-MAX_GAP_M - 2.0 * BAND_SIGMAS * noise, min(width, 2.0 * MAX_GAP_M + 0.05))
    t = along[face & (s <= window[1])]
    if len(t) < MIN_FACE_POINTS:
        return None
    ends = (float(t.min()) + MARGIN_M, float(t.max()) - MARGIN_M)
    inside = (along >= ends[0]) & (along <= ends[1]) & (s >= window[0]) & (s <= window[1])
    inside &= np.abs(depth - plane) <= BAND_SIGMAS * noise + STRIP_M
    loc = locate_edge(s[inside], depth[inside] - plane, window, noise)
    if loc is None or abs(loc.offset_m) > MAX_GAP_M:
        return None
    return ModelEdge(normal, across, plane, loc, ends, width - loc.offset_m, noise)


def _covariance_direction(cov: FloatArray, unit: Vector3) -> float:
    """The variance of ``cov`` ((3, 3)) along ``unit``."""
    return float(unit @ cov @ unit)


def edge_update(
    edge: ModelEdge, fit: Stretched, line: tuple[Vector3, Vector3], target: Points, cov: FloatArray
) -> EdgeUpdate | None:
    """The scan's edge of ``edge`` (source frame) where ``fit`` carries it, and the axis's placement (``line``:
    point and unit direction, source frame, carried by ``fit``; covariance ``cov`` across it, target frame)
    updated by it. None when the scan holds too few of the face's points about where the fit puts the edge."""
    pos, direction = line
    pos_t, dir_t = fit.carry_line(pos, direction)
    normal_t = carried_normals(fit, edge.normal[None, :])[0]
    normal_t = normal_t - (normal_t @ dir_t) * dir_t
    normal_t /= np.linalg.norm(normal_t)
    across_t = np.cross(dir_t, normal_t)
    carried_across = fit.similarity.apply_direction(fit.linear() @ edge.across)
    if across_t @ carried_across < 0.0:
        across_t = -across_t
    edge_t, _ = fit.carry_line(pos + edge.edge.offset_m * edge.across + edge.depth_m * edge.normal, direction)
    lo_t = float((fit.carry_line(pos + edge.along_m[0] * direction, direction)[0] - pos_t) @ dir_t)
    hi_t = float((fit.carry_line(pos + edge.along_m[1] * direction, direction)[0] - pos_t) @ dir_t)
    scale = float(np.linalg.norm(fit.similarity.apply_direction(fit.linear() @ edge.across)))
    sigma_fit = math.sqrt(max(_covariance_direction(cov, across_t), 0.0))
    reach = min(max(WINDOW_SIGMAS * sigma_fit, MIN_WINDOW_M), 0.5 * edge.width_m * scale)
    rel = target - edge_t
    t = rel @ dir_t
    s = rel @ across_t
    depth = rel @ normal_t
    window = (-reach, reach + MIN_WINDOW_M)
    slab = (t >= min(lo_t, hi_t)) & (t <= max(lo_t, hi_t)) & (s >= window[0]) & (s <= window[1])
    depth_reach = max(MAX_GAP_M, 3.0 * math.sqrt(max(_covariance_direction(cov, normal_t), 0.0)))
    inner = slab & (s > MIN_WINDOW_M) & (np.abs(depth) <= depth_reach)
    if int(inner.sum()) < MIN_FACE_POINTS:
        return None
    plane, noise = _plane_noise(depth[inner])
    slab &= np.abs(depth - plane) <= BAND_SIGMAS * noise + STRIP_M
    loc = locate_edge(s[slab], depth[slab] - plane, window, noise)
    if loc is None:
        return None
    inset_std = abs(edge.edge.offset_m) * scale * math.log(MAX_STRETCH) / 3.0
    variance = loc.std_m**2 + (scale * edge.edge.std_m) ** 2 + inset_std**2
    innovation = loc.offset_m
    total = _covariance_direction(cov, across_t) + variance
    if innovation**2 > AGREEMENT_SIGMAS**2 * total:
        widened = cov + np.outer(across_t, across_t) * (innovation / AGREEMENT_SIGMAS) ** 2
        return EdgeUpdate(np.zeros(3), widened, innovation, math.sqrt(variance), agrees=False)
    gain = cov @ across_t / total
    updated = cov - np.outer(gain, across_t @ cov)
    return EdgeUpdate(gain * innovation, updated, innovation, math.sqrt(variance), agrees=True)
