"""``pbd transfer DESCRIPTOR --to MODEL``: carry a descriptor to a similar object by registering the models."""

from __future__ import annotations

import argparse
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
    parser.add_argument("--strict", action="store_true", help="a poor registration is an error (exit 2)")
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
    from tasks.store import Store, model_sha256, resolve_store_root, write_bytes_atomic  # noqa: PLC0415
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
    sha = model_sha256(target_points)  # stored only once the transfer succeeded
    target_ref = ObjectRef(object_name, sha, len(target_points), str(store.model_path(sha)))
    params = RegistrationParams(crop_radius_m=args.crop_radius, whole=args.whole)
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
    store.put_model(target_points)
    put = store.put_descriptor(result.descriptor)
    if args.out:
        write_bytes_atomic(Path(args.out), result.descriptor.to_json().encode())
    reg = result.registration
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
        f"{'  POOR' if result.poor else ''}\n"
    )
    return 0
