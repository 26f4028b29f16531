"""``learn_descriptor``: a recording in, a task descriptor T = <O, A, G, M, C> out (no IO, no printing).

Pipeline: prepare tracks -> segment (change points, or the paper's spectral clustering) -> classify and fit
each segment (BIC, or the paper's eq. (3)) -> merge neighbouring pieces of one motion -> extents -> chain M.
"""

from __future__ import annotations

import hashlib
import re
from dataclasses import dataclass, replace
from pathlib import Path

import numpy as np

from schemas.descriptor import Descriptor, Grasp, ObjectRef, Primitive
from tasks.arrays import Points
from tasks.errors import FitError, GraspError
from tasks.learn.boundaries import refine_boundaries, trim_to_motion
from tasks.learn.chain import (
    HAND_ONLY,
    SegmentFit,
    drop_small,
    fit_span,
    merge_adjacent,
    primitive_fit_json,
    refine_extents,
)
from tasks.learn.hand import hand_by_motion
from tasks.learn.params import LearnParams
from tasks.learn.prepare import PreparedRecording, is_orientation_marker, prepare
from tasks.learn.reversals import split_reversals
from tasks.recording.load import RecordingData
from tasks.segment.changepoint import ChangepointParams, search
from tasks.segment.spectral import runs_from_labels, spectral_labels

CODE_PACKAGES = ("tasks.segment", "tasks.fit", "tasks.learn", "tasks.grasp")
"""Packages whose sources make up ``provenance.code_version`` of a learned descriptor."""


@dataclass(frozen=True)
class LearnResult:
    """Everything learning found: the per-segment fits (all kinds, in time order) and warnings."""

    segments: tuple[SegmentFit, ...]
    chain: tuple[Primitive, ...]
    warnings: tuple[str, ...]


def segment_spans(prep: PreparedRecording, params: LearnParams, rng: np.random.Generator) -> list[tuple[float, float]]:
    """Time spans (s) of the segments of a prepared recording, contiguous and in order."""
    if params.segmenter == "spectral":
        objects = [tr for tr in prep.tracks if tr.name not in prep.hand] or list(prep.tracks)
        primary = max(objects, key=lambda tr: float(np.linalg.norm(np.diff(tr.points, axis=0), axis=1).sum()))
        if params.k != "auto" and int(params.k) > len(primary.t_s) - 1:
            msg = f"k={params.k} segments but only {len(primary.t_s)} samples"
            raise FitError(msg, primary.name, (float(primary.t_s[0]), float(primary.t_s[-1])))
        if params.k == 1:
            return [(float(primary.t_s[0]), float(primary.t_s[-1]) + 1e-9)]
        res = spectral_labels(
            primary.points,
            primary.t_s,
            k=params.k,
            delta_p_m=params.delta_p_m,
            delta_t_s=params.delta_t_s,
            rng=rng,
            max_k=params.max_k,
        )
        return runs_from_labels(res.labels, primary.t_s, params.min_segment_s)
    cp = ChangepointParams(
        grid_s=params.grid_s,
        min_segment_s=params.min_segment_s,
        penalty=params.penalty,
        undefined_nats=params.undefined_nats,
    )
    return search(list(prep.tracks), cp).spans


def learn_chain(rec: RecordingData, params: LearnParams, rng: np.random.Generator) -> LearnResult:
    """Segment and fit the recording's marker tracks; the chain M (time order) with extents C."""
    prep = prepare(rec, params.sigma_floor_m, params.hand_pattern)
    duration = max(float(tr.t_s[-1] - tr.t_s[0]) for tr in prep.tracks)
    if duration < params.min_segment_s:
        tr = prep.tracks[0]
        msg = f"recording lasts {duration:.3f} s, shorter than one segment ({params.min_segment_s} s)"
        raise FitError(msg, tr.name, (float(tr.t_s[0]), float(tr.t_s[-1])))
    spans = segment_spans(prep, params, rng)
    if params.classifier == "bic" and (found := hand_by_motion(prep, spans, params) - prep.hand):
        prep = replace(prep, hand=prep.hand | found)
    fits = [fit_span(prep, a, b, params) for a, b in spans]
    if all(f.kind == "still" for f in fits):
        names = ", ".join(tr.name for tr in prep.tracks)
        msg = f"every marker is still ({names}): no motion to learn"
        raise FitError(msg, None, (spans[0][0], spans[-1][1]))
    if params.classifier == "bic":
        fits = merge_adjacent(prep, fits, params)
        fits = split_reversals(prep, fits, params)
        fits = trim_to_motion(prep, fits)
        fits = refine_boundaries(prep, fits)  # first: the rests then hold no slow start or stop of the motion
        fits = refine_extents(prep, fits)
        fits = drop_small(fits, params.min_motion_m)
    chain = tuple(_primitive(f) for f in fits if f.kind in ("rotation", "translation"))
    warnings = list(prep.warnings)
    for f in fits:
        if f.kind == "undefined" and not f.note.startswith(HAND_ONLY):
            warnings.append(
                f"t={f.t_start:.3f}..{f.t_end:.3f} s: undefined motion dropped ({f.note or 'no model fits'})"
            )
    return LearnResult(tuple(fits), chain, tuple(warnings))


def _primitive(f: SegmentFit) -> Primitive:
    if f.kind == "rotation" and f.rotation is not None:
        pos = tuple(float(v) for v in f.rotation.pos)
        direction = tuple(float(v) for v in f.rotation.dir)
    elif f.translation is not None:
        pos = tuple(float(v) for v in f.translation.centroid)
        direction = tuple(float(v) for v in f.translation.dir)
    else:  # pragma: no cover - fit_span always returns the fit of the kind it names
        msg = f"{f.kind} segment without a fit"
        raise FitError(msg, None, (f.t_start, f.t_end))
    return Primitive(
        kind="rotation" if f.kind == "rotation" else "translation",
        pos=(pos[0], pos[1], pos[2]),
        dir=(direction[0], direction[1], direction[2]),
        extent=float(f.extent),
        t_start=round(f.t_start, 6),
        t_end=round(f.t_end, 6),
        markers=tuple(m for m in f.markers if not is_orientation_marker(m)),
        fit=primitive_fit_json(f),
    )


def model_sha256(points: Points) -> str:
    """Content hash of an object model exactly as ``Store.put_model`` computes it (float32 x, y, z bytes)."""
    pts = np.ascontiguousarray(np.asarray(points, dtype=np.float32).reshape(-1, 3))
    return hashlib.sha256(pts.tobytes()).hexdigest()


def _slug(text: str) -> str:
    out = re.sub(r"[^A-Za-z0-9._-]+", "-", text).strip("-._")
    return out or "demonstration"


def default_name(rec: RecordingData) -> str:
    """``<action>-<object>`` from the recording's meta, else the recording file's stem, else its id."""
    action = rec.meta.get("action")
    obj = rec.meta.get("object")
    if action and obj:
        return _slug(f"{action}-{obj}")
    source = rec.info.get("source")
    if source:
        stem = Path(str(source)).name.split(".")[0]
        if stem:
            return _slug(stem)
    return _slug(rec.id)


def learn_descriptor(
    rec: RecordingData, params: LearnParams, *, name: str | None = None, rng: np.random.Generator
) -> Descriptor:
    """Learn T = <O, A, G, M, C> from an ingested recording (world frame, metres, radians).

    Warnings (dropped markers, undefined segments, no grasp) are kept in ``provenance.warnings``.
    """
    if rec.object_model is not None and len(rec.object_model):
        _start_grasp_workers()
    result = learn_chain(rec, params, rng)
    warnings = list(result.warnings)
    obj_name = str(rec.meta.get("object") or (name or default_name(rec)))
    model = rec.object_model
    if model is not None and len(model):
        sha = model_sha256(model)
        obj = ObjectRef(obj_name, sha, len(model), f"models/{sha}.parquet")
    else:
        obj = ObjectRef(obj_name)
    grasp = _grasp(rec, result.chain, rng, warnings)
    from tasks.code_version import code_version  # noqa: PLC0415

    return Descriptor(
        name=_slug(name) if name else default_name(rec),
        action=str(rec.meta.get("action") or "manipulate"),
        object=obj,
        grasp=grasp,
        chain=result.chain,
        recording_id=rec.id,
        recording_path=str(rec.info.get("source")) if rec.info.get("source") else None,
        parameters=params.to_dict(),
        code_version=code_version(*CODE_PACKAGES),
        extra_provenance={"warnings": warnings} if warnings else {},
    )


def _start_grasp_workers() -> None:
    """Start the grasp planner's worker processes while the chain is learnt (``tasks.grasp.worker_pool.start``)."""
    try:
        from tasks.grasp.worker_pool import start  # noqa: PLC0415
    except ImportError:
        return
    start()


def _grasp(
    rec: RecordingData, chain: tuple[Primitive, ...], rng: np.random.Generator, warnings: list[str]
) -> Grasp | None:
    try:
        from tasks.grasp.api import plan_grasp_for_recording  # noqa: PLC0415
    except ImportError:
        return None
    t_seed = chain[0].t_start if chain else None
    try:
        return plan_grasp_for_recording(rec.object_model, rec.wrist, t_seed, rec.start_ns, rng)
    except GraspError as err:
        warnings.append(f"no grasp: {err}")
        return None
