"""Report figures (matplotlib, Agg): pure functions from arrays and descriptors to ``Figure`` objects.

Nothing here writes files; ``tasks.report.build`` saves the figures. Coordinates are metres in the world
frame of the recording; times are seconds since the recording's ``start_ns``.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import dataclass

import matplotlib as mpl

mpl.use("Agg")
import matplotlib.pyplot as plt
import numpy as np
from matplotlib.figure import Figure

from schemas.descriptor import Descriptor, Grasp, Primitive
from tasks.arrays import FloatArray, Points, StampsNs

AXIS_HALF_LENGTH_M = 0.15
"""Half length of a drawn rotation axis, metres (about the size of a door or lid in the sample scenes)."""

MAX_CLOUD_POINTS = 1500
"""Object model points drawn at most (a regular subsample), to keep the PNGs small."""

GRASP_VIEW_RADIUS_M = 0.2
"""Object points within this distance of the hand are drawn in the grasp view, metres (the hand spans ~0.25 m)."""

KIND_COLOURS = {"rotation": "tab:red", "translation": "tab:blue"}


@dataclass(frozen=True)
class Track:
    """One marker trajectory for plotting: stamps (n,) int64 ns, points (n, 3) metres, world frame."""

    name: str
    stamps_ns: StampsNs
    points: Points


@dataclass(frozen=True)
class JointTrace:
    """Simulated motion of one joint: times (n,) s, achieved values (n,) rad or m, demonstrated target."""

    name: str
    times_s: FloatArray
    values: FloatArray
    target: float
    unit: str


def segment_colours(count: int) -> list[tuple[float, float, float, float]]:
    """``count`` distinct RGBA colours (tab10, cycled) for the chain's segments in time order."""
    cmap = plt.get_cmap("tab10")
    return [cmap(i % 10) for i in range(count)]


def _segment_of(times_s: FloatArray, chain: Sequence[Primitive]) -> np.ndarray:
    """Index of the chain element whose [t_start, t_end] holds each time, -1 outside every segment."""
    out = np.full(times_s.shape, -1, dtype=np.int64)
    for i, prim in enumerate(chain):
        if prim.t_start is None or prim.t_end is None:
            continue
        out[(times_s >= prim.t_start) & (times_s <= prim.t_end)] = i
    return out


def _set_equal_3d(ax: object, points: Points) -> None:
    """Equal scale on the three axes of a 3-D plot around ``points`` (n, 3)."""
    finite = points[np.all(np.isfinite(points), axis=1)]
    if len(finite) == 0:
        return
    centre = (finite.max(axis=0) + finite.min(axis=0)) / 2
    half = max(float((finite.max(axis=0) - finite.min(axis=0)).max()) / 2, 0.05)
    ax.set_xlim(centre[0] - half, centre[0] + half)  # type: ignore[attr-defined]
    ax.set_ylim(centre[1] - half, centre[1] + half)  # type: ignore[attr-defined]
    ax.set_zlim(centre[2] - half, centre[2] + half)  # type: ignore[attr-defined]


def trajectories_figure(tracks: Sequence[Track], start_ns: int, desc: Descriptor) -> Figure:
    """3-D marker trajectories coloured by segment, with each primitive's fitted axis drawn in.

    Samples outside every segment (reaching, holding still) are grey. A rotation axis is a line through
    ``pos`` along ``dir``; a translation is an arrow of length ``extent`` along ``dir`` from the segment start.
    """
    fig = plt.figure(figsize=(7.0, 6.0))
    ax = fig.add_subplot(projection="3d")
    colours = segment_colours(len(desc.chain))
    every: list[Points] = []
    seg_start: dict[int, Points] = {}
    for track in tracks:
        times_s = (track.stamps_ns - start_ns) / 1e9
        seg = _segment_of(times_s, desc.chain)
        pts = track.points
        every.append(pts)
        ax.plot(pts[:, 0], pts[:, 1], pts[:, 2], color="0.8", lw=0.6)
        for i in range(len(desc.chain)):
            sel = seg == i
            if sel.any():
                ax.scatter(pts[sel, 0], pts[sel, 1], pts[sel, 2], s=2, color=colours[i])
                if (desc.chain[i].markers and track.name in desc.chain[i].markers) or i not in seg_start:
                    seg_start[i] = pts[sel][:1]
    for i, prim in enumerate(desc.chain):
        d = np.asarray(prim.dir)
        if prim.kind == "rotation" and prim.pos is not None:
            p = np.asarray(prim.pos)
            line = np.stack([p - AXIS_HALF_LENGTH_M * d, p + AXIS_HALF_LENGTH_M * d])
            ax.plot(line[:, 0], line[:, 1], line[:, 2], color=colours[i], lw=3, label=f"{i}: rotation axis")
            every.append(line)
        else:
            start = seg_start.get(i)
            p = start[0] if start is not None and len(start) else np.zeros(3)
            q = p + d * max(prim.extent, 0.05)
            ax.quiver(*p, *(q - p), color=colours[i], lw=2.5, arrow_length_ratio=0.15, label=f"{i}: {prim.kind}")
            every.append(np.stack([p, q]))
    if every:
        _set_equal_3d(ax, np.concatenate(every))
    ax.set_xlabel("x (m)")
    ax.set_ylabel("y (m)")
    ax.set_zlabel("z (m)")
    ax.set_title(f"{desc.name}: marker trajectories by segment, fitted axes")
    if desc.chain:
        ax.legend(loc="upper left", fontsize=8)
    fig.tight_layout()
    return fig


def timeline_figure(desc: Descriptor, duration_s: float) -> Figure:
    """The segment timeline: one bar per chain primitive over [t_start, t_end], gaps are undefined segments."""
    fig, ax = plt.subplots(figsize=(8.0, 1.8))
    colours = segment_colours(len(desc.chain))
    ax.broken_barh([(0.0, max(duration_s, 1e-3))], (0.0, 1.0), facecolors="0.9")
    for i, prim in enumerate(desc.chain):
        if prim.t_start is None or prim.t_end is None:
            continue
        ax.broken_barh([(prim.t_start, prim.t_end - prim.t_start)], (0.0, 1.0), facecolors=colours[i])
        unit = "rad" if prim.kind == "rotation" else "m"
        ax.text((prim.t_start + prim.t_end) / 2, 0.5, f"{i}: {prim.kind}\n{prim.extent:.3f} {unit}", ha="center",
                va="center", fontsize=8)  # fmt: skip
    ax.set_xlim(0.0, max(duration_s, 1e-3))
    ax.set_yticks([])
    ax.set_xlabel("time since recording start (s)")
    ax.set_title("segments (grey: reaching / holding, dropped from the chain)")
    fig.tight_layout()
    return fig


def model_selection_figure(desc: Descriptor) -> Figure:
    """Model selection per segment: each candidate model's cost (the fit's ``scores``, BIC in nats) above the
    chosen one (0 = chosen), or the chosen model's RMS residual when the fit records no scores."""
    fig, ax = plt.subplots(figsize=(7.0, 3.0))
    colours = segment_colours(len(desc.chain))
    scores: list[Mapping[str, float]] = []
    for prim in desc.chain:
        raw = prim.fit.get("bic") or prim.fit.get("scores") or {}
        scores.append({str(k): float(v) for k, v in raw.items()} if isinstance(raw, Mapping) else {})
    models = sorted({m for s in scores for m in s})
    if models:
        width = 0.8 / len(models)
        for j, model in enumerate(models):
            xs = [i + j * width - 0.4 + width / 2 for i, s in enumerate(scores) if model in s]
            ys = [s[model] - min(s.values()) for s in scores if model in s]
            ax.bar(xs, ys, width=width, label=model)
        ax.set_ylabel("cost above the chosen model (BIC, nats)")
        ax.set_yscale("symlog", linthresh=10.0)
        ax.legend(fontsize=8)
    else:
        rms_mm = [1000 * float(p.fit.get("rms_m", 0.0)) for p in desc.chain]
        ax.bar(range(len(desc.chain)), rms_mm, color=colours)
        ax.set_ylabel("fit RMS (mm)")
    ax.set_xticks(range(len(desc.chain)), [f"{i}: {p.kind}" for i, p in enumerate(desc.chain)])
    ax.set_title("model selection per segment")
    fig.tight_layout()
    return fig


def quat_to_matrix(quat_xyzw: Sequence[float]) -> FloatArray:
    """3x3 rotation matrix of a unit quaternion [x, y, z, w]."""
    x, y, z, w = (float(v) for v in quat_xyzw)
    n = np.sqrt(x * x + y * y + z * z + w * w) or 1.0
    x, y, z, w = x / n, y / n, z / n, w / n
    return np.array(
        [
            [1 - 2 * (y * y + z * z), 2 * (x * y - z * w), 2 * (x * z + y * w)],
            [2 * (x * y + z * w), 1 - 2 * (x * x + z * z), 2 * (y * z - x * w)],
            [2 * (x * z - y * w), 2 * (y * z + x * w), 1 - 2 * (x * x + y * y)],
        ]
    )


def grasp_figure(
    grasp: Grasp,
    object_points: Points | None,
    finger_dofs_rad: Sequence[float] | None = None,
    hand_lines: Sequence[Points] | None = None,
) -> Figure:
    """The planned grasp: object model points, the hand base frame (x red, y green, z blue = approach), the
    hand's fingers as polylines (world, metres) when given, and the eigengrasps, qualities and dofs as text."""
    fig = plt.figure(figsize=(6.0, 5.5))
    ax = fig.add_subplot(projection="3d")
    pos = np.asarray(grasp.wrist_position)
    every = [pos[None, :]]
    if object_points is not None and len(object_points):
        near = object_points[np.linalg.norm(object_points - pos, axis=1) < GRASP_VIEW_RADIUS_M]
        step = max(1, len(near) // MAX_CLOUD_POINTS)
        pts = near[::step]
        ax.scatter(pts[:, 0], pts[:, 1], pts[:, 2], s=1, color="0.55")
    rot = quat_to_matrix(grasp.wrist_orientation)
    size = 0.08
    for k, colour in enumerate(("red", "green", "blue")):
        axis = rot[:, k] * size
        ax.quiver(*pos, *axis, color=colour, lw=2.5, arrow_length_ratio=0.2)
        every.append((pos + axis)[None, :])
    for line in hand_lines or ():
        ax.plot(line[:, 0], line[:, 1], line[:, 2], color="black", lw=2.5, marker="o", ms=2)
        every.append(line)
    _set_equal_3d(ax, np.concatenate(every))
    a1, a2 = grasp.eigengrasps
    lines = [f"hand {grasp.hand}", f"eigengrasps a1={a1:.3f} a2={a2:.3f}"]
    lines += [f"{k} {float(v):.4g}" for k, v in sorted(grasp.quality.items()) if isinstance(v, int | float)]
    if finger_dofs_rad is not None:
        lines.append("dofs [spread f1 f2 f3] rad: " + " ".join(f"{v:.2f}" for v in finger_dofs_rad))
    ax.text2D(0.02, 0.98, "\n".join(lines), transform=ax.transAxes, va="top", fontsize=8, family="monospace")
    ax.set_xlabel("x (m)")
    ax.set_ylabel("y (m)")
    ax.set_zlabel("z (m)")
    ax.set_title("planned grasp (hand base frame; blue = approach)")
    fig.tight_layout()
    return fig


def joint_motion_figure(traces: Sequence[JointTrace], title: str) -> Figure:
    """Simulated joint motion against the demonstrated target: one line per joint, target dashed."""
    fig, ax = plt.subplots(figsize=(7.0, 3.2))
    colours = segment_colours(len(traces))
    for i, tr in enumerate(traces):
        ax.plot(tr.times_s, tr.values, color=colours[i], label=f"{tr.name} achieved ({tr.unit})")
        ax.axhline(tr.target, color=colours[i], ls="--", lw=1, label=f"{tr.name} target {tr.target:.3f}")
    ax.set_xlabel("simulated time (s)")
    ax.set_ylabel("joint value (rad or m)")
    ax.set_title(title)
    if traces:
        ax.legend(fontsize=7)
    fig.tight_layout()
    return fig


def diff_figure(changes: Sequence[tuple[str, float, float]]) -> Figure:
    """The diff against the previous version: per primitive, axis angle change (deg) and offset (mm)."""
    fig, ax = plt.subplots(figsize=(7.0, 2.8))
    labels = [c[0] for c in changes]
    xs = np.arange(len(changes))
    ax.bar(xs - 0.2, [c[1] for c in changes], width=0.4, label="axis angle change (deg)")
    ax.bar(xs + 0.2, [c[2] for c in changes], width=0.4, label="axis offset (mm)")
    ax.set_xticks(xs, labels)
    ax.set_title("change against the previous version")
    ax.legend(fontsize=8)
    fig.tight_layout()
    return fig


def simulation_extent_figure(joints: Sequence[str], achieved: Sequence[float], target: Sequence[float]) -> Figure:
    """Simulated joint motion against the demonstrated target, one pair of bars per executed primitive."""
    fig, ax = plt.subplots(figsize=(7.0, 2.8))
    xs = np.arange(len(target))
    ax.bar(xs - 0.2, target, width=0.4, color="0.7", label="demonstrated extent (target)")
    ax.bar(xs + 0.2, achieved, width=0.4, color="tab:green", label="achieved in simulation")
    labels = [f"{i}: {joints[i]}" if i < len(joints) else str(i) for i in range(len(target))]
    ax.set_xticks(xs, labels)
    ax.set_ylabel("joint motion (rad or m)")
    ax.set_title("simulated joint motion vs target")
    ax.legend(fontsize=8)
    fig.tight_layout()
    return fig
