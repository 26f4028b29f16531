"""The command line's shape: every command is there, errors are one line and exit 2."""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

from flows.cli import COMMANDS, build_parser

REPO = Path(__file__).resolve().parents[2]


def test_every_documented_command_is_there() -> None:
    assert set(COMMANDS) == {
        "demo",
        "synth",
        "ingest",
        "learn",
        "transfer",
        "simulate",
        "diff",
        "ls",
        "archive",
        "serve",
    }
    parser = build_parser()
    for name in COMMANDS:
        assert parser.parse_args([name, "--help"] if False else [name, *_minimal_args(name)]).command == name


def _minimal_args(name: str) -> list[str]:
    return {
        "synth": ["microwave", "--out", "x.mcap"],
        "ingest": ["x.mcap"],
        "learn": ["x.mcap"],
        "transfer": ["d.json", "--to", "m.ply"],
        "simulate": ["d.json"],
        "diff": ["a.json", "b.json"],
        "archive": ["dir"],
    }.get(name, [])


def test_cli_start_up_is_light() -> None:
    code = (
        "import sys; from flows.cli import build_parser; build_parser();"
        "heavy = [m for m in ('prefect', 'open3d', 'pybullet', 'matplotlib') if m in sys.modules];"
        "print(','.join(heavy))"
    )
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True, cwd=REPO)
    assert out.stdout.strip() == ""


def test_an_error_after_pybullet_loaded_is_one_stderr_line(tmp_path: Path) -> None:
    """pybullet prints its build time on stderr when imported; commands that load it import it quietly."""
    from tests.simulate.objects import DrawerSpec

    desc = tmp_path / "door.json"
    desc.write_text(DrawerSpec().descriptor(0.3).to_json())  # a translation: the bottle has no slide
    out = subprocess.run(
        [
            sys.executable,
            "-m",
            "flows.cli",
            "simulate",
            str(desc),
            "--scene",
            "bottle",
            "--store",
            str(tmp_path / "store"),
        ],
        capture_output=True,
        text=True,
        timeout=120,
        check=False,
    )
    assert out.returncode == 2
    lines = out.stderr.splitlines()
    assert len(lines) == 1, out.stderr
    assert lines[0].startswith("pbd simulate: "), lines[0]
    assert "prismatic" in lines[0], lines[0]
