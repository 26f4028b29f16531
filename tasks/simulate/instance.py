"""Which built-in scene instance a descriptor belongs to: the scene and seed a synthesised recording names in its
meta (``/demo/meta``: ``{"scene": ..., "seed": ...}``, as ``pbd synth`` writes it)."""

from __future__ import annotations

from collections.abc import Mapping
from pathlib import Path
from typing import Any

from tasks.recording.load import read_recording_info


def instance_from_meta(meta: Mapping[str, Any]) -> tuple[str | None, int | None]:
    """``(scene, seed)`` named by a recording's meta; None where it names none (a seed that is not an integer
    counts as none, so the nominal instance is used)."""
    scene = meta.get("scene")
    seed = meta.get("seed")
    return (
        scene if isinstance(scene, str) and scene else None,
        seed if isinstance(seed, int) and not isinstance(seed, bool) else None,
    )


def recording_meta(recording_dir: Path) -> dict[str, Any]:
    """The meta of an ingested recording (``recording.json``'s ``meta``; empty when it has none);
    ``RecordingError`` when ``recording.json`` cannot be read."""
    meta = read_recording_info(recording_dir).get("meta")
    return dict(meta) if isinstance(meta, dict) else {}


def descriptor_instance(
    provenance: Mapping[str, Any], recording_meta: Mapping[str, Any] | None
) -> tuple[str | None, int | None]:
    """``(scene, seed)`` of the built-in scene instance a descriptor was learned on: its provenance's ``scene``
    (``{"name", "seed"}``, written by learning), else what its recording's meta names (``recording_meta``, when the
    recording is at hand); ``(None, None)`` when neither names one."""
    named = provenance.get("scene")
    if isinstance(named, Mapping):
        return instance_from_meta({"scene": named.get("name"), "seed": named.get("seed")})
    return instance_from_meta(recording_meta or {})
