"""``pbd diff A B [--json]`` and ``pbd diff NAME``: what changed between two descriptors (exit 0 same,
1 different, 2 bad input). With one argument, a descriptor name, the latest version against the one before it.
The text shows each change and its old -> new values, the grasps' quality and the parameters that differ."""

from __future__ import annotations

import argparse
import json
import sys

from tasks.diff.core import diff_descriptors, format_diff
from tasks.diff.values import changed_values, format_values
from tasks.errors import DescriptorError
from tasks.store import Store, resolve_store_root


def refs(store: Store, a: str, b: str | None) -> tuple[str, str]:
    """The two descriptor references to compare: ``a`` and ``b``, or ``NAME@v(N-1)`` and ``NAME@vN`` for a name."""
    if b is not None:
        return a, b
    versions = store.versions(a)
    if len(versions) < 2:
        what = "no such descriptor name" if not versions else "only one version: nothing to compare it with"
        raise DescriptorError(a, what)
    return f"{a}@v{versions[-2].version}", f"{a}@v{versions[-1].version}"


def run(args: argparse.Namespace) -> int:
    """Resolve both descriptors, compare, print; 0 when the same, 1 when different."""
    store = Store(resolve_store_root(args.store))
    ref_a, ref_b = refs(store, args.a, args.b)
    a, b = store.load(ref_a), store.load(ref_b)
    d = diff_descriptors(a, b)
    values = changed_values(a, b, d)
    if args.json:
        out = {**d.to_dict(), "refs": [ref_a, ref_b], "values": values}
        sys.stdout.write(json.dumps(out, indent=2, sort_keys=True) + "\n")
    else:
        head, *changes = format_diff(d)
        sys.stdout.write("\n".join([head, f"  compared: {ref_a} -> {ref_b}", *changes, *format_values(values)]) + "\n")
    return 0 if d.same else 1
