"""``pbd transfer DESCRIPTOR --to MODEL``: carry a descriptor to a similar object by registering the models."""

from __future__ import annotations

import argparse
import json
import re
import sys
from pathlib import Path


def add_arguments(parser: argparse.ArgumentParser) -> None:
    """Arguments of ``pbd transfer``."""
    parser.add_argument("descriptor", metavar="DESCRIPTOR", help="file, content id (8+ hex) or name@vN / name@latest")
    parser.add_argument(
        "--to",
        dest="model",
        metavar="MODEL",
        required=True,
        help="target model: PLY, PCD, XYZ, OBJ, STL, OFF, Parquet, npy; or a recording id / file with an object model",
    )
    parser.add_argument("--out", metavar="FILE", default=None, help="also write the transferred descriptor to FILE")
    parser.add_argument("--name", metavar="NAME", default=None, help="descriptor name (default <source>-to-<model>)")
    parser.add_argument("--whole", action="store_true", help="align the whole model, not only its functional part")
    parser.add_argument("--crop-radius", metavar="M", type=float, default=None, help="functional region radius (m)")
    parser.add_argument("--strict", action="store_true", help="a failed grasp re-planning is an error (exit 2)")
    parser.add_argument(
        "--accept-ambiguous",
        action="store_true",
        help="write the best guess even when the registration is poor, ambiguous or loose (default: exit 2)",
    )
    parser.add_argument(
        "--scale-range",
        nargs=2,
        type=float,
        metavar=("LO", "HI"),
        default=None,
        help="target/source size ratios allowed (default 0.6 1.7)",
    )
    parser.add_argument("--json", action="store_true", help="print the outcome (and the candidates' axes) as JSON")
    parser.add_argument("--replan-grasp", action="store_true", help="re-plan the grasp on the target model")
    parser.add_argument("--seed", metavar="N", type=int, default=0, help="random seed (default 0)")


def _label(text: str) -> str:
    """A name usable in descriptor names (``[A-Za-z0-9._-]``)."""
    out = re.sub(r"[^A-Za-z0-9._-]+", "-", text).strip("-._")
    return out or "model"


def run(args: argparse.Namespace) -> int:
    """Register, carry, store; print ``name@vN``, the id and the registration figures."""
    import numpy as np  # noqa: PLC0415

    from schemas.descriptor import ObjectRef  # noqa: PLC0415
    from tasks.errors import TransferError  # noqa: PLC0415
    from tasks.store import Store, resolve_store_root, write_bytes_atomic  # noqa: PLC0415
    from tasks.transfer.api import RegistrationParams, transfer_descriptor  # noqa: PLC0415
    from tasks.transfer.model_io import (  # noqa: PLC0415
        is_recording_ref,
        read_model_file,
        read_recording_model,
        source_model_of,
    )

    if args.crop_radius is not None and not args.crop_radius > 0.0:
        msg = f"--crop-radius {args.crop_radius}: must be positive (metres)"
        raise TransferError(msg)
    store = Store(resolve_store_root(args.store))
    source = store.load(args.descriptor)
    source_points = source_model_of(store, source.object.model_sha256, source.object.model_uri, args.descriptor)
    if is_recording_ref(store, args.model):
        target_points, label, object_name = read_recording_model(store, args.model)
    else:
        path = Path(args.model)
        target_points = read_model_file(path, seed=args.seed)
        label, object_name = str(path), _label(path.stem)
    sha, model_path = store.put_model(target_points)
    target_ref = ObjectRef(object_name, sha, len(target_points), str(model_path))
    scale_range = tuple(args.scale_range) if args.scale_range else RegistrationParams().scale_range
    if not 0.0 < scale_range[0] < scale_range[1]:
        msg = f"--scale-range {scale_range[0]:g} {scale_range[1]:g}: need 0 < LO < HI"
        raise TransferError(msg)
    params = RegistrationParams(crop_radius_m=args.crop_radius, whole=args.whole, scale_range=scale_range)
    name = args.name or f"{source.name}-to-{_label(object_name)}"
    result = transfer_descriptor(
        source,
        source_points,
        target_points,
        target_ref,
        name=name,
        params=params,
        strict=args.strict,
        replan_grasp=args.replan_grasp,
        target_label=label,
        rng=np.random.default_rng(args.seed),
    )
    info = result.descriptor.extra_provenance["transfer"]
    if result.poor and not args.accept_ambiguous:
        if args.json:
            outcome = {"refused": True, "reasons": list(result.reasons), "candidates": info["candidates"]}
            sys.stdout.write(json.dumps(outcome, indent=2) + "\n")
        msg = f"refused: {'; '.join(result.reasons)} (--accept-ambiguous writes the best guess)"
        raise TransferError(msg)
    put = store.put_descriptor(result.descriptor)
    if args.out:
        write_bytes_atomic(Path(args.out), result.descriptor.to_json().encode())
    reg = result.registration
    if args.json:
        outcome = {"refused": False, "name": put.name, "version": put.version, "id": put.id, "transfer": info}
        sys.stdout.write(json.dumps(outcome, indent=2) + "\n")
        return 0
    for warning in result.warnings:
        sys.stderr.write(f"pbd transfer: warning: {warning}\n")
    sys.stdout.write(
        f"{put.name}@v{put.version}{'' if put.created else ' (unchanged)'}\n"
        f"id {put.id}\n"
        f"parent {source.id}\n"
        f"fitness {reg.best.fitness:.3f}  inlier RMSE {reg.best.inlier_rmse_m * 1e3:.2f} mm  "
        f"scale {reg.best.transform.scale:.4f}  axis spread {result.axis_spread_deg:.2f} deg "
        f"{result.axis_spread_mm:.2f} mm  region "
        f"{'whole' if reg.crop_radius_m is None else f'functional (r={reg.crop_radius_m * 1e3:.0f} mm)'}"
        f"{'  POOR (accepted)' if result.poor else ''}\n"
    )
    for i, prim in enumerate(result.descriptor.chain):
        pos_std, dir_std = prim.fit.get("pos_std_m"), prim.fit.get("dir_std_rad")
        pos_text = f"{pos_std * 1e3:.2f} mm, " if isinstance(pos_std, float) else ""
        dir_text = f"{dir_std * 57.29577951308232:.2f} deg" if isinstance(dir_std, float) else "unknown"
        sys.stdout.write(f"axis {i} ({prim.kind}) uncertainty: {pos_text}{dir_text} (one sigma)\n")
    return 0
