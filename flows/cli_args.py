"""The arguments of every ``pbd`` command: argparse and the standard library only, so ``pbd --help`` and the
parsing of any command import nothing of the stages."""

from __future__ import annotations

import argparse
import json
from collections.abc import Callable
from pathlib import Path
from typing import Any

from tasks.errors import PbdError


class ParameterError(PbdError):
    """A ``--param KEY=VALUE`` argument is malformed."""


def add_param_argument(parser: argparse.ArgumentParser) -> None:
    """``--param KEY=VALUE`` (repeatable): a learning parameter, the value read as JSON when it parses."""
    parser.add_argument(
        "--param",
        action="append",
        default=[],
        metavar="KEY=VALUE",
        help="learning parameter for tasks.learn.api.LearnParams (repeatable), e.g. --param t0=0.1",
    )


def add_grasp_param_argument(parser: argparse.ArgumentParser) -> None:
    """``--grasp-param KEY=VALUE`` (repeatable): a parameter of the grasp planner."""
    parser.add_argument(
        "--grasp-param",
        action="append",
        default=[],
        metavar="KEY=VALUE",
        help="grasp planner parameter for tasks.grasp.planner.PlannerParams (repeatable), e.g. --grasp-param steps=300",
    )


def parse_params(items: list[str], flag: str = "--param") -> dict[str, Any]:
    """``["k=3", "t0=0.1"]`` → ``{"k": 3, "t0": 0.1}``; values that are not JSON stay strings."""
    out: dict[str, Any] = {}
    for item in items:
        key, sep, raw = item.partition("=")
        if not sep or not key:
            msg = f"{flag} {item!r}: expected KEY=VALUE"
            raise ParameterError(msg)
        try:
            out[key] = json.loads(raw)
        except json.JSONDecodeError:
            out[key] = raw
    return out


def _k(text: str) -> int | str:
    if text == "auto":
        return text
    try:
        k = int(text)
    except ValueError:
        msg = f"--k takes 'auto' or a positive integer, not {text!r}"
        raise argparse.ArgumentTypeError(msg) from None
    if k < 1:
        msg = f"--k must be at least 1, not {k}"
        raise argparse.ArgumentTypeError(msg)
    return k


DEFAULT_ARCHIVE = Path("data/recordings")


def demo_arguments(parser: argparse.ArgumentParser) -> None:
    """Arguments of ``pbd demo``."""
    parser.add_argument("--samples", type=Path, default=Path("data/recordings"), help="folder of the sample recordings")
    parser.add_argument("--workers", type=int, default=2, metavar="N", help="recordings in flight at once")
    parser.add_argument("--json", action="store_true", help="print the run summary as JSON on stdout")


def synth_arguments(parser: argparse.ArgumentParser) -> None:
    """Arguments of ``pbd synth``."""
    parser.add_argument("scene", metavar="SCENE", help="built-in scene name")
    parser.add_argument(
        "--out", type=Path, required=True, metavar="PATH", help="recording to write (never overwritten)"
    )
    parser.add_argument(
        "--format", default="mcap", metavar="FORMAT", help="mcap (default), bag or rosbag2 (PATH is then a folder)"
    )
    parser.add_argument(
        "--seed", type=int, default=None, metavar="N", help="randomised instance (placement, sizes, pace, sensors)"
    )
    parser.add_argument("--json", action="store_true", help="print the result as JSON on stdout")


def ingest_arguments(parser: argparse.ArgumentParser) -> None:
    """Arguments of ``pbd ingest``."""
    parser.add_argument("recordings", nargs="+", type=Path, metavar="RECORDING", help=".mcap, .bag or rosbag2 folder")
    parser.add_argument("--topics", type=Path, metavar="MAP", help="topic map YAML overriding role detection")
    parser.add_argument(
        "--recover",
        action="store_true",
        help="keep the intact messages of a truncated or damaged MCAP, bag or rosbag2 (warns what was lost)",
    )
    parser.add_argument(
        "--object-model", type=Path, metavar="FILE", help="object model .ply/.pcd/.obj/.stl (world frame)"
    )
    parser.add_argument("--json", action="store_true", help="print the result as JSON on stdout")


def learn_arguments(parser: argparse.ArgumentParser) -> None:
    """Arguments of ``pbd learn``."""
    parser.add_argument("recording", metavar="RECORDING", help="recording file or folder, or an ingested recording id")
    parser.add_argument("--k", type=_k, default="auto", help="number of segments for --segmenter spectral (or auto)")
    parser.add_argument("--t0", type=float, default=0.05, help="eq. (3) threshold T0 for --classifier eigen")
    parser.add_argument("--segmenter", choices=("changepoint", "spectral"), default="changepoint")
    parser.add_argument("--classifier", choices=("bic", "eigen"), default="bic")
    parser.add_argument("--object-model", type=Path, default=None, help="object model file (.ply .pcd .obj .stl)")
    parser.add_argument("--name", default=None, help="descriptor name (default <action>-<object> from the meta)")
    parser.add_argument("--out", type=Path, default=None, help="also write the descriptor JSON here (never overwrites)")
    parser.add_argument("--topics", type=Path, default=None, help="topic map YAML for ingest")
    parser.add_argument("--seed", type=int, default=0, help="seed for k-means and the grasp planner")
    parser.add_argument("--json", action="store_true", help="print the result as JSON on stdout")


def transfer_arguments(parser: argparse.ArgumentParser) -> None:
    """Arguments of ``pbd transfer``."""
    parser.add_argument("descriptor", metavar="DESCRIPTOR", help="file, content id (8+ hex) or name@vN / name@latest")
    parser.add_argument(
        "--to",
        dest="model",
        metavar="MODEL",
        required=True,
        help="target model: PLY, PCD, XYZ, OBJ, STL, OFF, Parquet, npy; or a recording id / file with an object model",
    )
    parser.add_argument("--out", metavar="FILE", default=None, help="also write the transferred descriptor to FILE")
    parser.add_argument("--name", metavar="NAME", default=None, help="descriptor name (default <source>-to-<model>)")
    parser.add_argument("--whole", action="store_true", help="align the whole model, not only its functional part")
    parser.add_argument("--crop-radius", metavar="M", type=float, default=None, help="functional region radius (m)")
    parser.add_argument("--strict", action="store_true", help="a poor registration is an error (exit 2)")
    parser.add_argument("--replan-grasp", action="store_true", help="re-plan the grasp on the target model")
    parser.add_argument("--seed", metavar="N", type=int, default=0, help="random seed (default 0)")
    parser.add_argument("--json", action="store_true", help="print the result as JSON on stdout")


def simulate_arguments(parser: argparse.ArgumentParser) -> None:
    """Arguments of ``pbd simulate``."""
    parser.add_argument("descriptor", metavar="DESCRIPTOR", help="file path, content id (8+ hex) or name@vN|latest")
    where = parser.add_mutually_exclusive_group()
    where.add_argument("--scene", metavar="NAME", help="built-in scene (default: the descriptor's object name)")
    where.add_argument("--urdf", type=Path, metavar="FILE", help="your own articulated object (fixed base at origin)")
    parser.add_argument(
        "--joints", metavar="J1,J2", help="with --urdf: the joints the chain may drive, comma-separated"
    )
    parser.add_argument(
        "--seed", type=int, default=None, help="randomised scene instance (default: the one it was learned on)"
    )
    parser.add_argument("--frames", type=Path, metavar="DIR", help="write key frames (PNG) into DIR")
    parser.add_argument(
        "--grasp",
        choices=("constraint", "friction"),
        default="constraint",
        help="hold the part by a fixed palm constraint once the fingers close (default) or by friction alone",
    )
    parser.add_argument("--json", action="store_true", help="machine-readable result on stdout")


def diff_arguments(parser: argparse.ArgumentParser) -> None:
    """Arguments of ``pbd diff``."""
    parser.add_argument(
        "a", metavar="A", help="descriptor (file, content id, name@vN, name@latest), or a NAME: its last two versions"
    )
    parser.add_argument("b", metavar="B", nargs="?", default=None, help="descriptor to compare with A")
    parser.add_argument("--json", action="store_true", help="print the diff as JSON on stdout")


def ls_arguments(parser: argparse.ArgumentParser) -> None:
    """Arguments of ``pbd ls``."""
    parser.add_argument("name", metavar="NAME", nargs="?", default=None, help="list this descriptor's versions")
    parser.add_argument("--json", action="store_true", help="print the listing as JSON on stdout")


def archive_arguments(parser: argparse.ArgumentParser) -> None:
    """Arguments of ``pbd archive``."""
    parser.add_argument("dir", type=Path, help="folder of recordings (*.mcap, *.bag, rosbag2 folders)")
    parser.add_argument("--address", metavar="tcp://HOST:PORT", help="run the tasks on this Dask scheduler")
    parser.add_argument("--workers", type=int, default=2, metavar="N", help="recordings in flight at once")
    parser.add_argument("--seed", type=int, default=0, help="seed of the grasp planner's random generator")
    add_param_argument(parser)
    add_grasp_param_argument(parser)
    parser.add_argument("--no-report", action="store_true", help="skip the HTML report")
    parser.add_argument("--json", action="store_true", help="print the run summary as JSON on stdout")


def serve_arguments(parser: argparse.ArgumentParser) -> None:
    """Arguments of ``pbd serve``."""
    parser.add_argument(
        "--archive", type=Path, default=DEFAULT_ARCHIVE, help="default archive folder of the nightly run"
    )
    parser.add_argument("--cron", default="0 3 * * *", help="schedule of the nightly run (default 03:00 UTC)")
    parser.add_argument("--workers", type=int, default=2, help="recordings in flight per archive run")
    parser.add_argument("--limit", type=int, default=2, help="flow runs executed at once by this server")
    parser.add_argument(
        "--address", metavar="tcp://HOST:PORT", help="default Dask scheduler of the nightly run's tasks"
    )


ARGUMENTS: dict[str, Callable[[argparse.ArgumentParser], None]] = {
    "demo": demo_arguments,
    "synth": synth_arguments,
    "ingest": ingest_arguments,
    "learn": learn_arguments,
    "transfer": transfer_arguments,
    "simulate": simulate_arguments,
    "diff": diff_arguments,
    "ls": ls_arguments,
    "archive": archive_arguments,
    "serve": serve_arguments,
}
"""Each command's arguments by name (the command's ``run`` is in ``flows.commands.<name>``)."""
