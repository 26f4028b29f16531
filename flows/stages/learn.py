"""Prefect wrappers of learning, one task per stage: segment → fit → grasp (which assembles the descriptor),
then storing.

Each stage is cached on the content of its inputs (the recording id; the spans; the chain), its parameters and
the code version of the modules it runs, so a changed grasp parameter re-runs the grasp and what follows only.
Results are small (spans, primitives, the descriptor's JSON), never arrays. ``store_descriptor_task`` is not
cached: it is cheap, idempotent (a new version only when the content id differs from the latest) and must see
the store as it is now.
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass
from typing import Any, TypeVar

import numpy as np
import pyarrow.parquet as pq
from prefect import task
from prefect.cache_policies import NO_CACHE
from prefect.context import TaskRunContext

from flows.caching import RETRIED, stage_key
from flows.cli_args import ParameterError
from schemas.descriptor import Descriptor, Primitive
from schemas.tables import OBJECT_MODEL_FILE
from tasks.grasp.planner import PlannerParams
from tasks.learn.api import assemble_descriptor, fit_segments, plan_recording_grasp, segment_recording
from tasks.learn.params import LearnParams
from tasks.recording.load import load_recording
from tasks.report.refs import DescriptorRef, RecordingRef
from tasks.store import Store

SEGMENT_MODULES = ("tasks.segment", "tasks.learn.prepare", "tasks.learn.params", "tasks.recording", "schemas")
FIT_MODULES = ("tasks.fit", "tasks.learn", "tasks.recording", "schemas")
GRASP_MODULES = ("tasks.grasp", "tasks.hand", "tasks.learn.api", "tasks.recording", "schemas")
"""Modules whose source is each stage's code version."""

P = TypeVar("P")


@dataclass(frozen=True)
class Segments:
    """The segments of a recording: time spans (s) and the generator's state after segmenting (the grasp
    planner continues from it, so a flow's descriptor is the one ``pbd learn`` makes with the same seed)."""

    recording: RecordingRef
    spans: tuple[tuple[float, float], ...]
    rng_state: dict[str, Any]


@dataclass(frozen=True)
class Chain:
    """The fitted chain M of a recording, its spans and learning's warnings so far."""

    segments: Segments
    primitives: tuple[Primitive, ...]
    warnings: tuple[str, ...]


def learn_params_of(params: dict[str, Any] | None) -> LearnParams:
    """``LearnParams`` from a flow's ``params`` dict; an unknown name is a ``ParameterError``."""
    return _params_of(LearnParams, params, "learning")


def planner_params_of(params: dict[str, Any] | None) -> PlannerParams:
    """``PlannerParams`` of the grasp planner from a flow's ``grasp`` dict; an unknown name is a ``ParameterError``."""
    return _params_of(PlannerParams, params, "grasp")


def _params_of(cls: type[P], params: dict[str, Any] | None, what: str) -> P:
    """An instance of the parameter dataclass ``cls`` from ``params``; ``ParameterError`` for a bad name or value."""
    known = {f.name for f in dataclasses.fields(cls)}  # type: ignore[arg-type]
    unknown = sorted(set(params or {}) - known)
    if unknown:
        msg = f"unknown {what} parameter(s) {', '.join(unknown)} (known: {', '.join(sorted(known))})"
        raise ParameterError(msg)
    return cls(**(params or {}))


def _checked(fn: Any, value: Any) -> Any:
    """``fn(value)`` or None when it raises ``ParameterError`` (the task itself then raises it)."""
    try:
        return fn(value)
    except ParameterError:
        return None


def segment_cache_key(context: TaskRunContext, parameters: dict[str, Any]) -> str | None:
    """Recording id, learning parameters, seed (the spectral segmenter draws from it), code version."""
    del context
    learn = _checked(learn_params_of, parameters.get("params"))
    if learn is None:
        return None
    refs = {"recording": parameters["recording"].recording_id}
    return stage_key("segment", SEGMENT_MODULES, refs, {"params": learn.to_dict(), "seed": parameters.get("seed", 0)})


def fit_cache_key(context: TaskRunContext, parameters: dict[str, Any]) -> str | None:
    """Recording id, the spans, learning parameters, code version."""
    del context
    learn = _checked(learn_params_of, parameters.get("params"))
    if learn is None:
        return None
    segments: Segments = parameters["segments"]
    refs = {"recording": segments.recording.recording_id, "spans": [list(s) for s in segments.spans]}
    return stage_key("fit", FIT_MODULES, refs, {"params": learn.to_dict()})


def grasp_cache_key(context: TaskRunContext, parameters: dict[str, Any]) -> str | None:
    """Recording id, the chain, the generator's state, planner parameters, name, seed, code version."""
    del context
    learn = _checked(learn_params_of, parameters.get("params"))
    planner = _checked(planner_params_of, parameters.get("grasp"))
    if learn is None or planner is None:
        return None
    chain: Chain = parameters["chain"]
    refs = {
        "recording": chain.segments.recording.recording_id,
        "chain": [p.to_dict() for p in chain.primitives],
        "warnings": list(chain.warnings),
        "rng": chain.segments.rng_state,
    }
    params = {
        "params": learn.to_dict(),
        "grasp": dataclasses.asdict(planner),
        "name": parameters.get("name"),
        "seed": parameters.get("seed", 0),
    }
    return stage_key("grasp", GRASP_MODULES, refs, params)


_STAGE_OPTIONS: dict[str, Any] = {"persist_result": True, **RETRIED}


@task(name="segment", cache_key_fn=segment_cache_key, **_STAGE_OPTIONS)
def segment_task(
    store_root: str, recording: RecordingRef, params: dict[str, Any] | None = None, seed: int = 0
) -> Segments:
    """Segment an ingested recording's marker tracks into time spans."""
    learn = learn_params_of(params)
    rng = np.random.default_rng(seed)
    spans = segment_recording(load_recording(Store(store_root), recording.recording_id), learn, rng)
    return Segments(recording, tuple((float(a), float(b)) for a, b in spans), dict(rng.bit_generator.state))


@task(name="fit", cache_key_fn=fit_cache_key, **_STAGE_OPTIONS)
def fit_task(store_root: str, segments: Segments, params: dict[str, Any] | None = None) -> Chain:
    """Classify and fit each segment: the chain M with extents C."""
    rec = load_recording(Store(store_root), segments.recording.recording_id)
    result = fit_segments(rec, [tuple(s) for s in segments.spans], learn_params_of(params))  # type: ignore[misc]
    return Chain(segments, result.chain, result.warnings)


@task(name="grasp", cache_key_fn=grasp_cache_key, **_STAGE_OPTIONS)
def grasp_task(
    store_root: str,
    chain: Chain,
    params: dict[str, Any] | None = None,
    *,
    grasp: dict[str, Any] | None = None,
    name: str | None = None,
    seed: int = 0,
) -> Descriptor:
    """Plan the grasp G on the recording's object model and assemble the descriptor T (not yet stored)."""
    learn, planner = learn_params_of(params), planner_params_of(grasp)
    rec = load_recording(Store(store_root), chain.segments.recording.recording_id)
    rng = np.random.default_rng()
    rng.bit_generator.state = chain.segments.rng_state
    warnings = list(chain.warnings)
    planned = plan_recording_grasp(rec, chain.primitives, rng, warnings, planner)
    return assemble_descriptor(rec, learn, chain.primitives, planned, warnings, name=name, seed=seed)


@task(
    name="store-descriptor",
    cache_policy=NO_CACHE,
    persist_result=False,
    **RETRIED,
)
def store_descriptor_task(store_root: str, descriptor: Descriptor) -> DescriptorRef:
    """Store the descriptor (and its object model) as the next version of its name unless the latest version
    has the same id."""
    store = Store(store_root)
    sha = descriptor.object.model_sha256
    if sha and descriptor.recording_id and not (store.models_dir / f"{sha}.parquet").is_file():
        model_file = store.recording_dir(descriptor.recording_id) / OBJECT_MODEL_FILE
        if model_file.is_file():  # the object model alone, not the whole recording
            table = pq.read_table(model_file)
            store.put_model(np.column_stack([table.column(c).to_numpy() for c in ("x", "y", "z")]))
    put = store.put_descriptor(descriptor)
    return DescriptorRef(put.name, put.version, put.id, str(put.path), put.created)
