"""``pbd serve``: serve ``reprocess-archive/nightly`` (cron) and ``process-recording/on-demand``.

Runs until stopped (Ctrl-C or SIGTERM). Start a run with
``prefect deployment run 'reprocess-archive/nightly' --param archive=DIR``.
"""

from __future__ import annotations

import argparse

from prefect import serve

from flows.address import check_address
from flows.deployments import build_deployments
from tasks.store import resolve_store_root


def run(args: argparse.Namespace) -> int:
    """Serve the deployments until stopped; returns 0 after a clean shutdown, 2 for a bad ``--address``."""
    if args.address:
        check_address(args.address)
    store = str(resolve_store_root(args.store).resolve())
    deployments = build_deployments(
        str(args.archive.resolve()), store, cron=args.cron, workers=args.workers, address=args.address
    )
    serve(*deployments, limit=args.limit)
    return 0
