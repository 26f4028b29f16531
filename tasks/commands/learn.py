"""``pbd learn RECORDING``: ingest if needed, segment, fit, plan the grasp, store a descriptor version."""

from __future__ import annotations

import argparse
import sys
from pathlib import Path
from typing import Any


def _k(text: str) -> int | str:
    if text == "auto":
        return text
    try:
        k = int(text)
    except ValueError:
        msg = f"--k takes 'auto' or a positive integer, not {text!r}"
        raise argparse.ArgumentTypeError(msg) from None
    if k < 1:
        msg = f"--k must be at least 1, not {k}"
        raise argparse.ArgumentTypeError(msg)
    return k


def add_arguments(parser: argparse.ArgumentParser) -> None:
    """Arguments of ``pbd learn``."""
    parser.add_argument("recording", metavar="RECORDING", help="recording file or folder, or an ingested recording id")
    parser.add_argument("--k", type=_k, default="auto", help="number of segments for --segmenter spectral (or auto)")
    parser.add_argument("--t0", type=float, default=0.05, help="eq. (3) threshold T0 for --classifier eigen")
    parser.add_argument("--segmenter", choices=("changepoint", "spectral"), default="changepoint")
    parser.add_argument("--classifier", choices=("bic", "eigen"), default="bic")
    parser.add_argument("--object-model", type=Path, default=None, help="object model file (.ply .pcd .obj .stl)")
    parser.add_argument("--name", default=None, help="descriptor name (default <action>-<object> from the meta)")
    parser.add_argument("--out", type=Path, default=None, help="also write the descriptor JSON here (never overwrites)")
    parser.add_argument("--topics", type=Path, default=None, help="topic map YAML for ingest")
    parser.add_argument("--seed", type=int, default=0, help="seed for k-means and the grasp planner")


def _load(args: argparse.Namespace, store: Any) -> Any:
    """The RecordingData for the RECORDING argument (ingesting it first when it is a file or folder)."""
    from tasks.errors import RecordingError  # noqa: PLC0415
    from tasks.recording.load import load_recording  # noqa: PLC0415

    source = Path(args.recording)
    if source.exists():
        from tasks.ingest.api import ingest_recording  # noqa: PLC0415

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
    import dataclasses  # noqa: PLC0415

    import numpy as np  # noqa: PLC0415

    from tasks.errors import StoreError  # noqa: PLC0415
    from tasks.learn.api import learn_descriptor  # noqa: PLC0415
    from tasks.learn.params import LearnParams  # noqa: PLC0415
    from tasks.store import Store, resolve_store_root, write_bytes_atomic  # noqa: PLC0415

    store = Store(resolve_store_root(args.store))
    if args.out is not None and args.out.exists():
        raise StoreError(args.out, "refusing to overwrite an existing file")
    rec = _load(args, store)
    if args.object_model is not None:
        from tasks.ingest.object_model import load_object_model  # noqa: PLC0415

        pts, _ = load_object_model(args.object_model)
        rec = dataclasses.replace(rec, object_model=np.asarray(pts, dtype=np.float64))
    params = LearnParams(segmenter=args.segmenter, classifier=args.classifier, k=args.k, t0=args.t0)
    desc = learn_descriptor(rec, params, name=args.name, rng=np.random.default_rng(args.seed))
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
    sys.stdout.write("\n".join(lines) + "\n")
    if args.out is not None:
        write_bytes_atomic(args.out, desc.to_json().encode())
    return 0
