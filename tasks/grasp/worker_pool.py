"""Processes beside the planner, for pybullet work whose result does not depend on where it runs.

A plan's hold checks (``shake.shake_test``) and its executions of candidate poses (``planner.execute_states``) each
build a pybullet client of their own, so they give the same result in any process. The planner sends them to
``workers()`` processes (one per core, two at most) and uses the results in the order a single process would:
``hold_budget.HoldBudget.first_that_holds`` checks the next candidates while the current one is being checked,
``planner.search`` executes the poses on the demonstrated approach and anneals half of its chains (each with its own
block of random draws) in the workers while it anneals the other half, and splits the annealed poses between the
processes; ``settle.settled_wraps`` settles its candidates side by side. Every plan is the one a single process
makes; a result not needed is dropped.

The processes are started on first use, or by ``start`` (``tasks.learn.api.learn_descriptor`` starts them before
it segments: about 1 s of CPU each to import pybullet, numpy and scipy), and kept for the life of the planner's.
With ``PBD_GRASP_PROCESSES=1`` in the environment, or on a machine with one core, everything runs in the planner's
process. If a process dies, its work is done in the planner's.
"""

from __future__ import annotations

import atexit
import concurrent.futures
import importlib
import multiprocessing
import os
import threading
from collections.abc import Callable
from concurrent.futures.process import BrokenProcessPool
from typing import Generic, ParamSpec, TypeVar

from tasks.errors import GraspError
from tasks.quiet_import import quiet_import

PROCESSES_ENV = "PBD_GRASP_PROCESSES"
"""Environment variable: how many processes a plan's pybullet work may use (``1``: the planner's alone)."""
MAX_WORKERS = 2
"""Processes beside the planner at most: the planner is meant for 2 cores, and it waits while they work."""

P = ParamSpec("P")
T = TypeVar("T")

_pool: concurrent.futures.ProcessPoolExecutor | None = None
_starting = threading.Lock()
_running = 0
"""Calls sent to the workers and not yet ended (``wait_idle``), guarded by ``_ended``."""
_ended = threading.Condition()


def workers() -> int:
    """How many processes take the planner's work: ``PBD_GRASP_PROCESSES`` (default: the cores, at most
    ``MAX_WORKERS``); 0 when that is 1 (all of it in the planner's process), and 0 in a process that
    multiprocessing started (a worker of ``bench/simulate.py``, or of this pool): such a process ends by joining its
    children without running ``atexit``, and it would wait for idle workers for ever. ``GraspError`` when the
    variable is not a whole number."""
    if multiprocessing.parent_process() is not None:
        return 0
    cores = min(os.cpu_count() or 1, MAX_WORKERS)
    text = os.environ.get(PROCESSES_ENV, str(cores))
    try:
        wanted = int(text)
    except ValueError as err:
        msg = f"{PROCESSES_ENV} must be a whole number of processes (1: the planner's alone), got {text!r}"
        raise GraspError(msg) from err
    return 0 if wanted <= 1 else min(wanted, MAX_WORKERS)


WARM_MODULES = ("scipy.optimize", "scipy.sparse.csgraph", "scipy.spatial", "scipy.cluster.vq")
"""Third-party modules a worker imports when it starts (with pybullet): a plan's first call need not wait for them."""


def _load() -> None:
    """Import what a worker runs, once, when it starts: pybullet without its build-time banner on stderr (as the CLI
    imports it) and the scientific modules the planner and the hold check use."""
    quiet_import("pybullet")
    for name in WARM_MODULES:
        importlib.import_module(name)


def _executor() -> concurrent.futures.ProcessPoolExecutor | None:
    """The worker processes (started now if they are not running), or None when there are none."""
    global _pool  # noqa: PLW0603 -- one set of workers per planner process
    count = workers()
    if count == 0:
        return None
    with _starting:  # plans in several threads (a flow's chains) share the workers
        if _pool is None:
            # spawn, not fork: the planner may run inside a threaded Prefect worker
            _pool = concurrent.futures.ProcessPoolExecutor(
                max_workers=count, mp_context=multiprocessing.get_context("spawn"), initializer=_load
            )
        return _pool


def start() -> None:
    """Start the workers now, so that their imports (about 1 s of CPU each) overlap what the planner's process does
    before it plans (``tasks.learn.api.learn_descriptor`` segments and fits first)."""
    for _ in range(workers()):
        Beside(_load)


def _shutdown() -> None:
    """Stop the workers without waiting for work nobody will read."""
    global _pool  # noqa: PLW0603 -- see _executor
    if _pool is not None:
        _pool.shutdown(wait=False, cancel_futures=True)
        _pool = None


def _count_running(change: int) -> None:
    """Count a call sent (+1) or ended (-1)."""
    global _running  # noqa: PLW0603 -- see _executor
    with _ended:
        _running += change
        _ended.notify_all()


def wait_idle() -> None:
    """Wait until the workers have ended every call sent to them, those whose results were dropped too (a plan
    returns while checks it started ahead still run; a benchmark timing plans one after another waits here)."""
    with _ended:
        _ended.wait_for(lambda: _running <= 0)


atexit.register(_shutdown)


class Beside(Generic[T]):
    """A call running in a worker process (or, when there is none, made here when its result is asked for)."""

    def __init__(self, fn: Callable[P, T], *args: P.args, **kwargs: P.kwargs) -> None:
        """Send ``fn(*args, **kwargs)`` to a worker process; ``fn`` and its arguments must pickle."""
        self._call = (fn, args, kwargs)
        self._future: concurrent.futures.Future[T] | None = None
        pool = _executor()
        if pool is not None:
            try:
                self._future = pool.submit(fn, *args, **kwargs)
            except (BrokenProcessPool, RuntimeError):
                _shutdown()
            else:
                _count_running(1)
                self._future.add_done_callback(lambda _: _count_running(-1))

    def result(self) -> T:
        """The call's result (waiting for it); exceptions raised by the call are raised here."""
        if self._future is not None:
            try:
                return self._future.result()
            except BrokenProcessPool:
                _shutdown()
        fn, args, kwargs = self._call
        return fn(*args, **kwargs)

    def drop(self) -> None:
        """Say the result is not needed: cancelled if it has not started (a started one runs to its end)."""
        if self._future is not None:
            self._future.cancel()
