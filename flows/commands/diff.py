"""``pbd diff A B [--json]``: what changed between two descriptors (exit 0 same, 1 different, 2 bad input)."""

from __future__ import annotations

import argparse
import json
import sys

from tasks.diff.core import diff_descriptors, format_diff
from tasks.store import Store, resolve_store_root


def run(args: argparse.Namespace) -> int:
    """Resolve both descriptors, compare, print; 0 when the same, 1 when different."""

    store = Store(resolve_store_root(args.store))
    a = store.load(args.a)
    b = store.load(args.b)
    d = diff_descriptors(a, b)
    if args.json:
        sys.stdout.write(json.dumps(d.to_dict(), indent=2, sort_keys=True) + "\n")
    else:
        sys.stdout.write("\n".join(format_diff(d)) + "\n")
    return 0 if d.same else 1
