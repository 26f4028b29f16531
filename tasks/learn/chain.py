"""Segments to the manipulation chain M with extents C (DESCRIPTOR.md signs and extents).

Per segment: each marker is still or moving (best model of its samples, ``tasks.fit.select``). The moving
object markers, with the hand markers that stay rigid with them, are one rigid part and get one joint fit;
a segment where only hand markers move is a reach or a release and is dropped, as are still and undefined
segments. Adjacent primitives of the same kind about the same axis are merged and refitted. Angles and
distances are measured from the still samples just before the motion to those just after it when there are
any, so a change point placed a few samples inside a slow start or stop loses no extent.
"""

from __future__ import annotations

import itertools
from dataclasses import dataclass, field, replace
from typing import Any

import numpy as np
from scipy.spatial.transform import Rotation

from tasks.arrays import FloatArray, Points
from tasks.errors import bounded
from tasks.fit.geometry import angle_between_axes, perpendicular_basis, unit
from tasks.fit.interpolate import bracketed, positions_at
from tasks.fit.noise import MAD_TO_SIGMA, independent_draws
from tasks.fit.rigid import PartMotion, ScrewAxis, part_motion, rss_about_axis, screw_axis
from tasks.fit.rotation import RotationFit, angles_about, fit_rotation
from tasks.fit.select import KINDS, SIGMA_MIN_M, Kind, SelectParams, choose_bic, choose_eigen, model_costs
from tasks.fit.translation import TranslationFit, fit_translation, travels_agree
from tasks.learn.params import LearnParams
from tasks.learn.prepare import MIN_SAMPLES, PreparedRecording, is_orientation_marker
from tasks.segment.changepoint import MIN_MODEL_SAMPLES, marker_costs
from tasks.segment.tracks import Track, span_indices

HAND_ONLY = "only hand markers move"
"""Note of a reach or release segment (normal, dropped without a warning)."""


@dataclass(frozen=True)
class SegmentFit:
    """One segment's model: kind, span (s), the markers of the moving part, fits and scores."""

    kind: Kind
    t_start: float
    t_end: float
    markers: tuple[str, ...] = ()
    still_markers: frozenset[str] = frozenset()
    rotation: RotationFit | None = None
    translation: TranslationFit | None = None
    scores: dict[str, float] = field(default_factory=dict)
    eigenvalues: tuple[float, float, float] = (0.0, 0.0, 0.0)
    extent: float = 0.0
    note: str = ""


def _samples(track: Track, t0: float, t1: float) -> tuple[FloatArray, Points]:
    i, j = span_indices(track, t0, t1)
    return track.t_s[i:j], track.points[i:j]


def marker_kind(track: Track, t0: float, t1: float, undefined: float) -> Kind | None:
    """Best model of one marker's samples over [t0, t1) (s), None with too few samples; still when the marker is
    not ``displaced`` beyond its noise, whatever model its scatter favours."""
    i, j = span_indices(track, t0, t1)
    if j - i < MIN_MODEL_SAMPLES:
        return None
    _, costs = marker_costs(track, np.array([i]), np.array([j]), undefined)
    kind = KINDS[int(np.argmin(costs[0]))]
    return "still" if kind != "still" and not displaced(track, t0, t1) else kind


SHIFT_SIGMAS = 4.0
"""A marker is displaced within a span when the mean positions of two of its quarters differ by this many of their
standard errors (Mahalanobis, under its noise covariance): noise passes 4 sigmas in 3-D once in 500 pairs."""
SHIFT_PARTS = 4
"""Parts of a span whose mean positions are compared: a door swung out and back within the span has the same mean
in its halves, not in its quarters."""


def noise_draws(track: Track, i: int, j: int) -> float:
    """How many independent draws of its noise ``track``'s samples [i, j) hold (``independent_draws`` under the
    track's noise correlation time), at least one."""
    if j <= i:
        return 1.0
    return independent_draws(float(j - i), float(track.t_s[j - 1] - track.t_s[i]), track.noise_tau_s)


def displaced(track: Track, t0: float, t1: float) -> bool:
    """Whether a marker's position over [t0, t1) (s) changes beyond its noise (``SHIFT_SIGMAS``) between two of the
    span's ``SHIFT_PARTS`` equal parts of time (a part's mean averages the noise down by its ``noise_draws``); a
    span with fewer samples than a model needs is not displaced."""
    i, j = span_indices(track, t0, t1)
    if j - i < MIN_MODEL_SAMPLES:
        return False
    edges = i + np.searchsorted(track.t_s[i:j], np.linspace(t0, t1, SHIFT_PARTS + 1)[1:-1])
    bounds = [i, *(int(e) for e in edges), j]
    means = []
    weights = []
    for a, b in itertools.pairwise(bounds):
        if b > a:
            means.append(track.points[a:b].mean(axis=0))
            weights.append(noise_draws(track, a, b))
    precision = np.linalg.pinv(track.noise_cov + np.eye(3) * SIGMA_MIN_M**2)
    for (ma, wa), (mb, wb) in itertools.combinations(zip(means, weights, strict=True), 2):
        delta = mb - ma
        if float(delta @ precision @ delta) / (1.0 / wa + 1.0 / wb) > SHIFT_SIGMAS**2:
            return True
    return False


def rigid_with(track: Track, ref: Track, t0: float, t1: float, tol: float) -> bool:
    """Whether ``track`` keeps its distance to ``ref`` over [t0, t1) (s) within ``tol`` (std, m). A distance's
    spread needs the few samples a model does (``MIN_MODEL_SAMPLES``), not the more a marker's fit needs: a
    hand riding a drawer for 0.6 s is 7 samples at 11 Hz."""
    t, p = _samples(track, t0, t1)
    tr, pr = _samples(ref, t0, t1)
    if len(t) < MIN_MODEL_SAMPLES or len(tr) < 2:
        return False
    return float(np.std(distances_to(t, p, tr, pr))) < tol


def distances_to(t_s: FloatArray, pts: Points, ref_t_s: FloatArray, ref_pts: Points) -> FloatArray:
    """Distances (m) of samples at times ``t_s`` (s) to a reference marker interpolated linearly at those times;
    samples the reference does not bracket (outside its track, or within an occlusion of it) are left out."""
    ok = bracketed(ref_t_s, t_s)
    out: FloatArray = np.linalg.norm(pts[ok] - positions_at(ref_t_s, ref_pts, t_s[ok]), axis=1)
    return out


def fit_span(
    prep: PreparedRecording, t0: float, t1: float, params: LearnParams, force: Kind | None = None
) -> SegmentFit:
    """Classify and fit one time span [t0, t1) (seconds) of the prepared recording."""
    kinds = {tr.name: marker_kind(tr, t0, t1, params.undefined_nats) for tr in prep.tracks}
    still = frozenset(n for n, k in kinds.items() if k == "still")
    moving = [tr for tr in prep.tracks if kinds[tr.name] not in (None, "still")]
    if force is not None:
        moving = [tr for tr in prep.tracks if kinds[tr.name] is not None and tr.name not in still] or moving
    if not moving:
        return SegmentFit("still", t0, t1, still_markers=still, note="no marker moves")
    objects = [tr for tr in moving if tr.name not in prep.hand]
    all_hand = all(tr.name in prep.hand for tr in prep.tracks)
    if objects:
        group = objects + [
            tr for tr in moving if tr.name in prep.hand and rigid_with(tr, objects[0], t0, t1, params.rigid_tol_m)
        ]
    elif all_hand:
        group = moving
    else:
        who = bounded([tr.name for tr in moving])
        return SegmentFit("undefined", t0, t1, still_markers=still, note=f"{HAND_ONLY} ({who})")
    group.sort(key=lambda tr: tr.name)
    samples = [_samples(tr, t0, t1) for tr in group]
    pts = [p for _, p in samples]
    names: tuple[str, ...] = tuple(tr.name for tr in group)
    sel = SelectParams(params.undefined_nats, params.min_rotation_rad)

    if params.classifier == "eigen":
        primary = max(range(len(pts)), key=lambda i: float(np.ptp(pts[i], axis=0).max()))
        single = [pts[primary]]
        tf = fit_translation(single)
        kind: Kind = force or choose_eigen(tf.eigenvalues, params.t0, 5.0 * params.sigma_floor_m)
        rf = fit_rotation(single, 3.0 * params.sigma_floor_m, algebraic_only=True) if kind == "rotation" else None
        return SegmentFit(kind, t0, t1, (names[primary],), still, rf, tf, {}, tf.eigenvalues, _extent(kind, rf, tf))

    tf = fit_translation(pts)
    sigma = model_sigma(group, pts, params.sigma_floor_m)
    sigma_hf = float(np.sqrt(np.mean([tr.sigma_hf_m**2 for tr in group])))
    motion = _part_motion(group, prep, t0, t1) if params.use_orientations else None
    screw = screw_axis(motion) if motion is not None else None
    rf = fit_rotation(pts, 3.0 * sigma, start=(screw.pos, screw.dir) if screw is not None else None)
    evidence = _evidence_per_sample(group, t0, t1)
    if motion is not None and screw is not None and np.isfinite(rf.dir_std_rad) and screw.dir_std_rad > 0:
        rf = _best_direction(pts, rf, screw, motion, sigma=sigma, evidence=evidence, undefined=params.undefined_nats)
    n = np.array([float(tf.n) * evidence])
    rss_still = np.array([sum(float(((p - p.mean(axis=0)) ** 2).sum()) for p in pts)]) * evidence
    costs = model_costs(
        n,
        rss_still,
        np.array([tf.rss * evidence]),
        np.array([rf.rss * evidence]),
        sigma_still=sigma_hf,
        sigma_model=sigma,
        undefined=params.undefined_nats,
    )[0]
    if max(rf.radii, default=0.0) < MIN_RADIUS_SIGMAS * sigma:
        costs[KINDS.index("rotation")] = np.inf
    if len(group) > 1 and not travels_agree([t for t, _ in samples], [p @ tf.dir for p in pts]):
        costs[KINDS.index("translation")] = np.inf  # a sliding part moves all its markers alike
    angle = swept_angle(pts, rf)
    if motion is not None:
        costs += evidence * orientation_costs(motion, rf.dir, sigma, params.undefined_nats)
    kind = choose_bic(costs, angle, sel, force)
    scores: dict[str, float] = {str(k): float(c) for k, c in zip(KINDS, costs, strict=True)}
    return SegmentFit(kind, t0, t1, names, still, rf, tf, scores, tf.eigenvalues, _extent(kind, rf, tf))


PATH_DEVIATION = 0.0075
"""A mechanism's path strays from its ideal circle or line by about this fraction of the path's size: play and
flex of a few tenths of a degree times the lever arm (a hinge's 1-6 mm over half-metre door paths)."""


def model_sigma(group: list[Track], pts: list[Points], floor_m: float) -> float:
    """Noise sigma (m) the motion models are judged with: each marker's sensor noise, or the mechanism's own
    deviation from an ideal path when larger, ``floor_m`` on a large path and ``PATH_DEVIATION`` of a small one
    (a 3 cm lever's arc is not within 2 mm of a line by play)."""
    size = max((float(np.ptp(p, axis=0).max()) for p in pts if len(p)), default=0.0)
    floor = min(floor_m, PATH_DEVIATION * size)
    return float(np.sqrt(np.mean([max(tr.sigma_hf_m, floor) ** 2 for tr in group])))


MIN_RADIUS_SIGMAS = 3.0
"""A rotation needs its largest marker radius at least this many model noise sigmas: a smaller circle does not
resolve its centre from the samples' scatter, and a circle fitted to scatter alone has a radius of about sigma."""


SWEPT_PERCENTILE = 2.0
"""Percentile of a marker's angles about the axis taken as either end of its arc (a stray sample does not widen it)."""


def swept_angle(pts: list[Points], rf: RotationFit) -> float:
    """Widest arc (rad) that a marker's samples cover about the fitted axis: a door swung to and fro covers its
    arc whatever its net turn. The arc between the first and the last sample counts whatever lies between them:
    a part seen at one end of an occlusion gap and again at its other end turned through the gap."""
    out = 0.0
    for p in pts:
        ang = angles_about(p, rf.pos, rf.dir)
        lo, hi = np.percentile(ang, [SWEPT_PERCENTILE, 100.0 - SWEPT_PERCENTILE])
        out = max(out, float(hi - lo), abs(float(ang[-1] - ang[0])))
    return out


def _evidence_per_sample(group: list[Track], t0: float, t1: float) -> float:
    """Mean evidence weight (``tasks.segment.tracks.sample_weights``) of the group's samples in [t0, t1)."""
    total = count = 0.0
    for tr in group:
        i, j = span_indices(tr, t0, t1)
        total += float(tr.weights[i:j].sum())
        count += j - i
    return total / count if count else 1.0


def _with_screw_direction(pts: list[Points], rf: RotationFit, screw: ScrewAxis, loss_scale_m: float) -> RotationFit:
    """The circle fit's axis direction and the part's turn axis averaged by their inverse variances, then the
    axis point and radii refitted about it (rad, m)."""
    w_fit = 1.0 / max(rf.dir_std_rad, 1e-9) ** 2
    w_turn = 1.0 / screw.dir_std_rad**2
    sign = 1.0 if float(np.dot(rf.dir, screw.dir)) >= 0 else -1.0
    direction = unit(w_fit * rf.dir + w_turn * sign * screw.dir)
    out = fit_rotation(pts, loss_scale_m, start=(rf.pos, direction), fixed_dir=True)
    return replace(out, dir_std_rad=float(1.0 / np.sqrt(w_fit + w_turn)))


def _best_direction(
    pts: list[Points],
    rf: RotationFit,
    screw: ScrewAxis,
    motion: PartMotion,
    *,
    sigma: float,
    evidence: float,
    undefined: float,
) -> RotationFit:
    """The circle fit's axis and the part's turn axis averaged by their inverse variances when they agree within
    ``AXES_AGREE_SIGMAS``; else whichever of the two, its circle refitted, explains the markers' positions and the
    part's orientations at least cost (nats, at noise ``sigma`` m): a short noisy arc's circle fit can land far
    beyond its linearised uncertainty, and a turn measured from a noisy reference configuration can too."""
    fused = _with_screw_direction(pts, rf, screw, 3.0 * sigma)
    apart = angle_between_axes(rf.dir, screw.dir, signed=False)
    if apart <= AXES_AGREE_SIGMAS * float(np.hypot(rf.dir_std_rad, screw.dir_std_rad)):
        return fused
    sign = 1.0 if float(np.dot(rf.dir, screw.dir)) >= 0 else -1.0
    turn = fit_rotation(pts, 3.0 * sigma, start=(rf.pos, sign * screw.dir), fixed_dir=True)
    turn = replace(turn, dir_std_rad=screw.dir_std_rad)

    def cost(f: RotationFit) -> float:
        return evidence * (f.rss / (2.0 * sigma**2) + float(orientation_costs(motion, f.dir, sigma, undefined)[2]))

    return min((rf, turn), key=cost)


AXES_AGREE_SIGMAS = 3.0
"""Two estimates of one axis direction agree when they differ by at most this many of their combined sigmas."""


def _part_motion(group: list[Track], prep: PreparedRecording, t0: float, t1: float) -> PartMotion | None:
    """Orientation over [t0, t1) of the rigid part carried by the group's object markers (the hand's slip)."""
    objects = [tr for tr in group if tr.name not in prep.hand]
    samples = [_samples(tr, t0, t1) for tr in objects]
    samples = [(t, p) for t, p in samples if len(t) >= MIN_SAMPLES]
    return part_motion([t for t, _ in samples], [p for _, p in samples])


def orientation_costs(motion: PartMotion, axis_dir: FloatArray, sigma_m: float, undefined: float) -> FloatArray:
    """(4,) extra cost (nats) of still, translation, rotation, undefined from the rigid part's orientation: the
    excess residual (m^2, over its markers) of no turn (translation) or of a turn about ``axis_dir`` only
    (rotation) over the best turn, at noise ``sigma_m`` per axis; each sample's share truncated at ``undefined``
    as in the model choice. Still and undefined are left as the positions score them."""
    no_turn = np.minimum((motion.rss_no_turn - motion.rss_best) / (2.0 * sigma_m**2), undefined)
    about = np.minimum((rss_about_axis(motion, axis_dir) - motion.rss_best) / (2.0 * sigma_m**2), undefined)
    return np.array([0.0, float(no_turn.sum()), float(about.sum()), 0.0])


def _extent(kind: Kind, rf: RotationFit | None, tf: TranslationFit | None) -> float:
    if kind == "rotation" and rf is not None:
        return rf.angle_rad
    if kind == "translation" and tf is not None:
        return tf.distance_m
    return 0.0


MERGE_NOISE_SIGMAS = 2.0
"""A union's fit may exceed the mechanism's own departure from its ideal path by this many times the sensor noise
(3-D rms) of its markers."""
PIECE_RMS_FACTOR = 3.0
"""A union's fit may depart from an ideal line or circle at most this many times as far as its pieces' own fits
do: a wobbling door cut into arcs fits one circle about as well as its arcs; a knob's turn and the door's swing
after it, each fitted to a fraction of a millimetre, do not fit one circle within centimetres."""


def _own_fit(f: SegmentFit) -> RotationFit | TranslationFit | None:
    """The fit of the kind a segment is (None for still and undefined)."""
    return f.rotation if f.kind == "rotation" else f.translation if f.kind == "translation" else None


def _fit_rms(f: SegmentFit) -> float:
    """RMS residual (m) of a primitive's own fit (0 for other kinds)."""
    fit = _own_fit(f)
    return fit.rms_m if fit is not None else 0.0


def _residual_sigma(parts: list[SegmentFit]) -> float:
    """Per-axis scatter (m) of the pieces' samples about their own fits: their residual sum of squares over its
    degrees of freedom (two residual axes per sample, less each fit's parameters: direction 2, axis point 2 or the
    line's offset 2 per marker, and a circle's radius and height per marker); inf without a fitted piece."""
    rss = dof = 0.0
    for f in parts:
        fit = _own_fit(f)
        if fit is None:
            continue
        m = max(len(f.markers), 1)
        rss += fit.rss
        dof += max(2.0 * fit.n - (4.0 + 2.0 * m if f.kind == "rotation" else 2.0 + 2.0 * m), 1.0)
    return float(np.sqrt(rss / dof)) if dof else float("inf")


def merge_tolerance(
    prep: PreparedRecording, union: SegmentFit, parts: list[SegmentFit], mechanism_rms_m: float
) -> float:
    """Largest rms (m) of one primitive's fit over a union of segments: ``PIECE_RMS_FACTOR`` times the pieces' own
    scatter about their fits (their largest rms, or their per-axis residual per degree of freedom as 3-D rms where
    short pieces absorb their noise), and never more than the mechanism's own departure from an ideal line or
    circle (``mechanism_rms_m``) combined with the markers' noise (camera tracks scatter by centimetres). The
    pieces' scatter already holds the sensor noise, so it is not added to it again. The noise is the sensor's
    from the data, or the pieces' residual scatter where that is less (the high-frequency estimate also counts
    timing jitter and depth noise along the path, which a fit's residual does not)."""
    by_name = {tr.name: tr for tr in prep.tracks}
    sensor = max((by_name[n].sigma_hf_m for n in union.markers if n in by_name), default=0.0)
    residual = _residual_sigma(parts)
    spread = np.sqrt(2.0) * residual if np.isfinite(residual) else 0.0
    scatter = max(*(_fit_rms(f) for f in parts), spread)
    ceiling = np.hypot(mechanism_rms_m, MERGE_NOISE_SIGMAS * np.sqrt(3.0) * min(sensor, residual))
    return float(min(PIECE_RMS_FACTOR * scatter, ceiling))


def _coordinate(f: SegmentFit, pts: Points) -> FloatArray:
    """Angle (rad, unwrapped) or distance (m) of points along the fitted primitive ``f``."""
    if f.kind == "rotation" and f.rotation is not None:
        e1, e2 = perpendicular_basis(f.rotation.dir)
        q = pts - f.rotation.pos
        out: FloatArray = np.unwrap(np.arctan2(q @ e2, q @ e1))
        return out
    if f.translation is not None:
        return pts @ f.translation.dir
    return np.zeros(len(pts))


def _union_is_one_motion(prep: PreparedRecording, union: SegmentFit, parts: list[SegmentFit], tol_m: float) -> bool:
    """The union fits one model within ``tol_m`` rms and every part moves forward along it."""
    fit = union.rotation if union.kind == "rotation" else union.translation
    if fit is None or fit.rms_m > tol_m:
        return False
    by_name = {tr.name: tr for tr in prep.tracks}
    for part in parts:
        nets = [
            float(np.median(c[-3:]) - np.median(c[:3]))
            for name in union.markers
            if len(c := _coordinate(union, _samples(by_name[name], part.t_start, part.t_end)[1])) >= MIN_SAMPLES
        ]
        if nets and float(np.median(nets)) <= 0.0:
            return False
    return True


def same_joint(prep: PreparedRecording, a: SegmentFit, b: SegmentFit) -> bool:
    """Whether two primitives can be one joint's motion: the same part moves, that is the same object markers (a
    lever pressed moves its own markers; the door swung after it moves the lever's and the leaf's). Short pieces
    of one wobbling real motion have confidently different axes, so the axes are left to the union's fit."""
    return {n for n in a.markers if n not in prep.hand} == {n for n in b.markers if n not in prep.hand}


def merge_adjacent(prep: PreparedRecording, fits: list[SegmentFit], params: LearnParams) -> list[SegmentFit]:
    """Merge consecutive primitives of one motion (no other primitive between them; ``same_joint``; the union fits
    one line or circle within ``merge_tolerance``; every part moves forward along it, so an opening and the closing
    after it stay apart) and refit the union. Real mechanisms are not ideal circles and a robot's or hand's path wobbles
    about them, so the change-point search may cut one door swing into arcs of other radii and senses."""
    out = list(fits)
    changed = True
    while changed:
        changed = False
        moving = [i for i, f in enumerate(out) if f.kind in ("rotation", "translation")]
        for i, j in itertools.pairwise(moving):
            if (
                any(out[k].kind in ("rotation", "translation") for k in range(i + 1, j))
                or not same_joint(prep, out[i], out[j])
                or _legs_of_one_reversal(out[i], out[j])
            ):
                continue
            union = fit_span(prep, out[i].t_start, out[j].t_end, params)
            if union.kind not in ("rotation", "translation") and union.scores:
                # the wobble of a long real motion can cost more than "undefined" at the model noise floor;
                # the union is one motion when the better primitive fits it within the tolerance
                best = min(("rotation", "translation"), key=lambda k: union.scores[k])
                union = fit_span(prep, out[i].t_start, out[j].t_end, params, force=best)  # type: ignore[arg-type]
            if union.kind in ("rotation", "translation") and _union_is_one_motion(
                prep, union, [out[i], out[j]], merge_tolerance(prep, union, [out[i], out[j]], params.merge_rms_m)
            ):
                out[i : j + 1] = [replace(union, still_markers=out[i].still_markers)]
                changed = True
                break
    return out


def _legs_of_one_reversal(a: SegmentFit, b: SegmentFit) -> bool:
    """Whether ``a`` and ``b`` are two legs of one motion split at its reversal (``tasks.learn.reversals``): one fit,
    its direction turned; they go opposite ways and are never one motion, so no union is fitted for them."""
    if a.kind != b.kind:
        return False
    if a.rotation is not None and b.rotation is not None and a.kind == "rotation":
        fa, fb = a.rotation, b.rotation
        return bool(np.array_equal(fa.pos, fb.pos) and np.allclose(fa.dir, -fb.dir))
    if a.translation is not None and b.translation is not None and a.kind == "translation":
        ta, tb = a.translation, b.translation
        return bool(np.array_equal(ta.centroid, tb.centroid) and np.allclose(ta.dir, -tb.dir))
    return False


def rest_window(name: str, fits: list[SegmentFit], i: int, step: int) -> tuple[float, float] | None:
    """Time span (s) of the run of segments next to segment i (``step`` -1 before, +1 after) where marker
    ``name`` is still: its rest there, with the slow start or stop of the motion a small part of it."""
    j = i + step
    lo = hi = None
    while 0 <= j < len(fits) and name in fits[j].still_markers:
        lo = fits[j].t_start if lo is None or step < 0 else lo
        hi = fits[j].t_end if hi is None or step > 0 else hi
        j += step
    if lo is None or hi is None:
        return None
    return lo, hi


def _rest_samples(track: Track, fits: list[SegmentFit], i: int, step: int) -> Points | None:
    """Samples of ``track`` in its rest window next to segment i (None when it moves there)."""
    window = rest_window(track.name, fits, i, step)
    if window is None:
        return None
    pts = _samples(track, *window)[1]
    return pts if len(pts) else None


def _rest_orientation(times: FloatArray, quats: FloatArray, window: tuple[float, float]) -> FloatArray | None:
    """Mean orientation (rotation matrix) of a rigid body over a rest window, None without samples."""

    keep = (times >= window[0]) & (times < window[1])
    if keep.sum() < MIN_SAMPLES:
        return None
    rots = Rotation.from_quat(quats[keep])
    mean = rots.mean()
    for _ in range(3):  # drop the slow start or stop of the motion left in the rest window
        dist = (rots * mean.inv()).magnitude()
        med = float(np.median(dist))
        near = dist <= med + 3.0 * MAD_TO_SIGMA * float(np.median(np.abs(dist - med))) + 1e-9
        if near.sum() < MIN_SAMPLES:
            break
        mean = rots[near].mean()
    out: FloatArray = mean.as_matrix()
    return out


def _orientation_angle(
    prep: PreparedRecording, fits: list[SegmentFit], i: int, axis_dir: FloatArray, coarse: float
) -> float | None:
    """Turn (rad) about ``axis_dir`` between the rest orientations of a rigid-body marker of segment i's part,
    or None when no marker of the part has orientations at rest on both sides."""

    angles = []
    for name in fits[i].markers:
        if name not in prep.orientations:
            continue
        times, quats = prep.orientations[name]
        before = rest_window(name, fits, i, -1)
        after = rest_window(name, fits, i, +1)
        if before is None or after is None:
            continue
        r0 = _rest_orientation(times, quats, before)
        r1 = _rest_orientation(times, quats, after)
        if r0 is None or r1 is None:
            continue
        rotvec = Rotation.from_matrix(r1 @ r0.T).as_rotvec()
        angles.append(float(np.dot(rotvec, axis_dir)))
    if not angles:
        return None
    fine = float(np.mean(angles))
    return fine + 2.0 * np.pi * round((coarse - fine) / (2.0 * np.pi))


REST_TOLERANCE_SIGMAS = 3.0
"""A rest sample lies within this many noise sigmas (3-D) of the rest position; farther ones are the slow start or
stop of the neighbouring motion, which the segmentation left in the still segment."""


def rest_position(samples: Points, sigma_m: float) -> FloatArray:
    """Robust rest position (m) of a marker from its still samples: median, then median of the samples near it."""
    centre = np.median(samples, axis=0)
    tol = max(REST_TOLERANCE_SIGMAS * np.sqrt(3.0) * sigma_m, 1e-4)
    for _ in range(3):
        near = samples[np.linalg.norm(samples - centre, axis=1) < tol]
        if len(near) < MIN_SAMPLES:
            break
        centre = np.median(near, axis=0)
    out: FloatArray = centre
    return out


END_WINDOW_S = 0.05
"""Samples within this time (s) of a primitive's first or last sample are averaged into its end position where
no rest is next to it (a reversal): at a turning point the part barely moves for that long."""


def _end(t_s: FloatArray, seg: Points, first: bool) -> Points:
    """(1, 3) mean position (m) of the samples within ``END_WINDOW_S`` of the first (or last) sample."""
    near = t_s <= t_s[0] + END_WINDOW_S if first else t_s >= t_s[-1] - END_WINDOW_S
    out: Points = seg[near].mean(axis=0)[None]
    return out


def refine_extents(prep: PreparedRecording, fits: list[SegmentFit]) -> list[SegmentFit]:
    """Extents from the rest positions just before and just after each primitive (when the part is still there),
    measured about / along the fitted axis; the turn of a rotation from the rigid body's orientations where the
    recording has them, else by Procrustes over two or more markers of the part, else the markers' turns weighted
    by their squared radii (the inverse variance of an angle: a marker near the axis turns by its noise alone)."""
    by_name = {tr.name: tr for tr in prep.tracks}
    out = list(fits)
    for i, f in enumerate(fits):
        if f.kind not in ("rotation", "translation"):
            continue
        nets: list[float] = []
        wts: list[float] = []
        rests: list[tuple[FloatArray, FloatArray, bool]] = []
        for name in f.markers:
            tr = by_name[name]
            _, seg = _samples(tr, f.t_start, f.t_end)
            if len(seg) < MIN_SAMPLES:
                continue
            before = _rest_samples(tr, fits, i, -1)
            after = _rest_samples(tr, fits, i, +1)
            t_seg = _samples(tr, f.t_start, f.t_end)[0]
            head = rest_position(before, tr.sigma_hf_m)[None] if before is not None else _end(t_seg, seg, True)
            tail = rest_position(after, tr.sigma_hf_m)[None] if after is not None else _end(t_seg, seg, False)
            if before is not None and after is not None:
                rests.append((head[0], tail[0], name in prep.hand))
            path = np.concatenate([head, seg, tail])
            if f.kind == "rotation" and f.rotation is not None:
                e1, e2 = perpendicular_basis(f.rotation.dir)
                q = path - f.rotation.pos
                coord = np.unwrap(np.arctan2(q @ e2, q @ e1))
                weight = float(np.median(np.linalg.norm(q - np.outer(q @ f.rotation.dir, f.rotation.dir), axis=1))) ** 2
            elif f.translation is not None:
                coord = path @ f.translation.dir
                weight = 1.0
            else:
                continue
            nets.append(float(coord[-1] - coord[0]))
            wts.append(weight * len(seg))
        if nets and sum(wts) > 0:
            net = float(np.average(nets, weights=wts))
            pairs = [(b, a) for b, a, hand in rests if not hand]  # a hand is not on the part at its rests
            if f.kind == "rotation" and f.rotation is not None:
                oriented = _orientation_angle(prep, fits, i, f.rotation.dir, net)
                if oriented is not None:
                    net = oriented
                elif len(pairs) >= 2:
                    net = _procrustes_angle(pairs, f.rotation.dir, net)
            out[i] = replace(f, extent=abs(net))
    return out


MIN_SPREAD_M = 0.005
"""Rest positions of a rigid part must spread this far (in the rotation plane) to fix its turn by themselves."""


def _procrustes_angle(rests: list[tuple[FloatArray, FloatArray]], axis_dir: FloatArray, coarse: float) -> float:
    """Rotation about ``axis_dir`` that maps the part's rest marker positions before onto those after.

    Centring each set removes the axis position, whose error (tenths of a millimetre on a 1 cm bottle cap) would
    otherwise bias the angle; the turn count comes from the unwrapped ``coarse`` angle (rad).
    """
    before = np.array([b for b, _ in rests])
    after = np.array([a for _, a in rests])
    e1, e2 = perpendicular_basis(axis_dir)
    u = (before - before.mean(axis=0)) @ np.column_stack([e1, e2])
    v = (after - after.mean(axis=0)) @ np.column_stack([e1, e2])
    if float(np.sqrt((u**2).sum(axis=1).mean())) < MIN_SPREAD_M:
        return coarse
    cross = float(np.sum(u[:, 0] * v[:, 1] - u[:, 1] * v[:, 0]))
    dot = float(np.sum(u * v))
    fine = float(np.arctan2(cross, dot))
    return fine + 2.0 * np.pi * round((coarse - fine) / (2.0 * np.pi))


def motion_m(f: SegmentFit) -> float:
    """How far the part moved in a primitive: arc length at the largest marker radius, or distance (m)."""
    if f.kind == "rotation" and f.rotation is not None:
        return f.extent * max(f.rotation.radii, default=0.0)
    return f.extent if f.kind == "translation" else 0.0


def drop_small(prep: PreparedRecording, fits: list[SegmentFit], min_motion_m: float) -> list[SegmentFit]:
    """Primitives that move the part less than ``min_motion_m`` (wiggles before a grasp), or that no marker of
    theirs samples ``MIN_MODEL_SAMPLES`` times (a circle passes through any three points: a few samples of coloured
    noise cut at their turning points support no motion model), become undefined."""
    by_name = {tr.name: tr for tr in prep.tracks}
    return [_small(f, min_motion_m, by_name) for f in fits]


def _small(f: SegmentFit, min_motion_m: float, tracks: dict[str, Track]) -> SegmentFit:
    if f.kind not in ("rotation", "translation"):
        return f
    if motion_m(f) < min_motion_m:
        return replace(f, kind="undefined", note=f"moves {motion_m(f) * 1000:.1f} mm < {min_motion_m * 1000:.1f} mm")
    spans = [span_indices(tracks[n], f.t_start, f.t_end) for n in f.markers if n in tracks]
    samples = max((j - i for i, j in spans), default=0)
    if samples < MIN_MODEL_SAMPLES:
        return replace(f, kind="undefined", note=f"{samples} samples < {MIN_MODEL_SAMPLES}")
    return f


def primitive_fit_json(f: SegmentFit) -> dict[str, Any]:
    """The ``fit`` block of a primitive: residual, eigenvalues, model scores (nats; the models the motion rules
    out, such as a translation whose markers travel unequal distances, are listed under ``ruled_out`` instead),
    axis uncertainty, and the evidence used (marker positions; a rigid body's orientations too)."""
    scores = {k: v for k, v in f.scores.items() if np.isfinite(v)}
    out: dict[str, Any] = {"eigenvalues": list(f.eigenvalues), "scores": scores}
    if ruled_out := sorted(k for k in f.scores if k not in scores):
        out["ruled_out"] = ruled_out
    out["evidence"] = ["positions", "orientations"] if any(map(is_orientation_marker, f.markers)) else ["positions"]
    if f.kind == "rotation" and f.rotation is not None:
        rf = f.rotation
        out.update(rms_m=rf.rms_m, radii_m=list(rf.radii), n=rf.n)
        if np.isfinite(rf.dir_std_rad):
            out.update(dir_std_rad=rf.dir_std_rad, pos_std_m=rf.pos_std_m)
    elif f.translation is not None:
        tf = f.translation
        out.update(rms_m=tf.rms_m, n=tf.n, dir_std_rad=tf.dir_std_rad)
    return out
