"""``pbd serve``: serve ``reprocess-archive/nightly`` (cron) and ``process-recording/on-demand``.

Runs until stopped (Ctrl-C or SIGTERM). Start a run with
``prefect deployment run 'reprocess-archive/nightly' --param archive=DIR``.
"""

from __future__ import annotations

import argparse
from pathlib import Path

DEFAULT_ARCHIVE = Path("data/recordings")


def add_arguments(parser: argparse.ArgumentParser) -> None:
    """Arguments of ``pbd serve``."""
    parser.add_argument(
        "--archive", type=Path, default=DEFAULT_ARCHIVE, help="default archive folder of the nightly run"
    )
    parser.add_argument("--cron", default="0 3 * * *", help="schedule of the nightly run (default 03:00 UTC)")
    parser.add_argument("--workers", type=int, default=2, help="recordings in flight per archive run")
    parser.add_argument("--limit", type=int, default=2, help="flow runs executed at once by this server")


def run(args: argparse.Namespace) -> int:
    """Serve the deployments until stopped; returns 0 after a clean shutdown."""
    from prefect import serve  # noqa: PLC0415

    from flows.deployments import build_deployments  # noqa: PLC0415
    from tasks.store import resolve_store_root  # noqa: PLC0415

    store = str(resolve_store_root(args.store).resolve())
    deployments = build_deployments(str(args.archive.resolve()), store, cron=args.cron, workers=args.workers)
    serve(*deployments, limit=args.limit)
    return 0
