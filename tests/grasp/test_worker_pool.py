"""The planner's worker processes (``worker_pool.py``): calls run in another process and give what they give here;
a plan made with them is the plan one process makes, candidate for candidate and check for check."""

from __future__ import annotations

import multiprocessing
import os
import time
from pathlib import Path

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from tasks.arrays import FloatArray
from tasks.errors import GraspError
from tasks.grasp import worker_pool
from tasks.grasp.anneal import Schedule, annealing_draws
from tasks.grasp.api import part_near, plan_on_model
from tasks.grasp.hold_budget import HoldBudget
from tasks.grasp.object_model import ObjectModel, build_object_model
from tasks.grasp.planner import (
    ApproachSpace,
    GraspCandidate,
    PlannerParams,
    SearchBox,
    anneal_chains,
    execute_states,
    executing,
    pivot_distance,
    search,
)
from tasks.grasp.worker_pool import PROCESSES_ENV, Beside
from tests.grasp.cases.grasp import scene_cases

SEED = 7
"""``bench/grasp.py``'s first seed."""


def _pid() -> int:
    """The process this runs in."""
    return os.getpid()


def _fails(message: str) -> None:
    """Raise ``message``."""
    raise ValueError(message)


def _exit_if_elsewhere(planner_pid: int) -> int:
    """42 in the planner's process; in a worker, end the worker."""
    if os.getpid() != planner_pid:
        os._exit(3)  # the worker dies mid-call, as a killed one would
    return 42


@pytest.fixture(scope="module")
def microwave() -> tuple[ObjectModel, FloatArray, FloatArray]:
    """The benchmark's microwave (scene seed 0) as ``bench/grasp.py`` models it: model, palm position, quaternion."""
    case = scene_cases(range(1))[0]
    part = part_near(case.points, case.seed_pos)
    approach = Rotation.from_quat(case.seed_quat).as_matrix()[:, 2]
    model = build_object_model(part, np.random.default_rng(SEED), viewpoint=case.seed_pos, approach=approach)
    return model, np.asarray(case.seed_pos, dtype=np.float64), np.asarray(case.seed_quat, dtype=np.float64)


def _same(a: list[GraspCandidate], b: list[GraspCandidate]) -> None:
    assert len(a) == len(b)
    for x, y in zip(a, b, strict=True):
        np.testing.assert_array_equal(x.position, y.position)
        np.testing.assert_array_equal(x.quat_xyzw, y.quat_xyzw)
        np.testing.assert_array_equal(x.closed, y.closed)
        assert x.quality == y.quality
        assert x.energy == y.energy


def test_calls_run_in_a_worker_unless_one_process_is_asked_for(monkeypatch: pytest.MonkeyPatch) -> None:
    """With two cores a call runs in another process; ``PBD_GRASP_PROCESSES=1`` keeps it in this one."""
    monkeypatch.setenv(PROCESSES_ENV, "2")
    assert worker_pool.workers() == 2
    assert Beside(_pid).result() != os.getpid()
    monkeypatch.setenv(PROCESSES_ENV, "1")
    assert worker_pool.workers() == 0
    assert Beside(_pid).result() == os.getpid()
    monkeypatch.setenv(PROCESSES_ENV, "4")
    assert worker_pool.workers() == worker_pool.MAX_WORKERS


def test_a_count_that_is_no_number_is_refused(monkeypatch: pytest.MonkeyPatch) -> None:
    """``PBD_GRASP_PROCESSES=many`` is an error that names the variable and the value, not a silent default."""
    monkeypatch.setenv(PROCESSES_ENV, "many")
    with pytest.raises(GraspError, match=r"PBD_GRASP_PROCESSES must be a whole number .*got 'many'"):
        worker_pool.workers()


def test_a_call_raises_where_its_result_is_asked_for(monkeypatch: pytest.MonkeyPatch) -> None:
    """An exception in a worker is raised by ``result``, as the call made here would raise it."""
    monkeypatch.setenv(PROCESSES_ENV, "2")
    failing = Beside(_fails, "bad pose")
    with pytest.raises(ValueError, match="bad pose"):
        failing.result()


def test_work_of_a_dead_worker_is_done_here(monkeypatch: pytest.MonkeyPatch) -> None:
    """A worker that dies mid-call leaves its call to this process, and the next call starts new workers."""
    monkeypatch.setenv(PROCESSES_ENV, "2")
    assert Beside(_exit_if_elsewhere, os.getpid()).result() == 42
    assert Beside(_pid).result() != os.getpid()


def test_executions_in_parts_are_those_of_one_execution(
    microwave: tuple[ObjectModel, FloatArray, FloatArray], monkeypatch: pytest.MonkeyPatch
) -> None:
    """Poses on the demonstrated approach executed in two workers give the candidates, in order, that one pybullet
    client executing them all gives."""
    monkeypatch.setenv(PROCESSES_ENV, "2")
    model, pos, quat = microwave
    rot = Rotation.from_quat(quat).as_matrix()
    space = ApproachSpace(rot, pos, pivot_distance(model, rot, pos, 0.2))
    picks = [(np.array([a1, 0.0, space.pivot_m + back, 0.0, 0.0]), 0.0) for a1 in (-1.13, 0.0) for back in (0, 0.02)]
    parts = executing(model, space, picks, PlannerParams())
    assert len(parts) == 2
    in_parts = [cand for part in parts for cand in part.result()]
    assert len(in_parts) >= 2
    _same(in_parts, execute_states(model, space, picks, PlannerParams()))


def test_chains_annealed_in_a_worker_are_those_annealed_here(
    microwave: tuple[ObjectModel, FloatArray, FloatArray], monkeypatch: pytest.MonkeyPatch
) -> None:
    """Annealing chains, each with its block of uniforms, in a worker and in this process, together or one by one:
    the same states and energies, bit for bit (a chain's course depends on its start and its block alone)."""
    monkeypatch.setenv(PROCESSES_ENV, "2")
    model, pos, quat = microwave
    rot = Rotation.from_quat(quat).as_matrix()
    space = ApproachSpace(rot, pos, pivot_distance(model, rot, pos, 0.2))
    upper = np.array([4.0, 4.0, 0.2, 0.4, 0.4])
    lower = np.array([-4.0, -4.0, -0.03, -0.4, -0.4])
    box = SearchBox(lower, upper)
    rng = np.random.default_rng(SEED)
    chains = [(np.array([a1, -1.0, 0.05, 0.0, 0.0]), annealing_draws(rng, 60, 5)) for a1 in (-1.13, 0.87)]
    here = anneal_chains(model, space, box, chains, Schedule())
    beside = Beside(anneal_chains, model, space, box, chains[1:], Schedule()).result()
    assert len(here) == 2
    assert len(beside) == 1
    np.testing.assert_array_equal(beside[0].states, here[1].states)
    np.testing.assert_array_equal(beside[0].energies, here[1].energies)
    assert beside[0].accepted == here[1].accepted > 0
    assert not np.array_equal(here[0].states[1:], here[1].states[1:])


def test_search_and_checks_with_workers_are_those_of_one_process(
    microwave: tuple[ObjectModel, FloatArray, FloatArray], monkeypatch: pytest.MonkeyPatch
) -> None:
    """The benchmark's microwave searched (a short search: 100 annealing steps, 6 candidates) with two workers and
    in one process: the same candidates, and the same hold checks spent (count and simulated seconds) when checking
    three of them."""
    model, pos, quat = microwave
    short = PlannerParams(steps=100, candidates=6)
    searched, budgets = [], []
    for processes in ("2", "1"):
        monkeypatch.setenv(PROCESSES_ENV, processes)
        found = search(model, Rotation.from_quat(quat).as_matrix(), pos, np.random.default_rng(SEED), short)
        searched.append(found)
        budget = HoldBudget(3)
        held = budget.first_that_holds([(c, model) for c in found[1:]], 3)
        budgets.append((budget.left, budget.seconds, budget.longest_s, held is None))
    _same(searched[0], searched[1])
    assert budgets[0] == budgets[1]
    assert budgets[0][0] < 3  # checks were run


@pytest.mark.slow
def test_a_plan_with_workers_is_the_plan_of_one_process(
    microwave: tuple[ObjectModel, FloatArray, FloatArray], monkeypatch: pytest.MonkeyPatch
) -> None:
    """The benchmark's microwave planned with two workers and in one process: the same grasp."""
    model, pos, quat = microwave
    plans = []
    for processes in ("2", "1"):
        monkeypatch.setenv(PROCESSES_ENV, processes)
        plans.append(plan_on_model(model, pos, quat, np.random.default_rng(SEED)))
    _same(plans[:1], plans[1:])


def _write_later(folder: str) -> None:
    """Write ``started`` in ``folder``, and ``ended`` 0.3 s later."""
    (Path(folder) / "started").write_text("")
    time.sleep(0.3)
    (Path(folder) / "ended").write_text("")


def test_wait_idle_waits_for_dropped_calls(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    """A call whose result was dropped after it started still runs to its end, and ``wait_idle`` waits for it."""
    monkeypatch.setenv(PROCESSES_ENV, "2")
    running = Beside(_write_later, str(tmp_path))
    for _ in range(1000):
        if (tmp_path / "started").exists():
            break
        time.sleep(0.01)
    running.drop()
    worker_pool.wait_idle()
    assert (tmp_path / "ended").exists()


def _plan_in_a_child() -> None:
    """Plan from a process that multiprocessing started (as ``bench/simulate.py``'s workers learn): in it."""
    os.environ[PROCESSES_ENV] = "2"
    assert worker_pool.workers() == 0
    assert Beside(_pid).result() == os.getpid()


def test_a_process_multiprocessing_started_plans_alone_and_ends() -> None:
    """A multiprocessing child leaves by ``os._exit`` after joining its children, without ``atexit``: it starts no
    workers of its own, and it ends."""
    child = multiprocessing.get_context("spawn").Process(target=_plan_in_a_child)
    child.start()
    child.join(timeout=60)
    ended = child.exitcode is not None
    if not ended:
        child.kill()
        child.join()
    assert ended
    assert child.exitcode == 0
