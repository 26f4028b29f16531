"""``pbd synth SCENE --out PATH [--format mcap|bag|rosbag2] [--seed N]``: record a simulated demonstration of a
built-in scene, with ``PATH.truth.json`` beside it.

Prints the recording's path and the truth file's path, one per line. Imports nothing heavy at module top (no
Prefect ever; pybullet only once the arguments are checked).
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path


def add_arguments(parser: argparse.ArgumentParser) -> None:
    """Arguments of ``pbd synth``."""
    parser.add_argument("scene", metavar="SCENE", help="built-in scene name")
    parser.add_argument(
        "--out", type=Path, required=True, metavar="PATH", help="recording to write (never overwritten)"
    )
    parser.add_argument(
        "--format", default="mcap", metavar="FORMAT", help="mcap (default), bag or rosbag2 (PATH is then a folder)"
    )
    parser.add_argument(
        "--seed", type=int, default=None, metavar="N", help="randomised instance (placement, sizes, pace, sensors)"
    )


def run(args: argparse.Namespace) -> int:
    """Synthesise the recording and its truth file; ``SceneError``/``RecordingError`` (exit 2) for bad input."""
    from tasks.errors import SceneError  # noqa: PLC0415
    from tasks.scenes.catalog import SCENE_NAMES  # noqa: PLC0415
    from tasks.synth.paths import check_output, check_scene_name, truth_path  # noqa: PLC0415

    if args.seed is not None and args.seed < 0:
        msg = f"--seed must be a non-negative integer, not {args.seed}"
        raise SceneError(msg)
    check_scene_name(args.scene, SCENE_NAMES)
    check_output(args.out, args.format)
    from tasks.synth.record import synthesize  # noqa: PLC0415 - pybullet loads here, once the arguments are good

    out = synthesize(args.scene, args.seed, args.out, args.format)
    sys.stdout.write(f"{out}\n{truth_path(out)}\n")
    sys.stdout.flush()
    return 0
