"""``pbd synth SCENE --out PATH [--format mcap|bag|rosbag2] [--seed N]``: record a simulated demonstration of a
built-in scene, with ``PATH.truth.json`` beside it.

Prints the recording's path and the truth file's path, one per line. Imports nothing heavy at module top (no
Prefect ever; pybullet only once the arguments are checked).
"""

from __future__ import annotations

import argparse
import json
import sys

from tasks.errors import SceneError
from tasks.scenes.catalog import SCENE_NAMES
from tasks.synth.paths import check_output, check_scene_name, truth_path
from tasks.synth.record import synthesize


def run(args: argparse.Namespace) -> int:
    """Synthesise the recording and its truth file; ``SceneError``/``RecordingError`` (exit 2) for bad input."""

    if args.seed is not None and args.seed < 0:
        msg = f"--seed must be a non-negative integer, not {args.seed}"
        raise SceneError(msg)
    check_scene_name(args.scene, SCENE_NAMES)
    check_output(args.out, args.format)

    out = synthesize(args.scene, args.seed, args.out, args.format)
    if args.json:
        sys.stdout.write(json.dumps({"recording": str(out), "truth": str(truth_path(out))}) + "\n")
    else:
        sys.stdout.write(f"{out}\n{truth_path(out)}\n")
    sys.stdout.flush()
    return 0
