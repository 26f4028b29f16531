"""The per-recording chain of stage tasks, shared by the flows: ingest → segment → fit → grasp → store →
simulate, and the diff against the previous version.

``submit_chain`` submits the tasks of one recording to the flow's task runner, each taking its upstream's
future, so recordings proceed independently; ``collect`` waits for them, logs the outcome (chain, version
stored, simulation) and summarises it. A failed stage fails its recording: the others go on, the report lists
the error, and the flow run ends Failed (``flows.summary.finish``).

A recording whose every stage result is already known (``flows.known``: cached under the key its task would
compute, the descriptor already the latest version) is summarised from those results without submitting a
task; its log line says so. One definition of the chain (``chain_steps``) serves both ways.
"""

from __future__ import annotations

import logging
from collections import deque
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from prefect import Task, get_run_logger
from prefect.futures import PrefectFuture, as_completed

from flows.caching import STAGE_TIMEOUT_S, on_store
from flows.known import KnownResults, NotKnownError
from flows.progress import notify
from flows.stages.diff import diff_task, nothing_to_compare
from flows.stages.ingest import ingest_task
from flows.stages.learn import fit_task, grasp_task, segment_task, store_descriptor_task
from flows.stages.simulate import simulate_task
from tasks.learn.api import name_from_meta, slug
from tasks.report.refs import DescriptorRef, EntryResult, RecordingRef
from tasks.simulate.instance import recording_meta
from tasks.store import Store


@dataclass(frozen=True)
class ChainSettings:
    """What every recording of a run shares: the store, the learning parameters, the seed (grasp planner,
    spectral segmenter), a fixed descriptor name, the seed of the randomised scene instance to simulate on (None:
    the one the recording names, else nominal) and the grasp planner's parameters."""

    store_root: str
    params: dict[str, Any] = field(default_factory=dict)
    seed: int = 0
    name: str | None = None
    scene_seed: int | None = None
    grasp: dict[str, Any] = field(default_factory=dict)


@dataclass(frozen=True)
class Chain:
    """The submitted tasks of one recording, in pipeline order (stage name → future; the ingested recording's
    reference itself when it was known before submitting)."""

    source: Path
    futures: dict[str, Any]

    @property
    def last(self) -> PrefectFuture[Any]:
        """The future that finishes last: the final stage's (``collect`` waits for every stage anyway)."""
        last: PrefectFuture[Any] = list(self.futures.values())[-1]
        return last


class StageTasks:
    """The stage tasks bound to one store (results persisted under ``<store>/prefect-results``)."""

    def __init__(self, store_root: str) -> None:
        self.ingest = on_store(ingest_task, store_root)
        self.segment = on_store(segment_task, store_root)
        self.fit = on_store(fit_task, store_root)
        self.grasp = on_store(grasp_task, store_root)
        self.store: Task[..., DescriptorRef] = store_descriptor_task
        self.simulate = on_store(simulate_task, store_root)
        self.diff = on_store(diff_task, store_root)


def chain_steps(
    tasks: StageTasks,
    settings: ChainSettings,
    name: str | None,
    ingested: Any,
    run: Callable[..., Any],
) -> dict[str, Any]:
    """The chain of one ingested recording, segment → fit → grasp → store → simulate, diff, each stage as
    ``run(task, *args, **kwargs)`` on its upstream's outcome: ``Task.submit`` (futures) or a lookup of known
    results (values). Stage name → outcome, in pipeline order, ingest first.

    ``name`` names the descriptor (default: ``settings.name``, else learning's ``<action>-<object>``).
    """
    root, params, seed = settings.store_root, settings.params, settings.seed
    out: dict[str, Any] = {"ingest": ingested}
    out["segment"] = run(tasks.segment, root, ingested, params, seed=seed)
    out["fit"] = run(tasks.fit, root, out["segment"], params)
    grasp = settings.grasp
    out["grasp"] = run(tasks.grasp, root, out["fit"], params, grasp=grasp, name=name or settings.name, seed=seed)
    out["store"] = run(tasks.store, root, out["grasp"])
    if settings.scene_seed is None:  # the scene instance the recording's meta names (pbd synth), else nominal
        out["simulate"] = run(tasks.simulate, root, out["store"], recording=ingested)
    else:
        out["simulate"] = run(tasks.simulate, root, out["store"], seed=settings.scene_seed)
    out["diff"] = run(tasks.diff, root, out["store"])
    return out


def _submit(task: Task[..., Any], *args: Any, **kwargs: Any) -> PrefectFuture[Any]:
    future: PrefectFuture[Any] = task.submit(*args, **kwargs)
    return future


def submit_chain(
    tasks: StageTasks,
    source: Path,
    settings: ChainSettings,
    name: str | None = None,
    ingested: PrefectFuture[RecordingRef] | RecordingRef | None = None,
) -> Chain:
    """Submit ingest → segment → fit → grasp → store → simulate, diff for one recording; returns futures."""
    ingested = ingested or tasks.ingest.submit(str(source), settings.store_root)
    return Chain(source, chain_steps(tasks, settings, name, ingested, _submit))


def known_chain(
    tasks: StageTasks, known: KnownResults, source: Path, settings: ChainSettings, *, name: str, ingested: RecordingRef
) -> EntryResult | None:
    """The outcome of an ingested recording whose every stage result is known (cached, and its descriptor the
    latest version of its name) without running a task, else None."""

    def lookup(task: Task[..., Any], *args: Any, **kwargs: Any) -> Any:
        if task is tasks.store:
            return known.unchanged(args[1])
        if task is tasks.diff and nothing_to_compare(args[1]):
            return None
        return known.cached(task, *args, **kwargs)

    try:
        results = chain_steps(tasks, settings, name, ingested, lookup)
    except NotKnownError:
        return None
    return entry_of(source, results, None)


def collect(chain: Chain, timeout_s: float = STAGE_TIMEOUT_S) -> EntryResult:
    """Wait for a chain and summarise it; the first failed stage's error names the recording's failure. A stage
    without a result ``timeout_s`` after it is waited for fails the recording ("timed out")."""
    results: dict[str, Any] = {}
    error: str | None = None
    for stage, future in chain.futures.items():
        if not isinstance(future, PrefectFuture):  # a result known before the chain was submitted
            results[stage] = future
            continue
        future.wait(timeout=timeout_s)
        state = future.state
        if not state.is_final():
            error = error or f"{stage}: timed out (no result {timeout_s:.0f} s after it was waited for)"
        elif state.is_completed():
            results[stage] = future.result()
        elif error is None:
            value = state.result(raise_on_failure=False) if state.is_failed() or state.is_crashed() else None
            error = f"{stage}: {value}" if isinstance(value, BaseException) else f"{stage}: {state.name}"
    entry = entry_of(chain.source, results, error)
    get_run_logger().log(logging.ERROR if error else logging.INFO, "%s", outcome_line(entry))
    return entry


def entry_of(source: Path, results: Mapping[str, Any], error: str | None) -> EntryResult:
    """A recording's summary from its stages' results (stage name → result) and the first failure."""
    desc = results.get("grasp")
    extra = {"chain": " → ".join(p.kind for p in desc.chain) or "(empty)"} if desc is not None else {}
    return EntryResult(
        source=str(source),
        recording=results.get("ingest"),
        descriptor=results.get("store"),
        simulation=results.get("simulate"),
        diff=results.get("diff"),
        error=error,
        extra=extra,
    )


def outcome_line(entry: EntryResult) -> str:
    """One log line per recording: chain learned, version stored (new, unchanged, changed), simulation result."""
    name = Path(entry.source).name
    if entry.error is not None:
        return f"{name}: failed at {entry.error}"
    d, sim = entry.descriptor, entry.simulation
    stored = f"{d.ref} {entry.status} ({d.id[:12]})" if d else "not stored"
    if sim is None:
        simulated = "not simulated"
    elif sim.skipped is not None:
        simulated = f"not simulated ({sim.skipped})"
    else:
        reached = ", ".join(f"{a / t:.0%}" for a, t in zip(sim.achieved, sim.target, strict=False) if t)
        simulated = f"simulation {'success' if sim.success else 'FAILED'} in {sim.scene}" + (
            f" (extent reached {reached})" if reached else ""
        )
    return f"{name}: chain {entry.extra.get('chain', '?')}; {stored}; {simulated}"


def run_names(
    sources: Sequence[Path], metas: Mapping[Path, Mapping[str, Any]], root: Path | None = None
) -> dict[Path, str]:
    """The descriptor name of each recording of a run, by the one naming rule of every entry point:
    ``<action>-<object>`` from the recording's meta, else the file name without suffixes; when several recordings
    of the run get the same name, each of them is ``<name>--<path>``, its path under ``root`` (else its file
    name) without suffixes, so each keeps a version history of its own."""
    names = {s: name_from_meta(metas.get(s, {}), s) or "recording" for s in sources}
    shared = {n for n in names.values() if list(names.values()).count(n) > 1}
    for source, name in names.items():
        if name in shared:
            rel = source.relative_to(root) if root and source.is_relative_to(root) else Path(source.name)
            names[source] = f"{name}--{slug('-'.join([*rel.parent.parts, rel.name.split('.')[0]]))}"
    return names


def run_chains(
    sources: Sequence[Path],
    settings: ChainSettings,
    workers: int,
    root: Path | None = None,
) -> list[EntryResult]:
    """Process ``sources`` with at most ``workers`` recordings in flight; results in the order of ``sources``.

    Every recording is ingested first, so that each is named by ``run_names`` (unless ``settings.name`` names
    them all); ``root`` is the archive folder the names' paths are taken under.
    """
    tasks = StageTasks(settings.store_root)
    store = Store(settings.store_root)
    known = KnownResults(settings.store_root)
    notify(0, len(sources), "")
    ingested: dict[Path, PrefectFuture[RecordingRef] | RecordingRef] = {}
    for source in sources:
        try:
            ingested[source] = known.cached(tasks.ingest, str(source), settings.store_root)
        except NotKnownError:
            ingested[source] = tasks.ingest.submit(str(source), settings.store_root)
    metas: dict[Path, dict[str, Any]] = {}
    results: dict[Path, EntryResult] = {}
    for source, outcome in ingested.items():
        if isinstance(outcome, RecordingRef):
            metas[source] = recording_meta(store.recording_dir(outcome.recording_id))
            continue
        outcome.wait()
        if outcome.state.is_completed():
            ingested[source] = outcome.result()
            metas[source] = recording_meta(store.recording_dir(outcome.result().recording_id))
        else:  # nothing downstream of a recording that cannot be read
            results[source] = collect(Chain(source, {"ingest": outcome}))
    names = run_names(sources, metas, root)
    pending: deque[Path] = deque()
    for source in sources:
        recording = ingested[source]
        if source in results or not isinstance(recording, RecordingRef):
            continue
        entry = known_chain(tasks, known, source, settings, name=settings.name or names[source], ingested=recording)
        if entry is None:
            pending.append(source)
            continue
        results[source] = entry
        get_run_logger().info("%s (every stage known: no task run)", outcome_line(entry))
        notify(len(results), len(sources), source.name)
    running: dict[PrefectFuture[Any], Chain] = {}
    while pending or running:
        while pending and len(running) < max(1, workers):
            source = pending.popleft()
            chain = submit_chain(tasks, source, settings, settings.name or names[source], ingested[source])
            running[chain.last] = chain
        try:
            done = next(iter(as_completed(list(running), timeout=STAGE_TIMEOUT_S)))
        except TimeoutError:
            done = next(iter(running))  # none finished in time: the oldest is collected, its stuck stage timed out
        finished = running.pop(done)
        results[finished.source] = collect(finished)
        notify(len(results), len(sources), finished.source.name)
    return [results[s] for s in sources]
