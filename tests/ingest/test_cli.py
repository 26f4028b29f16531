"""``pbd ingest`` as a user runs it: ids on stdout, one error line and exit 2, warnings on stderr, light start-up."""

from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

import numpy as np

from tests.conftest import LOGS, REPO

PBD = (sys.executable, "-m", "flows.cli")
"""The pbd command line of this checkout, run as a module by the interpreter running the tests."""


def _run(*args: str | Path) -> subprocess.CompletedProcess[str]:
    return subprocess.run([*PBD, *map(str, args)], capture_output=True, text=True, check=False, timeout=120)


def _recording(path: Path) -> Path:
    from tasks.recording.writer import RecordingWriter

    stamps = 1_700_000_000_000_000_000 + np.arange(200, dtype=np.int64) * 10_000_000
    with RecordingWriter(path, "mcap") as w:
        w.add_points("/mocap/handle", stamps, np.random.default_rng(0).normal(size=(200, 3)))
        w.add_string("/demo/meta", int(stamps[0]), '{"action": "open", "object": "drawer"}')
    return path


def test_ingest_prints_ids_and_is_idempotent(tmp_path: Path) -> None:
    """One id per line; ingesting again prints the same id and changes nothing."""
    rec = _recording(tmp_path / "demo.mcap")
    bag = LOGS / "rigid-body-motion" / "test.bag"
    store = tmp_path / "store"
    first = _run("ingest", rec, bag, "--store", store)
    assert first.returncode == 0, first.stderr
    ids = first.stdout.split()
    assert len(ids) == 2
    assert all(len(i) == 16 and int(i, 16) >= 0 for i in ids)
    info = json.loads((store / "recordings" / ids[0] / "recording.json").read_text())
    assert info["meta"] == {"action": "open", "object": "drawer"}
    assert info["source"] == str(rec)
    before = sorted(p.name for p in (store / "recordings").iterdir())
    again = _run("ingest", rec, "--store", store)
    assert again.returncode == 0
    assert again.stdout.split() == ids[:1]
    assert sorted(p.name for p in (store / "recordings").iterdir()) == before


def test_bad_input_exits_2_with_one_line(tmp_path: Path) -> None:
    """Exit 2, one stderr line naming the file and what is wrong, nothing in the store."""
    bad = tmp_path / "broken.mcap"
    bad.write_bytes(b"definitely not an mcap")
    store = tmp_path / "store"
    proc = _run("ingest", bad, "--store", store)
    assert proc.returncode == 2
    lines = proc.stderr.strip().splitlines()
    assert len(lines) == 1
    assert lines[0] == f"pbd ingest: {bad}: not a recording (a .mcap file without the mcap magic)"
    assert proc.stdout == ""
    assert not (store / "recordings").exists() or not any((store / "recordings").iterdir())


def test_recover_warns_and_exits_0(tmp_path: Path) -> None:
    """A truncated MCAP: exit 2 naming the byte; with --recover exit 0, the id, and a warning on stderr."""
    full = _recording(tmp_path / "demo.mcap").read_bytes()
    cut = tmp_path / "cut.mcap"
    cut.write_bytes(full[: len(full) * 2 // 3])
    store = tmp_path / "store"
    proc = _run("ingest", cut, "--store", store)
    assert proc.returncode == 2
    assert "truncated at byte" in proc.stderr
    proc = _run("ingest", cut, "--recover", "--store", store)
    assert proc.returncode == 0, proc.stderr
    assert len(proc.stdout.split()) == 1
    warnings = [line for line in proc.stderr.splitlines() if line.startswith("pbd ingest: warning:")]
    assert len(warnings) == 1
    assert "recovered" in warnings[0]


def test_startup_imports_nothing_heavy(tmp_path: Path) -> None:
    """The ingest path never imports prefect, open3d, pybullet or matplotlib."""
    rec = _recording(tmp_path / "demo.mcap")
    code = (
        "import sys\n"
        "from flows.cli import main\n"
        f"code = main(['ingest', {str(rec)!r}, '--store', {str(tmp_path / 'store')!r}])\n"
        "heavy = sorted(m for m in ('prefect', 'open3d', 'pybullet', 'matplotlib') if m in sys.modules)\n"
        "print(code, heavy)\n"
    )
    proc = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True, cwd=REPO)
    assert proc.stdout.strip().splitlines()[-1] == "0 []"
