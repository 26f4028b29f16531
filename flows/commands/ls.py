"""``pbd ls [NAME] [--json]``: the stored descriptors (name, versions, latest version, id, created), or the
versions of one name (version, id, created, recording, seed). Plain tab-separated text, one row per line."""

from __future__ import annotations

import argparse
import json
import sys
from typing import Any

from tasks.errors import DescriptorError
from tasks.store import Store, resolve_store_root


def listing(store: Store, name: str | None) -> list[dict[str, Any]]:
    """One row per descriptor name, or per version of ``name`` (oldest first); ``DescriptorError`` for an
    unknown name."""
    if name is None:
        rows = []
        for n in store.names():
            versions = store.versions(n)
            last = versions[-1]
            rows.append(
                {
                    "name": n,
                    "versions": len(versions),
                    "latest": f"{n}@v{last.version}",
                    "id": last.id,
                    "created": last.created,
                }
            )
        return rows
    versions = store.versions(name)
    if not versions:
        raise DescriptorError(name, "no such descriptor name")
    return [
        {
            "ref": f"{name}@v{v.version}",
            "id": v.id,
            "created": v.created,
            "recording": v.recording,
            "seed": store.load(f"{name}@v{v.version}").extra_provenance.get("seed"),
        }
        for v in versions
    ]


def run(args: argparse.Namespace) -> int:
    """Print the listing; 0."""
    rows = listing(Store(resolve_store_root(args.store)), args.name)
    if args.json:
        sys.stdout.write(json.dumps(rows, indent=2) + "\n")
        return 0
    if rows:
        keys = list(rows[0])
        lines = ["\t".join(keys)] + ["\t".join("-" if r[k] is None else str(r[k]) for k in keys) for r in rows]
        sys.stdout.write("\n".join(lines) + "\n")
    return 0
