"""``pbd simulate DESCRIPTOR [--scene NAME | --urdf FILE [--joints J1,J2]] [--json] [--seed N] [--frames DIR]``.

Executes the descriptor in pybullet (DIRECT, software renderer) and prints, per primitive, the demonstrated
extent, the joint motion achieved, contact and time, then success. ``--json`` prints one JSON document on stdout
alone. Without ``--scene``, ``--urdf`` or ``--seed`` the descriptor runs in the built-in scene instance it was
learned on (its provenance's ``scene``, else its recording's meta), else on the nominal scene named like its object.
Exit 0 when executed (success or not is in the output), 2 for bad input.
"""

from __future__ import annotations

import argparse
import json
import math
import sys
from typing import TYPE_CHECKING

import numpy as np

from tasks.errors import SimulationError
from tasks.simulate.api import simulate_descriptor
from tasks.simulate.instance import descriptor_instance, recording_meta
from tasks.store import Store, resolve_store_root

if TYPE_CHECKING:
    from tasks.simulate.result import SimulationResult


def _text(result: SimulationResult) -> str:
    """The human-readable report: one line per primitive, then grasp, contact, time and success."""
    lines = [f"scene {result.scene}  descriptor {result.descriptor_id[:12]}"]
    lines.append(
        f"{'#':>2} {'kind':<11} {'joint':<16} {'target':>9} {'achieved':>9} {'%':>5} {'contact':>8} "
        f"{'time s':>7}  stopped"
    )
    for p in result.primitives:
        scale, unit = (180.0 / math.pi, "°") if p.kind == "rotation" else (100.0, "cm")
        lines.append(
            f"{p.index:>2} {p.kind:<11} {p.joint:<16} {p.target * scale:>7.1f}{unit:<2} {p.achieved * scale:>7.1f}"
            f"{unit:<2}{100 * p.fraction:>5.0f} {100 * p.contact_fraction:>7.0f}% {p.sim_time_s:>7.2f}  {p.stopped}"
            f"{'' if p.success else '  (failed)'}"
        )
    lines.append(
        f"grasped {'yes' if result.grasped else 'no'}  contact kept {'yes' if result.contact_kept else 'no'} "
        f"({100 * result.contact_fraction:.0f}%)  grasp held by {result.grasp_mode}"
    )
    lines.append(
        f"simulated {result.sim_time_s:.2f} s in {result.wall_time_s:.2f} s wall "
        f"({result.real_time_factor:.0f}x real time)"
    )
    lines += [f"note: {note}" for note in result.notes]
    lines += [f"frame: {frame}" for frame in result.frames]
    lines.append(f"success: {'yes' if result.success else 'no'}")
    return "\n".join(lines) + "\n"


def run(args: argparse.Namespace) -> int:
    """Load the descriptor, run the simulation, print the result; exit 0 once executed."""

    if args.joints and args.urdf is None:
        msg = "--joints needs --urdf"
        raise SimulationError(msg)
    store = Store(resolve_store_root(args.store))
    desc = store.load(args.descriptor)
    joints = [j.strip() for j in args.joints.split(",") if j.strip()] if args.joints else None
    scene, seed = args.scene, args.seed
    if scene is None and seed is None and args.urdf is None:  # the scene instance the descriptor was learned on
        rec_id = desc.recording_id
        meta = recording_meta(store.recording_dir(rec_id)) if rec_id and store.has_recording(rec_id) else None
        scene, seed = descriptor_instance(desc.extra_provenance, meta)
    rng = np.random.default_rng(seed) if seed is not None else None
    result = simulate_descriptor(
        desc, scene=scene, urdf=args.urdf, joints=joints, rng=rng, frames_dir=args.frames, grasp_mode=args.grasp
    )
    if args.json:
        sys.stdout.write(json.dumps(result.to_dict(), indent=2, sort_keys=True) + "\n")
    else:
        sys.stdout.write(_text(result))
    return 0
