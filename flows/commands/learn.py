"""``pbd learn RECORDING``: ingest if needed, segment, fit, plan the grasp, store a descriptor version."""

from __future__ import annotations

import argparse
import dataclasses
import json
import sys
from pathlib import Path
from typing import Any

import numpy as np

from tasks.errors import RecordingError, StoreError
from tasks.ingest.api import ingest_recording
from tasks.ingest.object_model import load_object_model
from tasks.learn.api import learn_descriptor
from tasks.learn.params import LearnParams
from tasks.recording.load import load_recording
from tasks.store import Store, resolve_store_root, write_bytes_atomic


def _load(args: argparse.Namespace, store: Any) -> Any:
    """The RecordingData for the RECORDING argument (ingesting it first when it is a file or folder)."""

    source = Path(args.recording)
    if source.exists():
        result = ingest_recording(source, store, topics=args.topics, object_model=args.object_model)
        for w in result.warnings:
            sys.stderr.write(f"pbd learn: {w}\n")
        return load_recording(store, result.recording_id)
    if store.has_recording(args.recording):
        return load_recording(store, args.recording)
    msg = "no such file or folder, nor an ingested recording id"
    raise RecordingError(source, msg)


def run(args: argparse.Namespace) -> int:
    """Learn and store the descriptor; print name@vN, its id and one line per primitive."""

    store = Store(resolve_store_root(args.store))
    if args.out is not None and args.out.exists():
        raise StoreError(args.out, "refusing to overwrite an existing file")
    rec = _load(args, store)
    if args.object_model is not None:
        pts, _ = load_object_model(args.object_model)
        rec = dataclasses.replace(rec, object_model=np.asarray(pts, dtype=np.float64))
    params = LearnParams(segmenter=args.segmenter, classifier=args.classifier, k=args.k, t0=args.t0)
    desc = learn_descriptor(rec, params, name=args.name, rng=np.random.default_rng(args.seed), seed=args.seed)
    if rec.object_model is not None and desc.object.model_sha256 is not None:
        sha, _ = store.put_model(rec.object_model)
        if sha != desc.object.model_sha256:  # pragma: no cover - both hash the same float32 bytes
            msg = f"object model hash mismatch ({sha[:12]} vs {desc.object.model_sha256[:12]})"
            raise StoreError(store.models_dir, msg)
    put = store.put_descriptor(desc)
    for w in desc.extra_provenance.get("warnings", []):
        sys.stderr.write(f"pbd learn: {w}\n")
    status = "new version" if put.created else "unchanged"
    lines = [f"{put.name}@v{put.version} {put.id} ({status}, {len(desc.chain)} primitives)"]
    for i, p in enumerate(desc.chain):
        unit = "rad" if p.kind == "rotation" else "m"
        pos = "" if p.pos is None else " pos [" + ", ".join(f"{v:.4f}" for v in p.pos) + "]"
        dirs = ", ".join(f"{v:.4f}" for v in p.dir)
        span = f" t={p.t_start:.2f}..{p.t_end:.2f} s" if p.t_start is not None and p.t_end is not None else ""
        lines.append(f"  {i}: {p.kind:<11} extent {p.extent:.4f} {unit} dir [{dirs}]{pos}{span}")
    if args.json:
        out = {"ref": f"{put.name}@v{put.version}", "status": status, "path": str(put.path), **desc.to_dict()}
        sys.stdout.write(json.dumps(out, indent=2) + "\n")
    else:
        sys.stdout.write("\n".join(lines) + "\n")
    if args.out is not None:
        write_bytes_atomic(args.out, desc.to_json().encode())
    return 0
