"""The flows' thread-pool task runner, whose futures know their state without asking the server.

A stage task takes its upstream's future. When a task run starts, Prefect looks for parent task runs among its
arguments by reading each future's ``state``; a future whose result nobody has waited for yet reads the task run
from the server, one HTTP request per upstream (six per recording, most of a cached run's wall time on a busy
machine). The task ran in a thread of this process, so its state is here: the State the thread returned once it
finished, Pending before. ``LocalStateFuture`` answers from that; the flow's logic never depends on a running
upstream being recorded as a parent (that is for tasks that yield values while they run).
"""

from __future__ import annotations

from collections.abc import Iterable
from typing import Any

from prefect.client.schemas.objects import State
from prefect.futures import PrefectConcurrentFuture, PrefectFuture
from prefect.states import Pending
from prefect.task_runners import ThreadPoolTaskRunner


class LocalStateFuture(PrefectConcurrentFuture[Any]):
    """A thread-pool future whose ``state`` is the finished thread's State, else Pending; never a server read."""

    @property
    def state(self) -> State[Any]:
        """The task run's final State once its thread returned it, else Pending."""
        if self._final_state is None and self._wrapped_future.done() and self._wrapped_future.exception() is None:
            result = self._wrapped_future.result()
            if isinstance(result, State):
                self._final_state = result
        return self._final_state or Pending()


class LocalThreadPoolTaskRunner(ThreadPoolTaskRunner[Any]):
    """``ThreadPoolTaskRunner`` handing out ``LocalStateFuture``s."""

    def submit(
        self,
        task: Any,
        parameters: dict[str, Any],
        wait_for: Iterable[PrefectFuture[Any]] | None = None,
        dependencies: dict[str, Any] | None = None,
    ) -> LocalStateFuture:
        """Submit ``task`` to a worker thread, as ``ThreadPoolTaskRunner.submit``; a ``LocalStateFuture``."""
        future = super().submit(task, parameters, wait_for, dependencies)
        return LocalStateFuture(future.task_run_id, future.wrapped_future)
