"""Prefect wrapper of simulation (``tasks.simulate.api.simulate_descriptor``): a cached task over references.

The cache key is the descriptor's content id, the scene, the scene seed, the grasp mode and the code version
of the simulation, scene and grasp modules. A descriptor whose object has no built-in scene is not executed
(``SimulationRef.skipped`` says why), which is not an error of the recording.
"""

from __future__ import annotations

import contextlib
import io
from pathlib import Path
from typing import Any

import numpy as np
from prefect import task
from prefect.context import TaskRunContext

from flows.caching import RETRIED, stage_key
from tasks.errors import SceneError, SimulationError, StoreError
from tasks.report.refs import DescriptorRef, RecordingRef, SimulationRef
from tasks.simulate.api import simulate_descriptor
from tasks.simulate.instance import instance_from_meta, recording_meta
from tasks.store import Store, write_bytes_atomic

SIMULATE_MODULES = ("tasks.simulate", "tasks.scenes", "tasks.grasp", "schemas")
"""Modules whose source is the simulation stage's code version."""


def simulate_cache_key(context: TaskRunContext, parameters: dict[str, Any]) -> str:
    """Cache key of a simulation: descriptor id, the recording it came from (whose meta may name the scene
    instance), scene, seed, grasp mode, code version."""
    del context
    descriptor: DescriptorRef = parameters["descriptor"]
    recording: RecordingRef | None = parameters.get("recording")
    inputs = {"descriptor": descriptor.id, "recording": recording.recording_id if recording else None}
    params = {k: parameters.get(k) for k in ("scene", "seed", "grasp_mode")}
    return stage_key("simulate", SIMULATE_MODULES, inputs, params)


@task(
    name="simulate",
    cache_key_fn=simulate_cache_key,
    persist_result=True,
    **RETRIED,
)
def simulate_task(
    store_root: str,
    descriptor: DescriptorRef,
    *,
    scene: str | None = None,
    seed: int | None = None,
    grasp_mode: str = "constraint",
    recording: RecordingRef | None = None,
) -> SimulationRef:
    """Execute a stored descriptor on ``scene`` with ``seed`` (the randomised instance). Without either: the
    scene instance the ``recording``'s meta names (a ``pbd synth`` recording: scene and seed), not executed when
    it names none; with no recording either, the nominal built-in scene named like the descriptor's object. A
    descriptor that does not fit the scene is a failed simulation whose ``detail`` says why."""
    store = Store(store_root)
    desc = store.load(descriptor.path)
    if scene is None and seed is None and recording is not None:
        scene, seed = instance_from_meta(recording_meta(store.recording_dir(recording.recording_id)))
        if scene is None:
            why = "the recording names no built-in scene instance (its world frame is its own): use pbd simulate"
            return SimulationRef(desc.id, desc.object.name, False, (), (), skipped=why)
    rng = np.random.default_rng(seed) if seed is not None else None
    try:
        result = simulate_descriptor(desc, scene=scene, rng=rng, grasp_mode=grasp_mode)  # type: ignore[arg-type]
    except SceneError as err:
        return SimulationRef(desc.id, scene or desc.object.name, False, (), (), skipped=str(err))
    except SimulationError as err:  # the descriptor does not fit the scene or cannot be executed in it: a failure
        return SimulationRef(desc.id, scene or desc.object.name, False, (), (), detail=str(err))
    prims = result.primitives
    detail = "; ".join(result.notes)
    trace_path = _write_trace(store, desc.id, result, seed)
    return SimulationRef(
        descriptor_id=desc.id,
        scene=result.scene,
        success=result.success,
        achieved=tuple(float(p.achieved) for p in prims),
        target=tuple(float(p.target) for p in prims),
        joints=tuple(p.joint for p in prims),
        trace_path=str(trace_path) if trace_path else None,
        detail=detail,
    )


def _write_trace(store: Store, descriptor_id: str, result: Any, seed: int | None) -> Path | None:
    """The driven joints' trace as ``<store>/simulations/<id>-<scene>[-s<seed>].npz`` (times_s, values (k, n), targets,
    names, units) for the report; None when the simulation recorded no trace."""
    trace = getattr(result, "trace", None)
    if trace is None or not getattr(trace, "t_s", ()):
        return None
    names = list(trace.joints)
    targets = {p.joint: (float(p.target), "rad" if p.kind == "rotation" else "m") for p in result.primitives}
    buf = io.BytesIO()
    np.savez(
        buf,
        times_s=np.asarray(trace.t_s, dtype=np.float64),
        values=np.asarray(trace.q, dtype=np.float64).reshape(len(trace.t_s), -1).T,
        targets=np.array([targets.get(n, (np.nan, ""))[0] for n in names]),
        names=np.array(names),
        units=np.array([targets.get(n, (0.0, "rad"))[1] for n in names]),
    )
    instance = result.scene if seed is None else f"{result.scene}-s{seed}"
    path = store.root / "simulations" / f"{descriptor_id[:16]}-{instance}.npz"
    if not path.exists():
        with contextlib.suppress(StoreError):  # written by a concurrent run of the same simulation
            write_bytes_atomic(path, buf.getvalue())
    return path
