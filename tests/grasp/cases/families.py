"""Object families the planner was not developed on (``bench/grasp.py``): bar pulls of round, square and D-shaped
profile on a plate, knobs, levers of other lengths, bottles with caps of other proportions, and boxes and
cylinders at the Barrett hand's size limits. Each object is built from boxes and cylinders (``WorldShape``), its
scan the points of the part's and the mount's surfaces that lie on the outside of the union, its hold-test model
the shapes themselves (``exact.exact_model``; a free box or cylinder ``PrimitiveShape``), and its demonstrated palm
a seed drawn as for the randomised objects (``grasp.palm_seed``)."""

from __future__ import annotations

import functools

import numpy as np
from scipy.spatial.transform import Rotation

from tasks.arrays import Points
from tasks.grasp.object_model import ObjectModel, build_object_model
from tasks.grasp.primitive_shape import PrimitiveShape
from tasks.scenes.surface import WorldShape, sample_shapes
from tests.grasp.cases.exact import exact_model
from tests.grasp.cases.grasp import Case, palm_seed

CENTRE = np.array([0.5, 0.0, 0.5])
"""Where every family object stands (world, m)."""
SCAN_POINTS = 8192
DETAIL_RADIUS_M = 0.15
"""A scan as ``pbd synth`` records one (``tasks.synth.scan``): 8192 points, half of them on the surfaces within
15 cm of the demonstrated palm, the rest even over the object."""
FAMILIES = ("round pull", "square pull", "D pull", "knob", "lever", "bottle cap", "small box", "large box",
            "thin cylinder", "wide cylinder")  # fmt: skip
"""The families, drawn in turn."""


def _v(x: float, y: float, z: float) -> np.ndarray:
    return np.array([x, y, z])


def _inside(shape: WorldShape, points: Points, margin_m: float = 3e-4) -> np.ndarray:
    """Whether each point lies inside ``shape`` deeper than ``margin_m``."""
    local = (points - shape.translation) @ shape.rotation
    if shape.kind == "box":
        half = np.asarray(shape.size) / 2.0 - margin_m
        return np.all(np.abs(local) < half, axis=1)
    radius, length = shape.size
    return (np.hypot(local[:, 0], local[:, 1]) < radius - margin_m) & (np.abs(local[:, 2]) < length / 2.0 - margin_m)


def _scan(shapes: list[WorldShape], palm: np.ndarray, rng: np.random.Generator) -> Points:
    """Surface points of the union of ``shapes`` (those inside another shape dropped), scanned as ``pbd synth``
    scans (``SCAN_POINTS``, ``DETAIL_RADIUS_M`` around the ``palm``)."""
    dense = sample_shapes(shapes, 16 * SCAN_POINTS, rng)
    hidden = np.zeros(len(dense), dtype=bool)
    for s in shapes:
        hidden |= _inside(s, dense)
    dense = dense[~hidden]
    near = np.flatnonzero(np.linalg.norm(dense - palm, axis=1) < DETAIL_RADIUS_M)
    detail = dense[rng.choice(near, size=min(SCAN_POINTS // 2, len(near)), replace=False)]
    even = dense[rng.choice(len(dense), size=SCAN_POINTS - len(detail), replace=False)]
    return np.concatenate([even, detail])


def _cylinder(name: str, radius: float, length: float, axis: str, at: np.ndarray) -> WorldShape:
    rot = {"z": np.eye(3), "x": Rotation.from_euler("y", 90, degrees=True).as_matrix(),
           "y": Rotation.from_euler("x", 90, degrees=True).as_matrix()}[axis]  # fmt: skip
    return WorldShape(name, "cylinder", (radius, length), rot, np.asarray(at, dtype=np.float64))


def _box(name: str, size: tuple[float, float, float], at: np.ndarray) -> WorldShape:
    return WorldShape(name, "box", size, np.eye(3), np.asarray(at, dtype=np.float64))


def _pull(profile: str, rng: np.random.Generator) -> tuple[str, list[WorldShape], list[WorldShape], float, str]:
    """A bar pull on two posts standing ``standoff`` in front (-y) of a plate: (name, part, mount, front depth of the
    bar from its axis (m), bar axis)."""
    width = float(rng.uniform(0.008, 0.015))  # half width of the profile
    length, standoff = float(rng.uniform(0.10, 0.20)), float(rng.uniform(0.025, 0.05))
    axis = "z" if rng.random() < 0.5 else "x"
    along = np.array([0.0, 0.0, 1.0]) if axis == "z" else np.array([1.0, 0.0, 0.0])
    size = (2 * width, 2 * width, length) if axis == "z" else (length, 2 * width, 2 * width)
    if profile == "round":
        bar = [_cylinder("bar", width, length, axis, CENTRE)]
    elif profile == "square":
        bar = [_box("bar", size, CENTRE)]  # type: ignore[arg-type]
    else:  # D: round towards the hand, flat towards the plate
        back = (size[0], width, size[2])
        bar = [_cylinder("bar", width, length, axis, CENTRE), _box("bar", back, CENTRE + _v(0.0, width / 2, 0.0))]
    posts = [
        _cylinder("post", 0.006, standoff, "y", CENTRE + s * (length / 2 - 0.012) * along + _v(0.0, standoff / 2, 0.0))
        for s in (-1.0, 1.0)
    ]
    plate = (0.06, 0.01, length + 0.06) if axis == "z" else (length + 0.06, 0.01, 0.06)
    mount = [_box("plate", plate, CENTRE + _v(0.0, standoff + 0.005, 0.0))]  # type: ignore[arg-type]
    name = f"{profile} pull w{2000 * width:.0f} l{1000 * length:.0f}mm {'vertical' if axis == 'z' else 'horizontal'}"
    return name, bar + posts, mount, width, axis


def family_case(family: str, rng: np.random.Generator) -> Case:
    """One object of ``family`` (``FAMILIES``) with its demonstrated palm seed."""
    down, towards_plate = np.array([0.0, 0.0, -1.0]), np.array([0.0, 1.0, 0.0])
    gap = float(rng.uniform(0.02, 0.06))
    if family.endswith("pull"):
        name, part, mount, depth, axis = _pull(family.split(maxsplit=1)[0], rng)
        along = np.array([0.0, 0.0, 1.0]) if axis == "z" else np.array([1.0, 0.0, 0.0])
        pos, quat = palm_seed(CENTRE - _v(0.0, depth, 0.0), towards_plate, gap, rng, along)
    elif family == "knob":
        radius, height = float(rng.uniform(0.015, 0.03)), float(rng.uniform(0.015, 0.03))
        stem = float(rng.uniform(0.015, 0.03))
        part = [_cylinder("knob", radius, height, "y", CENTRE),
                _cylinder("stem", 0.006, stem, "y", CENTRE + _v(0.0, (height + stem) / 2, 0.0))]  # fmt: skip
        mount = [_box("plate", (0.12, 0.01, 0.12), CENTRE + _v(0.0, height / 2 + stem + 0.005, 0.0))]
        name = f"knob r{1000 * radius:.0f} h{1000 * height:.0f}mm"
        pos, quat = palm_seed(CENTRE - _v(0.0, height / 2, 0.0), towards_plate, gap, rng)
    elif family == "lever":
        length, radius = float(rng.uniform(0.07, 0.16)), float(rng.uniform(0.007, 0.011))
        standoff = float(rng.uniform(0.04, 0.06))
        rose = CENTRE + _v(-length / 2 + 0.01, 0.0, 0.0)
        part = [_cylinder("lever", radius, length, "x", CENTRE),
                _cylinder("rose", 0.01, standoff, "y", rose + _v(0.0, standoff / 2, 0.0))]  # fmt: skip
        mount = [_box("leaf", (length + 0.15, 0.01, 0.2), rose + _v(0.05, standoff + 0.005, 0.0))]
        name = f"lever r{1000 * radius:.0f} l{1000 * length:.0f}mm"
        grip_at = CENTRE + _v(length / 4, -radius, 0.0)
        pos, quat = palm_seed(grip_at, towards_plate, gap, rng, np.array([1.0, 0.0, 0.0]))
    elif family == "bottle cap":
        body_r, body_h = float(rng.uniform(0.03, 0.045)), float(rng.uniform(0.12, 0.22))
        neck_r, neck_h = float(rng.uniform(0.011, 0.016)), float(rng.uniform(0.015, 0.04))
        cap_r, cap_h = neck_r + float(rng.uniform(0.001, 0.006)), float(rng.uniform(0.012, 0.03))
        base = CENTRE - _v(0.0, 0.0, body_h)
        mount = [_cylinder("body", body_r, body_h, "z", base + _v(0.0, 0.0, body_h / 2)),
                 _cylinder("neck", neck_r, neck_h, "z", base + _v(0.0, 0.0, body_h + neck_h / 2))]  # fmt: skip
        top = base[2] + body_h + neck_h + cap_h
        part = [_cylinder("cap", cap_r, cap_h, "z", [CENTRE[0], CENTRE[1], top - cap_h / 2])]
        name = f"bottle cap r{1000 * cap_r:.0f} h{1000 * cap_h:.0f}mm body r{1000 * body_r:.0f}"
        pos, quat = palm_seed(np.array([CENTRE[0], CENTRE[1], top]), down, gap, rng)
    else:
        return _primitive_case(family, rng, gap)
    points = _scan(part + mount, pos, rng)
    return Case(name, points, pos, quat, functools.partial(exact_model, part, mount))


def _primitive_case(family: str, rng: np.random.Generator, gap: float) -> Case:
    """A free box or cylinder at the hand's size limits: a width the fingertips barely meet (10-20 mm) or one the
    open hand barely spans (90-120 mm for a box seen from above, 40-55 mm radius for a cylinder)."""
    if family.endswith("box"):
        small = family.startswith("small")
        width = float(rng.uniform(0.010, 0.020) if small else rng.uniform(0.09, 0.12))
        other, height = float(rng.uniform(0.03, 0.08)), float(rng.uniform(0.04, 0.12))
        half = (width / 2, other / 2, height / 2)
        shape = PrimitiveShape("box", half, tuple(CENTRE))  # type: ignore[arg-type]
        pos, quat = palm_seed(CENTRE + np.array([0.0, 0.0, height / 2]), np.array([0.0, 0.0, -1.0]), gap, rng,
                              np.array([0.0, 1.0, 0.0]))  # fmt: skip
        pts = _scan([_box("box", (width, other, height), CENTRE)], pos, rng)
        name = f"{family} {1000 * width:.0f}x{1000 * other:.0f}x{1000 * height:.0f}mm"
    else:
        thin = family.startswith("thin")
        radius = float(rng.uniform(0.006, 0.012) if thin else rng.uniform(0.04, 0.055))
        half_h = float(rng.uniform(0.04, 0.09))
        shape = PrimitiveShape("cylinder", (radius, half_h, 0.0), tuple(CENTRE))  # type: ignore[arg-type]
        pos, quat = palm_seed(CENTRE - np.array([0.0, radius, 0.0]), np.array([0.0, 1.0, 0.0]), gap, rng,
                              np.array([0.0, 0.0, 1.0]))  # fmt: skip
        pts = _scan([_cylinder("can", radius, 2 * half_h, "z", CENTRE)], pos, rng)
        name = f"{family} r{1000 * radius:.0f} h{2000 * half_h:.0f}mm"

    def truth(rng: np.random.Generator) -> ObjectModel:
        del rng
        return build_object_model(pts, np.random.default_rng(0), primitive=shape, normals=np.zeros_like(pts))

    return Case(name, pts, pos, quat, truth)


def family_cases(count: int, rng: np.random.Generator) -> list[Case]:
    """``count`` family objects, the families in turn (``FAMILIES``), each drawn from ``rng``."""
    return [family_case(FAMILIES[i % len(FAMILIES)], rng) for i in range(count)]
