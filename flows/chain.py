"""The per-recording chain of stage tasks, shared by the flows: ingest → learn → store → simulate, and the
diff against the previous version.

``submit_chain`` submits the tasks of one recording to the flow's task runner, each taking its upstream's
future, so recordings proceed independently; ``collect`` waits for them and summarises the outcome. A failed
stage fails its recording only: the archive goes on and the report lists the error.
"""

from __future__ import annotations

import re
from collections import deque
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from prefect import Task
from prefect.futures import PrefectFuture, as_completed

from flows.caching import on_store
from flows.progress import notify
from flows.stages.diff import diff_task
from flows.stages.ingest import ingest_task
from flows.stages.learn import learn_task, store_descriptor_task
from flows.stages.simulate import simulate_task
from tasks.report.refs import DescriptorRef, EntryResult


@dataclass(frozen=True)
class ChainSettings:
    """What every recording of a run shares: the store, the learning parameters, the grasp planner's seed,
    a fixed descriptor name, and the seed of the randomised scene instance to simulate on (None: nominal)."""

    store_root: str
    params: dict[str, Any] = field(default_factory=dict)
    seed: int = 0
    name: str | None = None
    scene_seed: int | None = None


@dataclass(frozen=True)
class Chain:
    """The submitted tasks of one recording, in pipeline order (stage name → future)."""

    source: Path
    futures: dict[str, PrefectFuture[Any]]

    @property
    def last(self) -> PrefectFuture[Any]:
        """The future that finishes last: the final stage's (``collect`` waits for every stage anyway)."""
        return list(self.futures.values())[-1]


class StageTasks:
    """The stage tasks bound to one store (results persisted under ``<store>/prefect-results``)."""

    def __init__(self, store_root: str) -> None:
        self.ingest = on_store(ingest_task, store_root)
        self.learn = on_store(learn_task, store_root)
        self.store: Task[..., DescriptorRef] = store_descriptor_task
        self.simulate = on_store(simulate_task, store_root)
        self.diff = on_store(diff_task, store_root)


def submit_chain(tasks: StageTasks, source: Path, settings: ChainSettings, name: str | None = None) -> Chain:
    """Submit ingest → learn (segment, fit, grasp) → store → simulate, diff for one recording; returns futures.

    ``name`` names the descriptor (default: ``settings.name``, else learning's ``<action>-<object>``).
    """
    root = settings.store_root
    ingested = tasks.ingest.submit(str(source), root)
    learned = tasks.learn.submit(root, ingested, settings.params, name=name or settings.name, seed=settings.seed)
    stored = tasks.store.submit(root, learned)
    if settings.scene_seed is None:  # the scene instance the recording's meta names (pbd synth), else nominal
        simulated = tasks.simulate.submit(root, stored, recording=ingested)
    else:
        simulated = tasks.simulate.submit(root, stored, seed=settings.scene_seed)
    diffed = tasks.diff.submit(root, stored)
    futures: dict[str, PrefectFuture[Any]] = {
        "ingest": ingested,
        "learn": learned,
        "store": stored,
        "simulate": simulated,
        "diff": diffed,
    }
    return Chain(source, futures)


def collect(chain: Chain) -> EntryResult:
    """Wait for a chain and summarise it; the first failed stage's error names the recording's failure."""
    results: dict[str, Any] = {}
    error: str | None = None
    for stage, future in chain.futures.items():
        future.wait()
        state = future.state
        if state.is_completed():
            results[stage] = future.result()
        elif error is None:
            value = state.result(raise_on_failure=False) if state.is_failed() or state.is_crashed() else None
            error = f"{stage}: {value}" if isinstance(value, BaseException) else f"{stage}: {state.name}"
    desc = results.get("learn")
    extra = {"chain": " → ".join(p.kind for p in desc.chain) or "(empty)"} if desc is not None else {}
    return EntryResult(
        source=str(chain.source),
        recording=results.get("ingest"),
        descriptor=results.get("store"),
        simulation=results.get("simulate"),
        diff=results.get("diff"),
        error=error,
        extra=extra,
    )


def archive_names(archive: Path, sources: Sequence[Path]) -> dict[Path, str]:
    """One descriptor name per recording of an archive: its path under ``archive`` without suffixes, slugged.

    Several demonstrations of one task in an archive each keep their own version history, so re-running
    an unchanged archive finds every descriptor unchanged.
    """
    out = {}
    for source in sources:
        rel = source.relative_to(archive) if source.is_relative_to(archive) else Path(source.name)
        stem = "-".join([*rel.parent.parts, rel.name.split(".")[0]])
        out[source] = re.sub(r"[^A-Za-z0-9._-]+", "-", stem).strip("-._") or "recording"
    return out


def run_chains(
    sources: Sequence[Path],
    settings: ChainSettings,
    workers: int,
    names: Mapping[Path, str] | None = None,
    submit: Callable[..., Chain] = submit_chain,
) -> list[EntryResult]:
    """Process ``sources`` with at most ``workers`` recordings in flight; results in the order of ``sources``.

    ``names`` gives a recording's descriptor name (see ``archive_names``); by default learning names it.
    """
    tasks = StageTasks(settings.store_root)
    pending = deque(sources)
    running: dict[PrefectFuture[Any], Chain] = {}
    results: dict[Path, EntryResult] = {}
    notify(0, len(sources), "")
    while pending or running:
        while pending and len(running) < max(1, workers):
            source = pending.popleft()
            chain = submit(tasks, source, settings, (names or {}).get(source))
            running[chain.last] = chain
        done = next(iter(as_completed(list(running))))
        finished = running.pop(done)
        results[finished.source] = collect(finished)
        notify(len(results), len(sources), finished.source.name)
    return [results[s] for s in sources]
