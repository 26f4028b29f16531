"""Synthetic object models for tests and the transfer benchmark: surface samples of simple shapes.

Every shape is built in its own object frame (metres, z up, base on z = 0) and comes with one functional
axis (a point and a unit direction) such as a bottle cap's axis or a lid's hinge, which the benchmark
transfers and checks. Samplers are area-weighted and driven by the ``rng`` passed in.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass

import numpy as np

from tasks.arrays import FloatArray, Points, Vector3

Sampler = Callable[[int, np.random.Generator], tuple[Points, Points]]
"""n, rng -> (points (n, 3), outward normals (n, 3))."""


@dataclass(frozen=True)
class Part:
    """One surface patch with its area (m^2) and its sampler."""

    area: float
    sample: Sampler


@dataclass(frozen=True)
class ShapeModel:
    """A sampled object model with its functional axis (object frame, metres)."""

    name: str
    points: Points
    normals: Points
    axis_pos: Vector3
    axis_dir: Vector3
    kind: str
    """``rotation`` or ``translation`` (the primitive the axis stands for)."""
    focus: Points
    """(k, 3) points of the functional part (axis point, grasp point)."""


def cylinder_side(radius: float, z0: float, z1: float, radius1: float | None = None) -> Part:
    """Side of a cylinder (or of a frustum when ``radius1`` differs) about z from ``z0`` to ``z1``."""
    r1 = radius if radius1 is None else radius1
    slant = float(np.hypot(z1 - z0, r1 - radius))
    area = float(np.pi * (radius + r1) * slant)

    def sample(n: int, rng: np.random.Generator) -> tuple[Points, Points]:
        # area-uniform along the slant: radius grows linearly, so sample u with density ~ r(u)
        u = rng.random(n)
        if abs(r1 - radius) > 1e-12:
            u = (np.sqrt(radius**2 + u * (r1**2 - radius**2)) - radius) / (r1 - radius)
        r = radius + u * (r1 - radius)
        phi = rng.random(n) * 2.0 * np.pi
        pts = np.column_stack([r * np.cos(phi), r * np.sin(phi), z0 + u * (z1 - z0)])
        nz = (radius - r1) / slant
        nr = (z1 - z0) / slant
        normals = np.column_stack([nr * np.cos(phi), nr * np.sin(phi), np.full(n, nz)])
        return pts, normals

    return Part(area, sample)


def disk(radius: float, z: float, up: bool, inner: float = 0.0) -> Part:
    """An annulus (disk when ``inner`` is 0) at height ``z`` facing +z (``up``) or -z."""
    area = float(np.pi * (radius**2 - inner**2))

    def sample(n: int, rng: np.random.Generator) -> tuple[Points, Points]:
        r = np.sqrt(inner**2 + rng.random(n) * (radius**2 - inner**2))
        phi = rng.random(n) * 2.0 * np.pi
        pts = np.column_stack([r * np.cos(phi), r * np.sin(phi), np.full(n, z)])
        normals = np.tile([0.0, 0.0, 1.0 if up else -1.0], (n, 1))
        return pts, normals

    return Part(area, sample)


def box(size: FloatArray, centre: FloatArray) -> list[Part]:
    """The six faces of an axis-aligned box of ``size`` (3,) about ``centre`` (3,)."""
    parts: list[Part] = []
    half = np.asarray(size, dtype=np.float64) / 2.0
    c = np.asarray(centre, dtype=np.float64)
    for axis in range(3):
        others = [a for a in range(3) if a != axis]
        area = float(4.0 * half[others[0]] * half[others[1]])
        for sign in (-1.0, 1.0):

            def sample(
                n: int, rng: np.random.Generator, axis: int = axis, others: list[int] = others, sign: float = sign
            ) -> tuple[Points, Points]:
                pts = np.empty((n, 3))
                pts[:, axis] = c[axis] + sign * half[axis]
                for o in others:
                    pts[:, o] = c[o] + (rng.random(n) * 2.0 - 1.0) * half[o]
                normals = np.zeros((n, 3))
                normals[:, axis] = sign
                return pts, normals

            parts.append(Part(area, sample))
    return parts


def torus_arc(major: float, minor: float, centre: FloatArray, phi0: float, phi1: float) -> Part:
    """A torus arc in the x-z plane about ``centre`` (a mug handle), angles ``phi0..phi1`` rad about +y."""
    c = np.asarray(centre, dtype=np.float64)
    area = float((phi1 - phi0) * major * 2.0 * np.pi * minor)

    def sample(n: int, rng: np.random.Generator) -> tuple[Points, Points]:
        # rejection-free approximation: area element ~ (major + minor cos theta); accept by weight
        out_p: list[Points] = []
        out_n: list[Points] = []
        have = 0
        while have < n:
            m = 2 * (n - have) + 8
            phi = phi0 + rng.random(m) * (phi1 - phi0)
            theta = rng.random(m) * 2.0 * np.pi
            keep = rng.random(m) * (major + minor) <= major + minor * np.cos(theta)
            phi, theta = phi[keep], theta[keep]
            radial = np.column_stack([np.cos(phi), np.zeros_like(phi), np.sin(phi)])
            normal = radial * np.cos(theta)[:, None] + np.array([0.0, 1.0, 0.0]) * np.sin(theta)[:, None]
            out_p.append(c + radial * major + normal * minor)
            out_n.append(normal)
            have += len(phi)
        return np.vstack(out_p)[:n], np.vstack(out_n)[:n]

    return Part(area, sample)


def sample_parts(parts: list[Part], n: int, rng: np.random.Generator) -> tuple[Points, Points]:
    """Area-weighted samples of ``n`` points (and normals) over ``parts``."""
    areas = np.array([p.area for p in parts])
    counts = rng.multinomial(n, areas / areas.sum())
    pts, nrm = zip(*(p.sample(int(k), rng) for p, k in zip(parts, counts, strict=True) if k > 0), strict=True)
    return np.vstack(pts), np.vstack(nrm)


def bottle(
    rng: np.random.Generator,
    *,
    n: int = 6000,
    radius: float = 0.035,
    height: float = 0.16,
    shoulder: float = 0.04,
    neck_radius: float = 0.013,
    neck: float = 0.02,
    cap_radius: float = 0.016,
    cap: float = 0.02,
) -> ShapeModel:
    """A bottle with a cap; the axis is the cap's (z through the cap's top centre), a rotation (twist)."""
    z_sh, z_neck = height, height + shoulder
    z_cap0 = z_neck + neck * 0.5
    z_top = z_cap0 + cap
    parts = [
        disk(radius, 0.0, False),
        cylinder_side(radius, 0.0, z_sh),
        cylinder_side(radius, z_sh, z_neck, neck_radius),
        cylinder_side(neck_radius, z_neck, z_cap0),
        disk(cap_radius, z_cap0, False, neck_radius),
        cylinder_side(cap_radius, z_cap0, z_top),
        disk(cap_radius, z_top, True),
    ]
    pts, nrm = sample_parts(parts, n, rng)
    pos = np.array([0.0, 0.0, z_top])
    focus = np.array([pos, [cap_radius, 0.0, z_cap0 + cap / 2.0]])
    return ShapeModel("bottle", pts, nrm, pos, np.array([0.0, 0.0, 1.0]), "rotation", focus)


def jar(rng: np.random.Generator, *, n: int = 5000, radius: float = 0.045, height: float = 0.1) -> ShapeModel:
    """A jar with a wider lid and a label band; rotation about the lid's axis."""
    lid_r, lid_h = radius * 1.08, 0.018
    parts = [
        disk(radius, 0.0, False),
        cylinder_side(radius, 0.0, height * 0.3),
        cylinder_side(radius, height * 0.3, height * 0.85, radius * 0.9),
        cylinder_side(radius * 0.9, height * 0.85, height),
        disk(lid_r, height, False, radius * 0.9),
        cylinder_side(lid_r, height, height + lid_h),
        disk(lid_r, height + lid_h, True),
    ]
    pts, nrm = sample_parts(parts, n, rng)
    pos = np.array([0.0, 0.0, height + lid_h])
    focus = np.array([pos, [lid_r, 0.0, height + lid_h / 2]])
    return ShapeModel("jar", pts, nrm, pos, np.array([0.0, 0.0, 1.0]), "rotation", focus)


def cabinet(
    rng: np.random.Generator, *, n: int = 6000, size: tuple[float, float, float] = (0.3, 0.25, 0.4)
) -> ShapeModel:
    """A box with a knob on its front (-y) face near one edge; rotation about the opposite vertical edge."""
    s = np.array(size)
    knob = np.array([s[0] * 0.38, -s[1] / 2 - 0.02, s[2] * 0.6])
    parts = [*box(s, np.array([0.0, 0.0, s[2] / 2])), *box(np.array([0.02, 0.04, 0.05]), knob)]
    pts, nrm = sample_parts(parts, n, rng)
    pos = np.array([-s[0] / 2, -s[1] / 2, s[2] / 2])
    focus = np.array([knob, pos])
    return ShapeModel("cabinet", pts, nrm, pos, np.array([0.0, 0.0, 1.0]), "rotation", focus)


def drawer(
    rng: np.random.Generator, *, n: int = 6000, size: tuple[float, float, float] = (0.4, 0.35, 0.2)
) -> ShapeModel:
    """A box with a bar handle off-centre on its front face; translation along -y (pull)."""
    s = np.array(size)
    handle = np.array([s[0] * 0.15, -s[1] / 2 - 0.0325, s[2] * 0.65])
    parts = [
        *box(s, np.array([0.0, 0.0, s[2] / 2])),
        *box(np.array([0.14, 0.025, 0.025]), handle),
        *box(np.array([0.02, 0.02, 0.02]), handle + np.array([0.05, 0.02, 0.0])),
        *box(np.array([0.02, 0.02, 0.02]), handle + np.array([-0.05, 0.02, 0.0])),
    ]
    pts, nrm = sample_parts(parts, n, rng)
    return ShapeModel("drawer", pts, nrm, handle, np.array([0.0, -1.0, 0.0]), "translation", handle[None, :])


def mug(rng: np.random.Generator, *, n: int = 6000, radius: float = 0.04, height: float = 0.1) -> ShapeModel:
    """A mug with a handle on +x; the axis is vertical through the handle (a lever-like turn)."""
    handle_c = np.array([radius, 0.0, height * 0.5])
    parts = [
        disk(radius, 0.0, False),
        cylinder_side(radius, 0.0, height),
        disk(radius, height, True, radius * 0.9),
        cylinder_side(radius * 0.9, height * 0.2, height),
        torus_arc(height * 0.3, 0.007, handle_c, -np.pi / 2, np.pi / 2),
    ]
    pts, nrm = sample_parts(parts, n, rng)
    pos = handle_c + np.array([height * 0.3, 0.0, 0.0])
    focus = np.array([pos, handle_c])
    return ShapeModel("mug", pts, nrm, pos, np.array([0.0, 0.0, 1.0]), "rotation", focus)


SHAPE_KINDS = ("bottle", "jar", "cabinet", "drawer", "mug")


def random_shape(rng: np.random.Generator, n: int = 6000, kind: str | None = None) -> ShapeModel:
    """One of the shapes above (``kind``, else a random one) with random proportions."""
    if kind is None:
        kind = SHAPE_KINDS[int(rng.integers(0, len(SHAPE_KINDS)))]

    def u(lo: float, hi: float) -> float:
        return float(rng.uniform(lo, hi))

    if kind == "bottle":
        return bottle(rng, n=n, radius=u(0.025, 0.045), height=u(0.1, 0.22), shoulder=u(0.02, 0.05))
    if kind == "jar":
        return jar(rng, n=n, radius=u(0.03, 0.06), height=u(0.06, 0.14))
    if kind == "cabinet":
        return cabinet(rng, n=n, size=(u(0.2, 0.45), u(0.2, 0.35), u(0.3, 0.6)))
    if kind == "drawer":
        return drawer(rng, n=n, size=(u(0.3, 0.5), u(0.25, 0.4), u(0.12, 0.25)))
    return mug(rng, n=n, radius=u(0.03, 0.05), height=u(0.08, 0.12))


def random_rotation(rng: np.random.Generator) -> FloatArray:
    """A uniformly random proper rotation matrix."""
    q = rng.normal(size=4)
    q /= np.linalg.norm(q)
    x, y, z, w = q
    out: FloatArray = np.array(
        [
            [1 - 2 * (y * y + z * z), 2 * (x * y - z * w), 2 * (x * z + y * w)],
            [2 * (x * y + z * w), 1 - 2 * (x * x + z * z), 2 * (y * z - x * w)],
            [2 * (x * z - y * w), 2 * (y * z + x * w), 1 - 2 * (x * x + y * y)],
        ]
    )
    return out


def partial_scan(
    points: Points, normals: Points, rng: np.random.Generator, keep: float, *, view: bool
) -> tuple[Points, Points]:
    """A partial scan: points facing a random view direction (``view``), or kept on one side of a random
    plane so that a fraction ``keep`` of the surface stays."""
    direction = rng.normal(size=3)
    direction /= np.linalg.norm(direction)
    if view:
        mask = normals @ direction > np.quantile(normals @ direction, 1.0 - keep)
    else:
        proj = points @ direction
        mask = proj >= np.quantile(proj, 1.0 - keep)
    return points[mask], normals[mask]
