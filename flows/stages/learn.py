"""Prefect wrappers of learning (``tasks.learn.api.learn_descriptor``: segment, fit, grasp) and of storing.

``learn_task`` is cached on the recording id, the learning parameters, the name, the seed and the code
version of every module learning runs (learn, segment, fit, grasp, the recording loader and the schemas).
Its result is the descriptor itself: a few kB of JSON, never arrays. ``store_descriptor_task`` is not cached:
it is cheap, idempotent (a new version only when the content id differs from the latest) and must see the
store as it is now.
"""

from __future__ import annotations

import dataclasses
from typing import Any

import numpy as np
import pyarrow.parquet as pq
from prefect import task
from prefect.cache_policies import NO_CACHE
from prefect.context import TaskRunContext

from flows.caching import RETRIES, RETRY_DELAY_S, retry_on_transient_io, stage_key
from flows.cli_args import ParameterError
from schemas.descriptor import Descriptor
from schemas.tables import OBJECT_MODEL_FILE
from tasks.learn.api import learn_descriptor
from tasks.learn.params import LearnParams
from tasks.recording.load import load_recording
from tasks.report.refs import DescriptorRef, RecordingRef
from tasks.store import Store

LEARN_MODULES = ("tasks.learn", "tasks.segment", "tasks.fit", "tasks.grasp", "tasks.recording", "schemas")
"""Modules whose source is the learning stage's code version."""


def learn_params_of(params: dict[str, Any] | None) -> LearnParams:
    """``LearnParams`` from a flow's ``params`` dict; an unknown name is a ``ParameterError``."""
    known = {f.name for f in dataclasses.fields(LearnParams)}
    unknown = sorted(set(params or {}) - known)
    if unknown:
        msg = f"unknown learning parameter(s) {', '.join(unknown)} (known: {', '.join(sorted(known))})"
        raise ParameterError(msg)
    return LearnParams(**(params or {}))


def learn_cache_key(context: TaskRunContext, parameters: dict[str, Any]) -> str | None:
    """Cache key of a learning run: recording id, every parameter (defaults filled in), name, seed, code version."""
    del context
    recording: RecordingRef = parameters["recording"]
    try:
        learn_params = learn_params_of(parameters.get("params")).to_dict()
    except (ParameterError, TypeError):
        return None  # the task itself raises the error
    params = {"params": learn_params, "name": parameters.get("name"),
              "seed": parameters.get("seed", 0)}  # fmt: skip
    return stage_key("learn", LEARN_MODULES, {"recording": recording.recording_id}, params)


@task(
    name="learn",
    cache_key_fn=learn_cache_key,
    persist_result=True,
    retries=RETRIES,
    retry_delay_seconds=RETRY_DELAY_S,
    retry_condition_fn=retry_on_transient_io,
)
def learn_task(
    store_root: str,
    recording: RecordingRef,
    params: dict[str, Any] | None = None,
    name: str | None = None,
    seed: int = 0,
) -> Descriptor:
    """Segment, fit and plan the grasp of an ingested recording: its descriptor (not yet stored)."""
    rec = load_recording(Store(store_root), recording.recording_id)
    learn_params = learn_params_of(params)
    return learn_descriptor(rec, learn_params, name=name, rng=np.random.default_rng(seed))


@task(
    name="store-descriptor",
    cache_policy=NO_CACHE,
    persist_result=False,
    retries=RETRIES,
    retry_delay_seconds=RETRY_DELAY_S,
    retry_condition_fn=retry_on_transient_io,
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
