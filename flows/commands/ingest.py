"""``pbd ingest RECORDING... [--topics MAP] [--recover] [--object-model FILE]``: recordings into the store.

Prints one recording id per line on stdout (warnings go to stderr). Imports nothing heavy at module top;
the ingest path itself never imports Prefect, open3d (except for ``--object-model``), pybullet or matplotlib.
"""

from __future__ import annotations

import argparse
import json
import sys

from tasks.ingest.api import ingest_recording
from tasks.store import Store, resolve_store_root


def run(args: argparse.Namespace) -> int:
    """Ingest each recording in turn; the first bad one raises (exit 2, nothing of it left in the store)."""

    store = Store(resolve_store_root(args.store))
    rows = []
    for source in args.recordings:
        result = ingest_recording(
            source, store, topics=args.topics, recover=args.recover, object_model=args.object_model
        )
        for warning in result.warnings:
            sys.stderr.write(f"pbd ingest: warning: {warning}\n")
        rows.append({"id": result.recording_id, "source": str(source), "warnings": list(result.warnings)})
        if not args.json:
            sys.stdout.write(result.recording_id + "\n")
            sys.stdout.flush()
    if args.json:
        sys.stdout.write(json.dumps(rows, indent=2) + "\n")
    return 0
