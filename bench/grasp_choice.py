"""Where the grasp planner loses holds: in the candidates it proposes, or in the check that chooses among them.

For each object of ``bench/grasp.py``'s seeds: the planner's ranked grasps are taken in rank order, those that
survive the wrist error (``execution.robust``) up to ``--candidates`` of them, and each is judged twice: by the
planner's own hold check on its model (``shake.hold_check``: firm, moved at most half its tolerances; held; or
failed) and by the benchmark's hold test on the object's exact shapes (a line per object: ``F+`` a firm grasp
that holds under the benchmark, ``h-`` one that held in the check and drops, ``x`` failed the check). Printed
per part:

- **a holding grasp proposed**: objects where at least one of those grasps holds under the benchmark (what a
  perfect choice among them would reach);
- **the plan holds**: the plan ``api.plan_on_model`` returns (its budget and ranking), judged by the benchmark;
- per verdict of the check, how many of its grasps hold under the benchmark (what the check's verdict predicts).

The **development** part is seed 7 (``--extra-seeds A-B`` adds further development seeds); the **held-out** part
(``bench/grasp.py``'s held-out seeds) is only reported.

    OMP_NUM_THREADS=1 .venv/bin/python bench/grasp_choice.py [--part development|held-out|all] [--extra-seeds A-B]
        [--candidates N] [--quick]
"""

from __future__ import annotations

import argparse
import sys
from collections import Counter
from dataclasses import dataclass
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from bench.grasp import DEVELOPMENT_SEED, HELD_OUT_SEEDS, _seed_range
from tasks.grasp.api import check_hold, choose, firm, ranked_grasps
from tasks.grasp.execution import grasp_from_candidate, hand_and_object, robust
from tasks.grasp.planner import PlannerParams
from tasks.grasp.shake import ShakeResult, shake_test
from tests.grasp.cases.bench import row_setup, seed_cases

VERDICTS = ("firm", "held", "failed")
MARKS = {"firm": "F", "held": "h", "failed": "x"}
"""An object's line marks each judged grasp with its check's verdict and + or - for the benchmark's."""


@dataclass(frozen=True)
class ObjectChoice:
    """One object: the check's verdict and the benchmark's for each judged grasp (rank order), and whether the
    plan holds under the benchmark."""

    name: str
    judged: tuple[tuple[str, bool], ...]
    plan_holds: bool


def verdict(check: ShakeResult) -> str:
    """``firm``, ``held`` or ``failed``: the planner's check of one grasp, as ``api.choose`` reads it."""
    return ("firm" if firm(check) else "held") if check.holds else "failed"


def judge_object(seed: int, index: int, count: int, quick: bool) -> ObjectChoice:
    """Plan one object of benchmark seed ``seed`` and judge its first ``count`` robust grasps both ways."""
    case = seed_cases(seed, quick)[index][1]
    model, truth, program = row_setup(case, seed, index)
    prm = PlannerParams()
    rng = np.random.default_rng(seed)  # as plan_on_model draws it, so the ranked grasps are the plan's
    ranked = ranked_grasps(model, case.seed_pos, case.seed_quat, rng, prm)
    if not ranked:
        return ObjectChoice(case.name, (), False)
    judged: list[tuple[str, bool]] = []
    with hand_and_object(model) as ids:
        for cand in ranked:
            if len(judged) >= count:
                break
            if not robust(ids, model, cand, prm.mu):
                continue
            check, quality = check_hold(model, cand, prm.mu)
            bench_holds = shake_test(truth, grasp_from_candidate(cand), program).holds
            judged.append((verdict(check) if quality.force_closure else "failed", bench_holds))
    plan = choose(model, ranked, prm)
    return ObjectChoice(case.name, tuple(judged), shake_test(truth, grasp_from_candidate(plan), program).holds)


def run_part(seeds: list[int], args: argparse.Namespace, title: str) -> None:
    """Judge every object of ``seeds`` (a line each) and print the part's summary."""
    objects: list[ObjectChoice] = []
    count = args.candidates
    for seed in seeds:
        for index in range(len(seed_cases(seed, args.quick))):
            obj = judge_object(seed, index, count, args.quick)
            objects.append(obj)
            marks = " ".join(f"{MARKS[v]}{'+' if b else '-'}" for v, b in obj.judged)
            print(f"{seed} {index:2d} {obj.name:38s} plan holds={obj.plan_holds!s:5s} | {marks}", flush=True)
    n = len(objects)
    proposed = sum(any(b for _, b in o.judged) for o in objects)
    print(f"\n== {title}: {n} objects, the first {count} grasps that survive the wrist error")
    print(f"{'a holding grasp proposed (a perfect choice)':48s} {proposed}/{n} ({proposed / max(n, 1):.0%})")
    planned = sum(o.plan_holds for o in objects)
    print(f"{'the plan holds':48s} {planned}/{n} ({planned / max(n, 1):.0%})")
    tally = Counter((v, b) for o in objects for v, b in o.judged)
    for v in VERDICTS:
        total = tally[v, True] + tally[v, False]
        print(f"{'check says ' + v + ': hold under the benchmark':48s} {tally[v, True]}/{total}")


def main() -> int:
    """Run the development part, and the held-out part when asked (reported only)."""
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--part", choices=("development", "held-out", "all"), default="development")
    parser.add_argument("--extra-seeds", type=_seed_range, metavar="A-B", help="further development seeds")
    parser.add_argument("--candidates", type=int, default=10, help="grasps judged per object (default 10)")
    parser.add_argument("--quick", action="store_true", help="6 randomised and 10 family objects per seed")
    args = parser.parse_args()
    extra = list(args.extra_seeds or ())
    if held := sorted(set(extra) & set(HELD_OUT_SEEDS)):
        parser.error(f"--extra-seeds: {held} are held out")
    if args.part in {"development", "all"}:
        seeds = [DEVELOPMENT_SEED, *extra]
        run_part(seeds, args, "development, seeds " + " ".join(map(str, seeds)))
    if args.part in {"held-out", "all"}:
        run_part(list(HELD_OUT_SEEDS), args, "held out, seeds " + " ".join(map(str, HELD_OUT_SEEDS)))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
