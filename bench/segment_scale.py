"""Scale of ``pbd learn``: a door opened and closed over and over for 5 minutes at 120 Hz (3 markers, 36,000
samples each, 130 primitives) against a 10-second recording of the same, each learned by a fresh ``pbd learn``
process (ingest included). Prints wall time, peak memory (ru_maxrss of the process) and whether every primitive
was found with its extent.

    .venv/bin/python bench/segment_scale.py [--quick]
"""

from __future__ import annotations

import argparse
import json
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

REPO = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(REPO))

from tasks.recording.writer import RecordingWriter  # noqa: E402
from tasks.store import Store  # noqa: E402

START_NS = 1_700_000_000_000_000_000
HZ = 120.0
HINGE = np.array([0.5, 0.2, 0.8])
MARKERS = {"/mocap/door_0": [0.8, 0.2, 0.9], "/mocap/door_1": [0.95, 0.2, 0.7], "/mocap/thumb": [1.0, 0.23, 0.8]}
SWING_S, HOLD_S = 1.5, 0.8

RUNNER = """
import resource, sys, time
t0 = time.perf_counter()
from flows.cli import main
code = main(sys.argv[1:])
use = resource.getrusage(resource.RUSAGE_SELF)
sys.stderr.write(f"BENCH {time.perf_counter() - t0:.3f} {use.ru_utime + use.ru_stime:.3f} {use.ru_maxrss}\\n")
sys.exit(code)
"""


def door_cycles(duration_s: float, rng: np.random.Generator) -> tuple[np.ndarray, np.ndarray, list[float]]:
    """Times (s), door angle (rad) and the signed swing of every primitive (open +, close -)."""
    t = np.arange(0.0, duration_s, 1.0 / HZ)
    angle = np.zeros_like(t)
    swings: list[float] = []
    now, current = 0.5, 0.0
    while True:
        target = rng.uniform(0.9, 1.4) if current == 0.0 else 0.0
        if now + SWING_S > duration_s - 0.3:
            break
        s = np.clip((t - now) / SWING_S, 0.0, 1.0)
        s = 10 * s**3 - 15 * s**4 + 6 * s**5
        moving = t >= now
        angle[moving] = current + (target - current) * s[moving]
        swings.append(target - current)
        current = target
        now += SWING_S + HOLD_S
    return t, angle, swings


def write(path: Path, duration_s: float, rng: np.random.Generator) -> list[float]:
    """Write the recording (PointStamped per marker, 0.5 mm noise) and return the true swings."""
    t, angle, swings = door_cycles(duration_s, rng)
    stamps = START_NS + np.round(t * 1e9).astype(np.int64)
    c, s = np.cos(angle), np.sin(angle)
    with RecordingWriter(path, "mcap") as w:
        for name, p0 in MARKERS.items():
            q = np.asarray(p0) - HINGE
            pts = np.column_stack([c * q[0] - s * q[1], s * q[0] + c * q[1], np.full_like(angle, q[2])]) + HINGE
            w.add_points(name, stamps, pts + rng.normal(0.0, 0.0005, pts.shape))
        w.add_string("/demo/meta", START_NS, json.dumps({"action": "swing", "object": "door"}))
    return swings


def learn(path: Path, store: Path) -> tuple[float, float, float, float]:
    """Run ``pbd learn`` in a fresh process: (wall s, in-process s, CPU s, peak RSS MB)."""
    t0 = time.perf_counter()
    proc = subprocess.run(
        [sys.executable, "-c", RUNNER, "learn", str(path), "--store", str(store), "--name", path.stem],
        capture_output=True,
        text=True,
        check=False,
        cwd=REPO,
    )
    wall = time.perf_counter() - t0
    if proc.returncode != 0:
        sys.exit(f"pbd learn failed: {proc.stderr.strip()}")
    line = next(x for x in proc.stderr.splitlines() if x.startswith("BENCH "))
    _, inner, cpu, rss_kb = line.split()
    return wall, float(inner), float(cpu), float(rss_kb) / 1024.0


def check(store: Store, name: str, swings: list[float]) -> tuple[int, int, float]:
    """(found, expected, worst extent error in degrees): kinds, order and sign of every swing."""
    desc = store.load(f"{name}@latest")
    if len(desc.chain) != len(swings) or any(p.kind != "rotation" for p in desc.chain):
        return len(desc.chain), len(swings), float("nan")
    axis = np.array([0.0, 0.0, 1.0])
    signs = [np.sign(np.dot(p.dir, axis)) for p in desc.chain]
    if any(sg != np.sign(w) for sg, w in zip(signs, swings, strict=True)):
        return len(desc.chain), len(swings), float("nan")
    worst = max(abs(p.extent - abs(w)) for p, w in zip(desc.chain, swings, strict=True))
    return len(desc.chain), len(swings), float(np.degrees(worst))


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--quick", action="store_true", help="60 s instead of 5 minutes")
    args = parser.parse_args()
    long_s = 60.0 if args.quick else 300.0
    rng = np.random.default_rng(0)
    with tempfile.TemporaryDirectory(prefix="pbd-bench-scale-") as tmp:
        folder = Path(tmp)
        store = Store(folder / "store")
        rows = []
        for label, duration in (("short", 10.0), ("long", long_s)):
            path = folder / f"door-{label}.mcap"
            swings = write(path, duration, rng)
            wall, inner, cpu, rss = learn(path, store.root)
            found, expected, worst = check(store, path.stem, swings)
            n = int(duration * HZ)
            rows.append((f"{duration:g} s", n, expected, found, worst, wall, inner, cpu, rss))
    print(f"pbd learn on a door opened and closed repeatedly (3 markers at {HZ:g} Hz, 0.5 mm noise, fresh process)")
    head = f"{'recording':<10} {'samples/marker':>14} {'primitives':>11} {'found':>6} {'worst extent err':>17}"
    print(head + f" {'wall s':>7} {'in-process s':>13} {'CPU s':>6} {'peak RSS MB':>12}")
    for dur, n, exp, found, worst, wall, inner, cpu, rss in rows:
        print(
            f"{dur:<10} {n:>14} {exp:>11} {found:>6} {worst:>13.3f} deg {wall:>7.1f} {inner:>13.1f} {cpu:>6.1f}"
            f" {rss:>12.0f}"
        )
    (_, n0, *_, t0, _, _, m0), (_, n1, *_, t1, _, _, m1) = rows
    print(f"growth: {n1 / n0:.0f}x samples -> {t1 / t0:.1f}x time, {m1 / m0:.1f}x memory")
    print(f"target: under 15 s and 1 GB; the dense Table I affinity alone would need "
          f"{n1**2 * 8 / 1e9:.1f} GB per marker here")  # fmt: skip


if __name__ == "__main__":
    main()
