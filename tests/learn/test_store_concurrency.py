"""Several processes storing descriptors under one name at once: versions stay contiguous and valid."""

from __future__ import annotations

import itertools
import subprocess
import sys
from pathlib import Path

from tasks.store import Store

REPO = Path(__file__).resolve().parents[2]

WRITER = """
import sys
from schemas.descriptor import Descriptor, ObjectRef, Primitive
from tasks.store import Store

store = Store(sys.argv[1])
worker = int(sys.argv[2])
for i in range(6):
    extent = 1.0 + 0.1 * ((worker + i) % 3)
    chain = (Primitive("rotation", (0.0, 0.0, 0.0), (0.0, 0.0, 1.0), extent),)
    store.put_descriptor(Descriptor("open-door", "open", ObjectRef("door"), None, chain, code_version="x"))
"""


def test_concurrent_learners_keep_the_version_history_consistent(store: Store) -> None:
    procs = [
        subprocess.Popen([sys.executable, "-c", WRITER, str(store.root), str(w)], cwd=REPO, stderr=subprocess.PIPE)
        for w in range(4)
    ]
    for p in procs:
        _, err = p.communicate(timeout=120)
        assert p.returncode == 0, err.decode()
    entries = store.versions("open-door")
    assert [e.version for e in entries] == list(range(1, len(entries) + 1))
    assert all(a.id != b.id for a, b in itertools.pairwise(entries))  # new version only on change
    for e in entries:
        assert store.load(f"open-door@v{e.version}").id == e.id
    assert {round(store.load(f"open-door@v{e.version}").chain[0].extent, 1) for e in entries} <= {1.0, 1.1, 1.2}
