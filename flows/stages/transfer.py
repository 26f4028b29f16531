"""Prefect wrappers of transfer (``tasks.transfer.api.transfer_descriptor``) and of its inputs.

``target_model_task`` puts the target model into the store (``models/<sha256>.parquet``; a recording is
ingested first) and returns a ``ModelRef``; ``resolve_descriptor_task`` turns a descriptor reference into a
``DescriptorRef``. ``transfer_task`` is cached on the source descriptor's id, the target model's sha256, the
registration parameters, the seed and the code version of the transfer and grasp modules.
"""

from __future__ import annotations

import re
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from prefect import task
from prefect.cache_policies import NO_CACHE
from prefect.context import TaskRunContext

from flows.caching import RETRIED, stage_key
from flows.transfer_inputs import TransferOptions, carry, read_target, refusal
from schemas.descriptor import Descriptor, ObjectRef
from tasks.errors import TransferError
from tasks.report.refs import DescriptorRef
from tasks.store import Store
from tasks.transfer.model_io import source_model_of

TRANSFER_MODULES = ("tasks.transfer", "tasks.grasp", "schemas")
"""Modules whose source is the transfer stage's code version."""


@dataclass(frozen=True)
class ModelRef:
    """An object model in the store: ``models/<sha256>.parquet`` with ``points`` points, named ``object_name``."""

    sha256: str
    points: int
    path: str
    object_name: str
    label: str
    recording_id: str | None = None
    """The ingested recording the model came from (its meta may name a built-in scene instance), else None."""


@task(name="resolve-descriptor", cache_policy=NO_CACHE, persist_result=False)
def resolve_descriptor_task(store_root: str, ref: str) -> DescriptorRef:
    """The stored version (or file) a descriptor reference (path, id prefix, ``name@vN``) points at."""
    store = Store(store_root)
    path = store.resolve(ref)
    desc = Descriptor.from_json(path.read_text(), source=str(path))
    match = re.fullmatch(r"v(\d+)", path.stem)
    version = int(match[1]) if match and path.parent == store.descriptor_dir(desc.name) else 0
    return DescriptorRef(desc.name, version, desc.id, str(path), created=False)


@task(
    name="target-model",
    cache_policy=NO_CACHE,
    persist_result=False,
    **RETRIED,
)
def target_model_task(store_root: str, model: str, seed: int = 0) -> ModelRef:
    """Store the target model (a model file, or the object model of a recording) by its sha256."""
    store = Store(store_root)
    target = read_target(store, model, seed=seed)
    sha, stored = store.put_model(target.points)
    return ModelRef(sha, len(target.points), str(stored), target.object_name, target.label, target.recording_id)


def transfer_cache_key(context: TaskRunContext, parameters: dict[str, Any]) -> str:
    """Cache key of a transfer: source descriptor id, target model sha256, the options, code version."""
    del context
    source: DescriptorRef = parameters["descriptor"]
    target: ModelRef = parameters["target"]
    options: TransferOptions = parameters.get("options") or TransferOptions()
    refs = {"descriptor": source.id, "target_model": target.sha256}
    return stage_key("transfer", TRANSFER_MODULES, refs, options.to_dict())


@task(
    name="transfer",
    cache_key_fn=transfer_cache_key,
    persist_result=True,
    **RETRIED,
)
def transfer_task(
    store_root: str, descriptor: DescriptorRef, target: ModelRef, options: TransferOptions | None = None
) -> Descriptor:
    """Register the source descriptor's object model onto ``target`` and carry chain and grasp across; a poor,
    ambiguous or loose registration is a ``TransferError`` unless ``options.accept_ambiguous``."""
    options = options or TransferOptions()
    store = Store(store_root)
    source = Descriptor.from_json(Path(descriptor.path).read_text(), source=descriptor.path)
    source_points = source_model_of(store, source.object.model_sha256, source.object.model_uri, descriptor.path)
    target_ref = ObjectRef(target.object_name, target.sha256, target.points, target.path)
    target_points = store.load_model(target.sha256)
    result = carry(source, source_points, target_points, target_ref, target_label=target.label, options=options)
    if (refused := refusal(result, options, accept="accept_ambiguous")) is not None:
        raise TransferError(refused)
    return result.descriptor
