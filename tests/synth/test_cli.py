"""``pbd synth`` end to end (the real console script) and its one-line errors (exit 2)."""

from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

import pytest

PBD = (sys.executable, "-m", "flows.cli")
"""The pbd command line of this checkout, run as a module by the interpreter running the tests."""


def _pbd(*args: str) -> subprocess.CompletedProcess[str]:
    return subprocess.run([*PBD, *args], capture_output=True, text=True, check=False, timeout=120)


def test_synth_writes_a_bag_and_its_truth(tmp_path: Path) -> None:
    out = tmp_path / "cap.bag"
    done = _pbd("synth", "bottle", "--out", str(out), "--format", "bag", "--seed", "3")
    assert done.returncode == 0, done.stderr
    assert done.stdout.splitlines()[-2:] == [str(out), f"{out}.truth.json"]
    truth = json.loads(Path(f"{out}.truth.json").read_text())
    assert (truth["scene"], truth["seed"], truth["recording"]["format"]) == ("bottle", 3, "bag")
    assert [p["kind"] for p in truth["chain"]] == ["rotation"]
    assert out.stat().st_size > 10_000


def test_synth_default_format_is_mcap_and_nominal_without_seed(tmp_path: Path) -> None:
    out = tmp_path / "m.mcap"
    done = _pbd("synth", "microwave", "--out", str(out))
    assert done.returncode == 0, done.stderr
    truth = json.loads(Path(f"{out}.truth.json").read_text())
    assert (truth["seed"], truth["recording"]["format"]) == (None, "mcap")
    assert out.read_bytes()[:8] == b"\x89MCAP0\r\n"


@pytest.mark.parametrize(
    ("args", "message"),
    [
        (["fridge", "--out", "{tmp}/f.mcap"], "pbd synth: unknown scene 'fridge' (built-in scenes: microwave, "),
        (["door", "--out", "{tmp}/f.mcap", "--format", "ros3"], "unknown format 'ros3' (expected one of mcap, bag"),
        (["door", "--out", "{tmp}/f.mcap", "--format", "bag"], "f.mcap: a bag recording must end in .bag"),
        (["door", "--out", "{tmp}/exists.mcap"], "exists.mcap: output exists; refusing to overwrite"),
        (["door", "--out", "{tmp}/f.mcap", "--seed", "-4"], "--seed must be a non-negative integer, not -4"),
    ],
)
def test_synth_errors_are_one_line_and_exit_2(tmp_path: Path, args: list[str], message: str) -> None:
    (tmp_path / "exists.mcap").write_bytes(b"keep")
    done = _pbd("synth", *(a.format(tmp=tmp_path) for a in args))
    assert done.returncode == 2
    lines = done.stderr.splitlines()
    assert len(lines) == 1 and message in lines[0], done.stderr
    assert (tmp_path / "exists.mcap").read_bytes() == b"keep"
    assert sorted(p.name for p in tmp_path.iterdir()) == ["exists.mcap"]
