"""``pbd ingest RECORDING... [--topics MAP] [--recover] [--object-model FILE]``: recordings into the store.

Prints one recording id per line on stdout (warnings go to stderr). Imports nothing heavy at module top;
the ingest path itself never imports Prefect, open3d (except for ``--object-model``), pybullet or matplotlib.
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path


def add_arguments(parser: argparse.ArgumentParser) -> None:
    """Arguments of ``pbd ingest``."""
    parser.add_argument("recordings", nargs="+", type=Path, metavar="RECORDING", help=".mcap, .bag or rosbag2 folder")
    parser.add_argument("--topics", type=Path, metavar="MAP", help="topic map YAML overriding role detection")
    parser.add_argument(
        "--recover",
        action="store_true",
        help="keep the intact messages of a truncated or damaged MCAP, bag or rosbag2 (warns what was lost)",
    )
    parser.add_argument(
        "--object-model", type=Path, metavar="FILE", help="object model .ply/.pcd/.obj/.stl (world frame)"
    )


def run(args: argparse.Namespace) -> int:
    """Ingest each recording in turn; the first bad one raises (exit 2, nothing of it left in the store)."""
    from tasks.ingest.api import ingest_recording  # noqa: PLC0415
    from tasks.store import Store, resolve_store_root  # noqa: PLC0415

    store = Store(resolve_store_root(args.store))
    for source in args.recordings:
        result = ingest_recording(
            source, store, topics=args.topics, recover=args.recover, object_model=args.object_model
        )
        for warning in result.warnings:
            sys.stderr.write(f"pbd ingest: warning: {warning}\n")
        sys.stdout.write(result.recording_id + "\n")
        sys.stdout.flush()
    return 0
