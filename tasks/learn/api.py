"""``learn_descriptor``: a recording in, a task descriptor T = <O, A, G, M, C> out (no IO, no printing).

Pipeline: prepare tracks -> segment (change points, or the paper's spectral clustering) -> classify and fit
each segment (BIC, or the paper's eq. (3)) -> merge neighbouring pieces of one motion -> extents -> chain M.
"""

from __future__ import annotations

import hashlib
import re
from collections.abc import Mapping
from dataclasses import dataclass, replace
from pathlib import Path
from typing import Any

import numpy as np

from schemas.descriptor import Descriptor, Grasp, ObjectRef, Primitive
from tasks.arrays import Points
from tasks.code_version import code_version
from tasks.errors import FitError, GraspError, bounded
from tasks.grasp.api import plan_grasp_for_recording
from tasks.grasp.planner import PlannerParams
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
from tasks.simulate.instance import instance_from_meta

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


def segment_recording(rec: RecordingData, params: LearnParams, rng: np.random.Generator) -> list[tuple[float, float]]:
    """The segments' time spans (s, contiguous, in order) of the recording's marker tracks; ``rng`` draws the
    spectral segmenter's k-means starts (the change-point search draws nothing)."""
    prep = prepare(rec, params.sigma_floor_m, params.hand_pattern)
    duration = max(float(tr.t_s[-1] - tr.t_s[0]) for tr in prep.tracks)
    if duration < params.min_segment_s:
        tr = prep.tracks[0]
        msg = f"recording lasts {duration:.3f} s, shorter than one segment ({params.min_segment_s} s)"
        raise FitError(msg, tr.name, (float(tr.t_s[0]), float(tr.t_s[-1])))
    return segment_spans(prep, params, rng)


def fit_segments(rec: RecordingData, spans: list[tuple[float, float]], params: LearnParams) -> LearnResult:
    """Classify and fit each span (s) of the recording; the chain M (time order) with extents C.

    The hand is looked for by its motion twice: over the change points' spans, and over the segments once their
    boundaries are at the part's rests, since a coarse segmentation may join a part's stop and the hand's
    withdrawal in one span (the withdrawal is then not seen alone); a hand found only then is fitted again."""
    prep = prepare(rec, params.sigma_floor_m, params.hand_pattern)
    if params.classifier == "bic" and (found := hand_by_motion(prep, spans, params) - prep.hand):
        prep = replace(prep, hand=prep.hand | found)
    fits = _fitted(prep, spans, params)
    if params.classifier == "bic":
        rested = [(f.t_start, f.t_end) for f in fits]
        if found := hand_by_motion(prep, rested, params) - prep.hand:
            prep = replace(prep, hand=prep.hand | found)
            fits = _fitted(prep, spans, params)
    chain = tuple(_primitive(f) for f in fits if f.kind in ("rotation", "translation"))
    warnings = list(prep.warnings)
    for f in fits:
        if f.kind == "undefined" and not f.note.startswith(HAND_ONLY):
            warnings.append(
                f"t={f.t_start:.3f}..{f.t_end:.3f} s: undefined motion dropped ({f.note or 'no model fits'})"
            )
    return LearnResult(tuple(fits), chain, tuple(warnings))


def _fitted(prep: PreparedRecording, spans: list[tuple[float, float]], params: LearnParams) -> list[SegmentFit]:
    """Each span classified and fitted, then (BIC classifier) merged, split at reversals, trimmed to the motion,
    its boundaries moved to the rests, its extents measured between them and too small motions dropped."""
    fits = [fit_span(prep, a, b, params) for a, b in spans]
    if all(f.kind == "still" for f in fits):
        names = bounded([tr.name for tr in prep.tracks])
        msg = f"every marker is still ({names}): no motion to learn"
        raise FitError(msg, None, (spans[0][0], spans[-1][1]))
    if params.classifier == "bic":
        fits = merge_adjacent(prep, fits, params)
        fits = split_reversals(prep, fits, params)
        fits = merge_adjacent(prep, fits, params)  # a reversal inside a span leaves its second leg in two pieces
        fits = trim_to_motion(prep, fits)
        fits = refine_boundaries(prep, fits, params)  # first: the rests then hold no slow start or stop of the motion
        fits = refine_extents(prep, fits)
        fits = drop_small(prep, fits, params.min_motion_m)
    return fits


def learn_chain(rec: RecordingData, params: LearnParams, rng: np.random.Generator) -> LearnResult:
    """Segment and fit the recording's marker tracks; the chain M (time order) with extents C."""
    return fit_segments(rec, segment_recording(rec, params, rng), params)


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


def slug(text: str) -> str:
    """``text`` as a descriptor name: runs of characters other than ``[A-Za-z0-9._-]`` become ``-``."""
    out = re.sub(r"[^A-Za-z0-9._-]+", "-", text).strip("-._")
    return out or "demonstration"


def name_from_meta(meta: Mapping[str, Any], source: str | Path | None) -> str | None:
    """The naming rule of every entry point: ``<action>-<object>`` from a recording's meta, else the recording
    file's name without suffixes; None when neither is known."""
    action, obj = meta.get("action"), meta.get("object")
    if action and obj:
        return slug(f"{action}-{obj}")
    stem = Path(str(source)).name.split(".")[0] if source else ""
    return slug(stem) if stem else None


def default_name(rec: RecordingData) -> str:
    """The recording's name by ``name_from_meta``, else its id."""
    return name_from_meta(rec.meta, rec.info.get("source")) or slug(rec.id)


def learn_descriptor(
    rec: RecordingData,
    params: LearnParams,
    *,
    name: str | None = None,
    rng: np.random.Generator,
    seed: int | None = None,
) -> Descriptor:
    """Learn T = <O, A, G, M, C> from an ingested recording (world frame, metres, radians).

    Warnings (dropped markers, undefined segments, no grasp) are kept in ``provenance.warnings``; ``seed``, the
    seed ``rng`` was made from, in ``provenance.seed``.
    """
    result = learn_chain(rec, params, rng)
    warnings = list(result.warnings)
    grasp = plan_recording_grasp(rec, result.chain, rng, warnings)
    return assemble_descriptor(rec, params, result.chain, grasp, warnings, name=name, seed=seed)


def assemble_descriptor(
    rec: RecordingData,
    params: LearnParams,
    chain: tuple[Primitive, ...],
    grasp: Grasp | None,
    warnings: list[str],
    *,
    name: str | None = None,
    seed: int | None = None,
) -> Descriptor:
    """The descriptor of a recording from its chain and grasp: name (``name``, else ``default_name``), object
    reference, provenance (recording, parameters, code version, warnings, ``seed`` and the built-in scene
    instance the recording's meta names, if any)."""
    obj_name = str(rec.meta.get("object") or (name or default_name(rec)))
    model = rec.object_model
    if model is not None and len(model):
        sha = model_sha256(model)
        obj = ObjectRef(obj_name, sha, len(model), f"models/{sha}.parquet")
    else:
        obj = ObjectRef(obj_name)
    extra: dict[str, object] = {"warnings": list(warnings)} if warnings else {}
    if seed is not None:
        extra["seed"] = seed
    scene, scene_seed = instance_from_meta(rec.meta)
    if scene is not None:
        extra["scene"] = {"name": scene, "seed": scene_seed}
    return Descriptor(
        name=slug(name) if name else default_name(rec),
        action=str(rec.meta.get("action") or "manipulate"),
        object=obj,
        grasp=grasp,
        chain=chain,
        recording_id=rec.id,
        recording_path=str(rec.info.get("source")) if rec.info.get("source") else None,
        parameters=params.to_dict(),
        code_version=code_version(*CODE_PACKAGES),
        extra_provenance=extra,
    )


def plan_recording_grasp(
    rec: RecordingData,
    chain: tuple[Primitive, ...],
    rng: np.random.Generator,
    warnings: list[str],
    planner: PlannerParams | None = None,
) -> Grasp | None:
    """The grasp planned on the recording's object model from the wrist pose where the chain starts; None (with
    a warning appended to ``warnings``) when none can be planned, or without an object model."""
    t_seed = chain[0].t_start if chain else None
    try:
        return plan_grasp_for_recording(rec.object_model, rec.wrist, t_seed, rec.start_ns, rng, params=planner)
    except GraspError as err:
        warnings.append(f"no grasp: {err}")
        return None
