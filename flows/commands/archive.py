"""``pbd archive DIR``: the reprocessing flow over every recording in DIR, with a progress bar on stderr.

With ``--address tcp://HOST:PORT`` the tasks run on an existing Dask cluster (prefect-dask's DaskTaskRunner);
without it they run concurrently on this machine, ``--workers`` recordings at a time. Exit 0 when every
recording was processed, 1 when some failed (one line each on stderr), 2 for bad arguments.
"""

from __future__ import annotations

import argparse
import json
import sys

from flows.address import check_address
from flows.cli_args import parse_params
from flows.cli_output import print_failures, print_run, progress_bar
from flows.discover import find_recordings
from flows.reprocess_archive import reprocess_archive
from flows.runtime import cli_settings
from flows.summary import summary_of
from tasks.store import resolve_store_root


def run(args: argparse.Namespace) -> int:
    """Run ``reprocess-archive`` over ``args.dir``; 0 all processed, 1 some recordings failed, 2 bad arguments."""
    params = parse_params(args.param)
    grasp = parse_params(args.grasp_param, "--grasp-param")
    find_recordings(args.dir)  # fail fast, before Prefect starts, on a missing folder
    if args.address:
        check_address(args.address)
    with cli_settings(), progress_bar("recordings", hidden=args.json):
        state = reprocess_archive(
            archive=str(args.dir.resolve()),
            store=str(resolve_store_root(args.store).resolve()),
            params=params,
            grasp=grasp,
            seed=args.seed,
            workers=args.workers,
            report=not args.no_report,
            address=args.address,
            return_state=True,
        )
    summary = summary_of(state)
    if args.json:
        sys.stdout.write(json.dumps(summary, indent=2) + "\n")
        return print_failures(summary, "archive")
    return print_run(summary, "reprocess-archive", "archive")
