"""``pbd demo``: make the sample recordings if missing, run the whole pipeline flow over them, print where the
descriptors and the report are and whether each task succeeded in simulation.

Needs no Prefect server: without ``PREFECT_API_URL`` Prefect starts a temporary one in this process. Exit 0
when every sample was processed, 1 when some failed.
"""

from __future__ import annotations

import argparse
import json
import sys

from flows.cli_output import print_failures, print_run, progress_bar
from flows.demo import demo
from flows.runtime import cli_settings
from flows.summary import summary_of
from tasks.store import resolve_store_root


def run(args: argparse.Namespace) -> int:
    """Run the demo flow; 0 when every sample recording was processed, 1 when some failed."""
    store = resolve_store_root(args.store).resolve()
    with cli_settings(), progress_bar("sample tasks", hidden=args.json):
        state = demo(store=str(store), samples=str(args.samples.resolve()), workers=args.workers, return_state=True)
    summary = summary_of(state)
    if args.json:
        sys.stdout.write(json.dumps(summary, indent=2) + "\n")
        return print_failures(summary, "demo")
    code = print_run(summary, f"pbd demo - store {store}", "demo")
    sys.stdout.write(f"descriptors: {store / 'descriptors'}\n")
    return code
