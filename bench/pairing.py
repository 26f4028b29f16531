"""Speed and reach of the stretched fits' pairing (``tasks.transfer.pairing.nearest_compatible``) beside its peer,
the nearest scan point dropped when its normal disagrees (one KD-tree query).

The scan is a door leaf's front (1.6 x 0.8 m) and one of its 40 mm edge faces, sampled every ``--spacing``
millimetres with 1.5 mm of noise and estimated normals; the model points are 3,000 on the front and 150 on the edge
face, whose scan lies ``--offset`` mm away across the leaf (a leaf stretched too little). Printed per
correspondence distance: seconds per query (best of three), how many front and edge points each pairs. Scans:
development spacing 3 mm (``--spacing 3``), held out 1 mm (only reported; a million points).

    OMP_NUM_THREADS=1 PYTHONPATH=. .venv/bin/python bench/pairing.py [--spacing MM] [--offset MM]
"""

from __future__ import annotations

import argparse
import sys
import time
from collections.abc import Callable
from functools import partial
from pathlib import Path
from typing import TypeVar

import numpy as np
from scipy.spatial import cKDTree

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from tasks.transfer.pairing import nearest_compatible
from tasks.transfer.registration import surface_normals
from tasks.transfer.stretch import NORMAL_COS

T = TypeVar("T")
DEV_SPACING_MM = 3.0
HELDOUT_SPACING_MM = 1.0


def leaf_scan(spacing: float, rng: np.random.Generator) -> np.ndarray:
    """(m, 3) metres: the leaf's front (z = 0) and its edge face (x = 0.4, z from -0.04 to 0), noisy."""
    xs, ys = np.arange(-0.4, 0.4, spacing), np.arange(-0.8, 0.8, spacing)
    gx, gy = np.meshgrid(xs, ys)
    front = np.column_stack([gx.ravel(), gy.ravel(), np.zeros(gx.size)])
    zs = np.arange(-0.04, 0.0, spacing)
    ey, ez = np.meshgrid(ys, zs)
    edge = np.column_stack([np.full(ey.size, 0.4), ey.ravel(), ez.ravel()])
    points = np.vstack([front, edge])
    return points + rng.normal(scale=0.0015, size=points.shape)


def plain(tree: cKDTree, points: np.ndarray, normals: np.ndarray, scan_normals: np.ndarray, dist: float) -> np.ndarray:
    """The peer: the nearest scan point, dropped when its normal disagrees."""
    d, idx = tree.query(points, distance_upper_bound=dist)
    ok = np.isfinite(d)
    ok[ok] &= np.abs(np.einsum("ij,ij->i", scan_normals[idx[ok]], normals[ok])) >= NORMAL_COS
    return ok


def best_of(fn: Callable[[], T], repeats: int = 3) -> tuple[float, T]:
    """Smallest wall time of ``repeats`` calls of ``fn`` and its last result."""
    times = []
    for _ in range(repeats):
        start = time.perf_counter()
        out = fn()
        times.append(time.perf_counter() - start)
    return min(times), out


def run(spacing_mm: float, offset_mm: float) -> None:
    rng = np.random.default_rng(0)
    scan = leaf_scan(spacing_mm * 1e-3, rng)
    scan_normals = surface_normals(scan, spacing_mm * 1e-3)
    tree = cKDTree(scan)
    front = np.column_stack([rng.uniform(-0.35, 0.35, 3000), rng.uniform(-0.75, 0.75, 3000), np.zeros(3000)])
    edge_x = 0.4 - offset_mm * 1e-3
    edge = np.column_stack([np.full(150, edge_x), rng.uniform(-0.75, 0.75, 150), rng.uniform(-0.04, 0.0, 150)])
    points = np.vstack([front, edge])
    normals = np.vstack([np.tile([0.0, 0.0, 1.0], (3000, 1)), np.tile([1.0, 0.0, 0.0], (150, 1))])
    print(f"scan {len(scan):,} points ({spacing_mm:g} mm spacing); model edge face {offset_mm:g} mm short")
    print(
        f"{'distance mm':>11} | {'compatible s':>12} {'front':>6} {'edge':>5} | {'nearest s':>9} {'front':>6} "
        f"{'edge':>5}"
    )
    for dist_mm in (10.0, 25.0, 50.0, 100.0):
        dist = dist_mm * 1e-3
        t_c, (_, found) = best_of(
            partial(nearest_compatible, tree, points, normals, scan_normals, dist_m=dist, min_cos=NORMAL_COS)
        )
        t_p, ok = best_of(partial(plain, tree, points, normals, scan_normals, dist))
        print(
            f"{dist_mm:11.0f} | {t_c:12.3f} {int(found[:3000].sum()):6d} {int(found[3000:].sum()):5d} | "
            f"{t_p:9.3f} {int(ok[:3000].sum()):6d} {int(ok[3000:].sum()):5d}"
        )


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--spacing", type=float, default=None, help="scan spacing, mm (default: both parts)")
    parser.add_argument("--offset", type=float, default=30.0, help="the model edge face's offset, mm")
    args = parser.parse_args()
    if args.spacing is not None:
        run(args.spacing, args.offset)
        return
    print("development")
    run(DEV_SPACING_MM, args.offset)
    print("\nheld out")
    run(HELDOUT_SPACING_MM, args.offset)


if __name__ == "__main__":
    main()
