"""Do the built-in scenes' truth descriptors execute in simulation? Success rate per scene over seeds.

Each instance: ``build_scene(name, seed)`` (seed None = nominal, then 0..N-1), its truth descriptor
(``tasks.scenes.kinematics.truth_descriptor``: the true chain and the demonstrated grasp), executed with
``tasks.simulate.api.simulate_descriptor`` in that same instance (``scene_setup_for``), palm constraint grasp.

    .venv/bin/python bench/scenes_truth.py [--seeds N] [--scenes microwave,door] [--verbose]
"""

from __future__ import annotations

import argparse
import time

from tasks.errors import PbdError
from tasks.scenes.catalog import SCENE_NAMES, build_scene
from tasks.scenes.kinematics import truth_descriptor
from tasks.simulate.execute import execute
from tasks.simulate.scenes import scene_setup_for


def run(name: str, seed: int | None) -> tuple[bool, str]:
    """Execute one instance's truth descriptor; (success, one-line detail)."""
    scene = build_scene(name, seed)
    desc = truth_descriptor(scene)
    try:
        result = execute(desc, scene_setup_for(scene))
    except PbdError as err:
        return False, f"error: {err}"
    detail = ", ".join(f"{p.joint} {p.achieved:.3f}/{p.target:.3f} {p.stopped}" for p in result.primitives)
    return result.success, f"{detail}; grasped {result.grasped}; contact {result.contact_fraction:.0%}"


def main(argv: list[str] | None = None) -> int:
    """Run the instances and print the success table."""
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--seeds", type=int, default=20, help="randomised instances per scene (plus the nominal)")
    parser.add_argument("--first-seed", type=int, default=0)
    parser.add_argument("--scenes", default=",".join(SCENE_NAMES))
    parser.add_argument("--verbose", action="store_true")
    args = parser.parse_args(argv)
    rows = []
    for name in args.scenes.split(","):
        t0 = time.perf_counter()
        ok = 0
        seeds: list[int | None] = [None, *range(args.first_seed, args.first_seed + args.seeds)]
        failed: list[str] = []
        for seed in seeds:
            success, detail = run(name, seed)
            ok += int(success)
            line = f"{name:<13} seed {seed!s:<5} {'ok  ' if success else 'FAIL'} {detail}"
            if args.verbose:
                print(line, flush=True)
            if not success:
                failed.append(line)
        rows.append((name, ok, len(seeds), time.perf_counter() - t0, failed))
    print("\nscene         | truth descriptor succeeds | seconds")
    print("--------------+---------------------------+--------")
    for name, ok, n, secs, _ in rows:
        print(f"{name:<13} | {ok:>3}/{n:<3} ({ok / n:6.1%})          | {secs:6.0f}")
    for *_, failed in rows:
        for line in failed:
            print(line)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
