"""The start of an axis neighbourhood's fit when the whole model knows the axis only loosely: a lever on a panel."""

from __future__ import annotations

import numpy as np

from tasks.arrays import Points
from tasks.transfer.neighbourhood_search import search_start
from tasks.transfer.similarity import Similarity
from tasks.transfer.stretch import Stretched
from tests.transfer import shapes
from tests.transfer.shapes import Part

AXIS = (np.zeros(3), np.array([0.0, 0.0, 1.0]))
"""The lever's spindle: the z axis (the panel's front face is z = 0)."""


def shifted(part: Part, offset: np.ndarray) -> Part:
    """``part`` moved by ``offset`` (metres)."""

    def sample(n: int, rng: np.random.Generator) -> tuple[Points, Points]:
        pts, normals = part.sample(n, rng)
        return pts + offset, normals

    return Part(part.area, sample)


def lever(at: np.ndarray) -> list[Part]:
    """A rose (27 mm radius), a spindle (9 mm) and a lever 130 x 20 x 14 mm standing off the panel at ``at``."""
    hardware = [
        shapes.cylinder_side(0.027, 0.0, 0.01),
        shapes.disk(0.027, 0.01, True, inner=0.009),
        shapes.cylinder_side(0.009, 0.01, 0.06),
    ]
    return [shifted(p, at) for p in hardware] + shapes.box(
        np.array([0.13, 0.02, 0.014]), at + np.array([-0.055, 0.0, 0.067])
    )


def panel_with(levers: list[np.ndarray]) -> list[Part]:
    """A panel 0.3 x 0.3 x 0.04 m with a lever at each of ``levers``."""
    parts = shapes.box(np.array([0.3, 0.3, 0.04]), np.array([0.0, 0.0, -0.02]))
    for at in levers:
        parts += lever(at)
    return parts


def model_and_scan(levers: list[np.ndarray], seed: int) -> tuple[Points, Points, Points, Points]:
    """The demonstrated panel's region about the spindle (one lever, 0.5 mm noise) with its normals, and a scan
    of a panel with ``levers`` from its front (1.5 mm noise) with its normals."""
    rng = np.random.default_rng(seed)
    source, normals = shapes.sample_parts(panel_with([np.zeros(3)]), 30_000, rng)
    near = np.hypot(source[:, 0], source[:, 1]) <= 0.1
    source = source[near] + rng.normal(scale=5e-4, size=(int(near.sum()), 3))
    scan, scan_normals = shapes.sample_parts(panel_with(levers), 30_000, rng)
    view = np.array([0.3, -0.2, 1.0]) / np.linalg.norm([0.3, -0.2, 1.0])
    seen = scan_normals @ view > 0.1
    scan = scan[seen] + rng.normal(scale=1.5e-3, size=(int(seen.sum()), 3))
    return source, normals[near], scan, scan_normals[seen]


def placed_off(start: Stretched) -> float:
    """How far ``start`` carries the spindle from the true one, metres."""
    pos, _ = start.carry_line(*AXIS)
    return float(np.hypot(pos[0], pos[1]))


def loose(offset: tuple[float, float]) -> Stretched:
    """A whole-model placement ``offset`` (x, y metres) off across the spindle."""
    return Stretched(Similarity(1.0, np.eye(3), np.array([*offset, 0.0])), np.eye(3), np.ones(3), np.zeros(3))


def test_a_loosely_placed_lever_is_found_across_the_axis() -> None:
    source, normals, scan, scan_normals = model_and_scan([np.zeros(3)], seed=3)
    whole = loose((0.03, 0.025))  # 39 mm off: beyond a local fit's reach of a lever 20 mm tall
    found = search_start(
        whole, source, normals, scan, scan_normals, line=AXIS, sigma_m=0.017, radius_m=0.1, dist_m=0.008, reach_m=0.02
    )
    assert found is not None
    assert placed_off(found.start) < 0.008 < placed_off(whole)
    assert found.spread_m == 0.0


def test_two_levers_the_scan_cannot_tell_apart_are_reported() -> None:
    source, normals, scan, scan_normals = model_and_scan([np.zeros(3), np.array([0.0, 0.07, 0.0])], seed=4)
    whole = loose((0.0, 0.035))  # half-way between them
    found = search_start(
        whole, source, normals, scan, scan_normals, line=AXIS, sigma_m=0.025, radius_m=0.1, dist_m=0.008, reach_m=0.02
    )
    assert found is not None
    assert found.spread_m > 0.06  # both places: the fit's sigma must cover their distance


def test_a_tight_placement_is_left_to_the_fit() -> None:
    source, normals, scan, scan_normals = model_and_scan([np.zeros(3)], seed=5)
    assert search_start(loose((0.001, 0.0)), source, normals, scan, scan_normals, line=AXIS, sigma_m=0.005,
                        radius_m=0.1, dist_m=0.008, reach_m=0.02) is None  # fmt: skip


def test_a_lever_seen_on_one_face_is_found_where_that_face_lies() -> None:
    # The scan sees the arm's lower face (-y) only. Searched at a distance over half the arm's 20 mm height, the
    # model slid 10 mm down has both its faces that far from the scanned one; only the place where the model's
    # lower face lies on it is the lever's.
    source, normals, scan, scan_normals = model_and_scan([np.zeros(3)], seed=6)
    whole = loose((0.0, 0.03))
    found = search_start(
        whole, source, normals, scan, scan_normals, line=AXIS, sigma_m=0.017, radius_m=0.1, dist_m=0.014,
        reach_m=0.02,
    )  # fmt: skip
    assert found is not None
    assert placed_off(found.start) < 0.005
