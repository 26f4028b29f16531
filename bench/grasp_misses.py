"""Why a planned grasp the benchmark drops was dropped: the planner's model, or the benchmark's program?

For each object of ``bench/grasp.py``'s seeds whose plan the benchmark's hold test drops, the plan is shaken six
or seven ways and a line printed (``H`` holds, ``-`` drops; then the part's largest shift in mm and turn in degrees):

- the planner's check (``shake.hold_check``) on its own model and on the object's exact shapes;
- the benchmark's program (``cases.grasp.hold_program``) on the model and on the exact shapes;
- on the model, the benchmark's gravity phases without their shakes, and its first phase (gravity down) alone;
- on the model, the check with three cycles of each motion, as the benchmark has (``--cycles``);
- when the model has a bar or cap, the check on the model with it colliding as its 64-sided prism, as the exact
  shapes' bars do, not as Bullet's round cylinder.

Each dropped object then falls in one class: **no firm grasp** (the plan did not hold within half the check's
tolerances: the budget ran out first), **model** (the check on the exact shapes drops it: the model lacks a detail
that decides the hold), **program** (the check holds on both, the benchmark's program drops it on the model too),
or **exact shapes only** (the benchmark holds it on the model, not on the exact shapes, which the check holds).
Counts per class and kind close the run, with how many of each class have a bar or cap and drop on its prism.

Only development seeds are taken (seed 7 and ``--seeds A-B``); the held-out seeds are refused, since what this
finds steers changes.

    OMP_NUM_THREADS=1 .venv/bin/python bench/grasp_misses.py [--seeds A-B] [--rows SEED:ROW ...] [--cycles N]
"""

from __future__ import annotations

import argparse
import dataclasses
import functools
import math
import sys
from collections import Counter
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from bench.grasp import DEVELOPMENT_SEED, HELD_OUT_SEEDS, _seed_range
from tasks.grasp.api import firm, plan_on_model
from tasks.grasp.execution import grasp_from_candidate
from tasks.grasp.shake import ShakeResult, hold_check, shake_test
from tests.grasp.cases.bench import row_setup, seed_cases

CLASSES = ("no firm grasp", "model", "program", "exact shapes only")

cases = functools.cache(seed_cases)
"""A seed's objects, drawn once per run."""


def mark(result: ShakeResult) -> str:
    """``H`` or ``-``, the largest shift (mm) and turn (degrees)."""
    shift, turn = 1000.0 * result.max_shift_m, math.degrees(result.max_turn_rad)
    return f"{'H' if result.holds else '-'} {shift:5.1f}/{turn:5.1f}"


def diagnose(seed: int, index: int, cycles: float) -> tuple[str, str, bool | None] | None:
    """The line and class of one object and whether the check drops its plan on the prism (None without a bar or
    cap), or None when the benchmark holds its plan."""
    case = cases(seed)[index][1]
    model, truth, program = row_setup(case, seed, index)
    plan = plan_on_model(model, case.seed_pos, case.seed_quat, np.random.default_rng(seed))
    grasp = grasp_from_candidate(plan)
    bench_truth = shake_test(truth, grasp, program)
    if bench_truth.holds:
        return None
    check = hold_check(plan.quat_xyzw)
    longer = dataclasses.replace(check, motions=tuple(dataclasses.replace(m, cycles=cycles) for m in check.motions))
    check_model, check_truth = shake_test(model, grasp, check), shake_test(truth, grasp, check)
    bench_model = shake_test(model, grasp, program)
    tilts_only = shake_test(model, grasp, dataclasses.replace(program, motions=()))
    down_only = shake_test(model, grasp, dataclasses.replace(program, gravity=program.gravity[:1]))
    longer_model = shake_test(model, grasp, longer)
    prism = None  # the bar or cap as the exact shapes' prism
    if model.cylinder is not None:
        prism = shake_test(dataclasses.replace(model, cylinder=None), grasp, check)
    if not (check_model.holds and firm(check_model)):
        kind = CLASSES[0]
    elif not check_truth.holds:
        kind = CLASSES[1]
    elif not bench_model.holds:
        kind = CLASSES[2]
    else:
        kind = CLASSES[3]
    line = (
        f"{seed:4d} {index:2d} {case.name[:26]:26s} {plan.source:13s} check: model {mark(check_model)}"
        f" exact {mark(check_truth)} | benchmark: model {mark(bench_model)} exact {mark(bench_truth)}"
        f" | model: tilts only {mark(tilts_only)} down only {mark(down_only)} check x{cycles:g} {mark(longer_model)}"
        f" prism {'none' if prism is None else mark(prism):13s}"
        f" | {kind}"
    )
    return line, kind, None if prism is None else not prism.holds


def main() -> None:
    """Diagnose the dropped plans of the chosen development objects, a line each, then the counts."""
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--seeds", type=_seed_range, default=range(DEVELOPMENT_SEED, DEVELOPMENT_SEED + 1))
    parser.add_argument("--rows", nargs="*", default=None, help="SEED:ROW objects instead of whole seeds")
    parser.add_argument("--cycles", type=float, default=3.0, help="cycles of each motion in the longer check")
    args = parser.parse_args()
    try:
        rows = [(int(r.split(":")[0]), int(r.split(":")[1])) for r in args.rows or ()]
    except (ValueError, IndexError):
        parser.error(f"--rows takes SEED:ROW, got {' '.join(args.rows)}")
    rows = rows or [(s, i) for s in args.seeds for i in range(len(cases(s)))]
    if held := sorted({s for s, _ in rows} & set(HELD_OUT_SEEDS)):
        parser.error(f"held-out seeds {held} are only reported by bench/grasp.py, not diagnosed")
    counts: Counter[str] = Counter()
    kinds: Counter[tuple[str, str]] = Counter()
    prism: Counter[tuple[str, bool]] = Counter()  # per class: plans with a bar or cap, and those the prism drops
    for seed, index in rows:
        found = diagnose(seed, index, args.cycles)
        if found is None:
            continue
        line, kind, prism_drops = found
        if prism_drops is not None:
            prism[kind, False] += 1
            prism[kind, True] += prism_drops
        print(line, flush=True)
        counts[kind] += 1
        kinds[kind, cases(seed)[index][1].name.split()[0]] += 1
    print(f"\n== {sum(counts.values())} dropped plans of {len(rows)} objects")
    for kind in CLASSES:
        per = ", ".join(f"{k} {n}" for (c, k), n in kinds.most_common() if c == kind)
        bars = f"; with a bar or cap {prism[kind, False]}, the check drops {prism[kind, True]} on its prism"
        print(f"{kind:18s} {counts[kind]:4d}  {per}{bars}")


if __name__ == "__main__":
    main()
