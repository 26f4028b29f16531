"""The real corpus: every labelled track in ``../shared/real`` as a case, with truths derived here (plain numpy,
independent of the learner) and the rates each is written at.

Assumed rates (the files have no stamps): Sturm robot tracks 30 Hz; ``articulation_models/door.txt`` 30 Hz (a
camera); ``articulation_models/drawer.txt`` 10 Hz (19 samples with 3 cm steps: at 30 Hz the drawer would open at
1 m/s); CHAMP relative poses 30 Hz. Verduyn pouring tracks have their own stamps and no labels
(``unlabelled_cases``).
"""

from __future__ import annotations

import itertools
import os
from pathlib import Path

import numpy as np

from bench.learn_corpus.case import Case, TruthPrimitive, resample
from bench.learn_corpus.rotations import Array, axis_angle_from_matrix, matrix_from_quat, unit

STURM_HZ = 30.0
"""Assumed rate of the Sturm robot tracks (no stamps; 1-2 mm steps at a robot's few cm/s)."""
CAMERA_HZ = 30.0
"""Assumed rate of camera-tracked poses (``door.txt``, CHAMP)."""
DRAWER_TXT_HZ = 10.0
"""Assumed rate of ``drawer.txt`` (3 cm between samples: a human drawer motion of 0.3 m/s)."""
RADIUS_TOL_M = 0.02
"""Radius tolerance around the published or fitted radius (the spread of Sturm's per-trial radii is 1 cm)."""
STURM_RADIUS_M = {"left_door": 0.344, "right_door": 0.385, "dishwasher": 0.656}
"""Published mean radii of the ``mechanisms_iros_2010`` mechanisms (``../shared/real/README.md``); each trial's
truth takes its own circle fit, which is within 2.2 cm of these (the trials grasp the handle at different points)."""
STURM_KIND = {"left_door": "rotation", "right_door": "rotation", "dishwasher": "rotation", "drawer": "translation"}
REVERSAL_HYSTERESIS_RAD = np.radians(10.0)
"""A turn reverses once the angle has come back this far from its extreme: 30x the door tag's angle jitter."""
SETTLE_RAD = np.radians(3.0)
"""A turn starts/ends where the smoothed angle leaves/reaches this band around its extremes (3x the jitter)."""
SMOOTH_SAMPLES = 5
"""Running-median width applied to camera angles (removes single-frame tag flips)."""
REPO = Path(__file__).resolve().parents[2]


def real_root() -> Path:
    """``$PBD_SHARED/real``, else the first ``shared/real`` beside the repository or one of its parents."""
    env = os.environ.get("PBD_SHARED")
    if env:
        return Path(env) / "real"
    for base in (REPO.parent, *REPO.parents[1:]):
        if (base / "shared" / "real").is_dir():
            return base / "shared" / "real"
    return REPO.parent / "shared" / "real"


# -- geometry -----------------------------------------------------------------------------------------------------
def fit_circle_3d(points: Array) -> tuple[Array, Array, float, float]:
    """Plane and circle through ``points`` (n, 3) m: centre, unit normal, radius (m) and RMS residual (m)
    (plane by SVD, algebraic circle then Gauss-Newton on the geometric distance)."""
    mean = points.mean(axis=0)
    _, _, vt = np.linalg.svd(points - mean, full_matrices=False)
    e1, e2, normal = vt[0], vt[1], vt[2]
    uv = np.stack([(points - mean) @ e1, (points - mean) @ e2], axis=1)
    a = np.column_stack([2 * uv, np.ones(len(uv))])
    sol, *_ = np.linalg.lstsq(a, (uv**2).sum(axis=1), rcond=None)
    centre = sol[:2]
    radius = float(np.sqrt(sol[2] + centre @ centre))
    for _ in range(20):
        d = uv - centre
        dist = np.linalg.norm(d, axis=1)
        jac = np.column_stack([-d / dist[:, None], -np.ones(len(uv))])
        step, *_ = np.linalg.lstsq(jac, -(dist - radius), rcond=None)
        centre, radius = centre + step[:2], radius + float(step[2])
    resid = np.hypot(np.linalg.norm(uv - centre, axis=1) - radius, (points - mean) @ normal)
    return mean + centre[0] * e1 + centre[1] * e2, normal, abs(radius), float(np.sqrt(np.mean(resid**2)))


def _motion_span(points: Array, t: Array, frac: float = 0.02) -> tuple[float, float]:
    """First time the track leaves, and first time it reaches, ``frac`` of its start-to-end distance (s)."""
    total = float(np.linalg.norm(points[-1] - points[0]))
    away = np.linalg.norm(points - points[0], axis=1) > frac * total
    near_end = np.linalg.norm(points - points[-1], axis=1) < frac * total
    i0 = int(np.argmax(away)) - 1
    i1 = int(np.argmax(near_end & (np.arange(len(t)) > i0)))
    return float(t[max(i0, 0)]), float(t[i1])


def single_primitive(points: Array, t: Array, kind: str, marker: str) -> TruthPrimitive:
    """The one primitive of a track that opens once: a circle fit (rotation) or the principal line (translation)."""
    ends = (np.median(points[:5], axis=0), np.median(points[-5:], axis=0))
    t0, t1 = _motion_span(points, t)
    mid = points[np.argmin(np.abs(t - 0.5 * (t0 + t1)))]
    if kind == "translation":
        direction = unit(ends[1] - ends[0])
        return TruthPrimitive("translation", None, direction, float(np.linalg.norm(ends[1] - ends[0])), t0, t1)
    centre, normal, fitted, _ = fit_circle_3d(points)
    if np.dot(np.cross(ends[0] - centre, ends[1] - centre), normal) < 0:
        normal = -normal
    r0, r1 = unit(ends[0] - centre), unit(ends[1] - centre)
    extent = float(np.arctan2(np.dot(np.cross(r0, r1), normal), np.dot(r0, r1)))
    if extent < 0:
        extent += 2 * np.pi
    foot = centre + np.dot(mid - centre, normal) * normal
    return TruthPrimitive("rotation", foot, normal, extent, t0, t1, fitted, marker)


# -- orientation tracks -------------------------------------------------------------------------------------------
def turn_angle(quat_xyzw: Array) -> tuple[Array, Array]:
    """Hinge axis (unit, the median axis of the turns over 20 degrees from the first pose) and the signed turn
    angle (n,) rad about it of each pose relative to the first (world-frame relative rotation ``R_k R_0^T``)."""
    rot = matrix_from_quat(quat_xyzw)
    rel = rot @ rot[0].T
    axes, angles = axis_angle_from_matrix(rel)
    big = angles > np.radians(20.0)
    ref = axes[big][0]
    aligned = np.where((axes[big] @ ref)[:, None] < 0, -axes[big], axes[big])
    hinge = unit(np.median(aligned, axis=0))
    q_rel = np.concatenate([axes * np.sin(angles / 2)[:, None], np.cos(angles / 2)[:, None]], axis=1)
    twist = 2.0 * np.arctan2(q_rel[:, :3] @ hinge, q_rel[:, 3])
    return hinge, twist


def running_median(x: Array, width: int) -> Array:
    """Running median of odd ``width`` with the ends padded by their edge values."""
    half = width // 2
    padded = np.concatenate([np.full(half, x[0]), x, np.full(half, x[-1])])
    windows = np.lib.stride_tricks.sliding_window_view(padded, width)
    out: Array = np.median(windows, axis=1)
    return out


def turning_points(angle: Array, hysteresis: float) -> list[int]:
    """Indices of the start, of every reversal (the extreme before the angle came back by ``hysteresis``) and of
    the end (a zigzag filter)."""
    points = [0]
    direction = 0
    ext = 0
    for k in range(1, len(angle)):
        if direction == 0:
            if abs(angle[k] - angle[0]) > hysteresis:
                direction, ext = (1 if angle[k] > angle[0] else -1), k
        elif direction * (angle[k] - angle[ext]) > 0:
            ext = k
        elif direction * (angle[ext] - angle[k]) > hysteresis:
            points.append(ext)
            direction, ext = -direction, k
    points.append(len(angle) - 1)
    return points


def pivot_fit(positions: Array, rot_rel: Array, hinge: Array) -> tuple[Array, Array, float]:
    """A point on the hinge and the tracked point (at the first pose) from ``p_k = R_k p_0 + (I - R_k) c``
    (least squares over all poses); returns ``c`` (the foot of ``p_0``), ``p_0`` and its radius (m)."""
    n = len(positions)
    a = np.concatenate([rot_rel, np.eye(3) - rot_rel], axis=2).reshape(3 * n, 6)
    sol, *_ = np.linalg.lstsq(a, positions.reshape(-1), rcond=None)
    p0, c = sol[:3], sol[3:]
    foot = c + np.dot(p0 - c, hinge) * hinge
    return foot, p0, float(np.linalg.norm(p0 - foot))


def turns(
    t: Array, angle: Array, hinge: Array, *, foot: Array, radius: float, marker: str
) -> tuple[TruthPrimitive, ...]:
    """One rotation per monotone run of the smoothed ``angle`` between turning points, each with the angle
    travelled between its extremes and the times it leaves/reaches ``SETTLE_RAD`` of them."""
    smooth = running_median(angle, SMOOTH_SAMPLES)
    idx = turning_points(smooth, REVERSAL_HYSTERESIS_RAD)
    out = []
    for a, b in itertools.pairwise(idx):
        seg = smooth[a : b + 1]
        delta = seg[-1] - seg[0]
        if abs(delta) < REVERSAL_HYSTERESIS_RAD:
            continue
        left = np.abs(seg - seg[0]) > SETTLE_RAD
        arrived = np.abs(seg - seg[-1]) < SETTLE_RAD
        i0 = a + max(int(np.argmax(left)) - 1, 0)
        i1 = a + int(np.argmax(arrived))
        sign = 1.0 if delta > 0 else -1.0
        out.append(
            TruthPrimitive(
                "rotation", foot, hinge * sign, float(abs(delta)), float(t[i0]), float(t[i1]), radius, marker
            )
        )
    return tuple(out)


def _noise_from_residual(resid: Array) -> float:
    """Largest per-axis sigma (m) of residuals (n, 3): the square root of the top covariance eigenvalue."""
    return float(np.sqrt(np.linalg.eigvalsh(np.cov(resid.T))[-1]))


# -- cases --------------------------------------------------------------------------------------------------------
def _times(n: int, hz: float) -> Array:
    return np.arange(n) / hz


def _sturm_case(path: Path, mechanism: str, tags: tuple[str, ...]) -> Case:
    """A Sturm robot track; a rotation's radius is this trial's circle fit (``STURM_RADIUS_M`` are the means)."""
    points = np.loadtxt(path, dtype=np.float64, ndmin=2)[:, :3]
    t = _times(len(points), STURM_HZ)
    kind = STURM_KIND[mechanism]
    prim = single_primitive(points, t, kind, "/marker")
    if kind == "rotation":
        _, _, _, rms = fit_circle_3d(points)
    else:
        centred = points - points.mean(axis=0)
        _, _, vt = np.linalg.svd(centred, full_matrices=False)
        rms = float(np.sqrt(np.mean(np.sum((centred - np.outer(centred @ vt[0], vt[0])) ** 2, axis=1))))
    return Case(
        name=f"{path.parent.parent.name}/{path.parent.name}/{path.stem}"
        if "mechanisms" in str(path)
        else f"{path.parent.name}/{path.stem}",
        markers={"/marker": (t, points)},
        poses={},
        wrist=None,
        truth=(prim,),
        noise_m=rms,
        hz=STURM_HZ,
        tags=("real", "sturm", mechanism, *tags),
        check_axis=False,
        radius_tol_m=RADIUS_TOL_M if kind == "rotation" else None,
        roles={"/marker": "object"},
    )


def _pose_turn_case(name: str, positions: Array, quats: Array, hz: float, tags: tuple[str, ...]) -> Case:
    """A rigid body turning about one hinge, possibly back and forth: truth from its orientations."""
    t = _times(len(positions), hz)
    hinge, angle = turn_angle(quats)
    rot = matrix_from_quat(quats)
    rel = rot @ rot[0].T
    foot, p0, radius = pivot_fit(positions, rel, hinge)
    predicted = np.einsum("nij,j->ni", rel, p0) + np.einsum("nij,j->ni", np.eye(3) - rel, foot)
    truth = turns(t, angle, hinge, foot=foot, radius=radius, marker="/tag")
    return Case(
        name=name,
        markers={},
        poses={"/tag": (t, positions, quats)},
        wrist=None,
        truth=truth,
        noise_m=_noise_from_residual(positions - predicted),
        hz=hz,
        tags=("real", "pose", *tags, *(("open-close",) if len(truth) > 1 else ())),
        check_axis=False,
        radius_tol_m=RADIUS_TOL_M,
        roles={"/tag": "body"},
    )


def _drawer_txt_case(path: Path) -> Case:
    """``drawer.txt``: opened then closed along the principal direction of its positions."""
    rows = np.loadtxt(path, dtype=np.float64, ndmin=2)
    positions, quats = rows[:, :3], rows[:, 3:7]
    t = _times(len(rows), DRAWER_TXT_HZ)
    centred = positions - positions.mean(axis=0)
    _, _, vt = np.linalg.svd(centred, full_matrices=False)
    axis = vt[0]
    s = (positions - positions[0]) @ axis
    if s[np.argmax(np.abs(s))] < 0:
        axis, s = -axis, -s
    peak = float(s.max())
    out_rows = np.flatnonzero(s > 0.8 * peak)
    start, top, end = float(np.median(s[:2])), float(np.median(s[out_rows])), float(np.median(s[-3:]))
    moving_out = np.flatnonzero(s - start > 0.1 * (top - start))
    moving_in = np.flatnonzero((top - s > 0.1 * (top - end)) & (np.arange(len(s)) > out_rows[0]))
    truth = (
        TruthPrimitive("translation", None, axis, top - start, float(t[moving_out[0] - 1]), float(t[out_rows[0]])),
        TruthPrimitive("translation", None, -axis, top - end, float(t[moving_in[0] - 1]), float(t[-1])),
    )
    resid = centred - np.outer(centred @ axis, axis)
    return Case(
        name="articulation_models/drawer",
        markers={},
        poses={"/tag": (t, positions, quats)},
        wrist=None,
        truth=truth,
        noise_m=_noise_from_residual(resid),
        hz=DRAWER_TXT_HZ,
        tags=("real", "pose", "camera", "open-close", "sparse"),
        check_axis=False,
        radius_tol_m=None,
        roles={"/tag": "body"},
    )


def _csv_pose(path: Path) -> tuple[Array, Array]:
    rows = np.loadtxt(path, dtype=np.float64, delimiter=",", skiprows=1, ndmin=2)
    return rows[:, :3], rows[:, 3:7]


def real_cases() -> list[Case]:
    """Every labelled track in ``../shared/real``, at its assumed rate (module docstring)."""
    root = real_root()
    cases = []
    for mechanism in ("left_door", "right_door", "dishwasher", "drawer"):
        for path in sorted((root / "sturm" / "mechanisms_iros_2010" / mechanism).glob("*.log")):
            cases.append(_sturm_case(path, mechanism, ("robot",)))
    for path in sorted((root / "sturm" / "second_set_dishwasher").glob("*.log")):
        cases.append(_sturm_case(path, "dishwasher", ("robot", "uneven", "repeats")))
    door = np.loadtxt(root / "sturm" / "articulation_models" / "door.txt", dtype=np.float64, ndmin=2)
    cases.append(
        _pose_turn_case("articulation_models/door", door[:, :3], door[:, 3:7], CAMERA_HZ, ("camera", "repeats"))
    )
    cases.append(_drawer_txt_case(root / "sturm" / "articulation_models" / "drawer.txt"))
    for stem in ("traj2_obj2_rel_obj1", "traj1_obj1_rel_obj2"):
        positions, quats = _csv_pose(root / "champ" / f"{stem}.csv")
        cases.append(_pose_turn_case(f"champ/{stem}", positions, quats, CAMERA_HZ, ("camera",)))
    return cases


def real_cases_at(rates: tuple[float, ...] = (10.0, 30.0, 100.0)) -> list[Case]:
    """Every case of ``real_cases`` resampled to each of ``rates`` (Hz)."""
    return [resample(case, hz) for case in real_cases() for hz in rates]


def unlabelled_cases() -> list[Case]:
    """Tracks without labels (empty truth): Verduyn's pouring and translation motions (their own stamps, the
    doubled rows dropped) and CHAMP's two raw AR-tag poses."""
    root = real_root()
    cases = []
    data = root / "verduyn" / "Data"
    for path in sorted(data.glob("*/*.csv")):
        rows = np.loadtxt(path, dtype=np.float64, delimiter=",", ndmin=2)
        keep = np.concatenate([[True], np.any(np.diff(rows[:, 1:], axis=0) != 0, axis=1)])
        rows = rows[keep]
        t = rows[:, 0] - rows[0, 0]
        span = float(t[-1]) if len(t) > 1 else 0.0
        cases.append(
            Case(
                name=f"verduyn/{path.parent.name}/{path.stem}",
                markers={},
                poses={"/body": (t, rows[:, 1:4], rows[:, 4:8])},
                wrist=None,
                truth=(),
                noise_m=0.0,
                hz=(len(t) - 1) / span if span > 0 else 0.0,
                tags=("real", "pose", "unlabelled"),
                check_axis=False,
            )
        )
    for stem in ("m1_obj1_pose", "m2_obj2_pose"):
        positions, quats = _csv_pose(root / "champ" / f"{stem}.csv")
        cases.append(
            Case(
                name=f"champ/{stem}",
                markers={},
                poses={"/tag": (_times(len(positions), CAMERA_HZ), positions, quats)},
                wrist=None,
                truth=(),
                noise_m=0.0,
                hz=CAMERA_HZ,
                tags=("real", "pose", "unlabelled"),
                check_axis=False,
            )
        )
    return cases
