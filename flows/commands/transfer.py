"""``pbd transfer DESCRIPTOR --to MODEL``: carry a descriptor to a similar object by registering the models."""

from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path

from flows.transfer_inputs import TransferOptions, carry, read_target, refusal
from schemas.descriptor import ObjectRef
from tasks.errors import TransferError
from tasks.store import Store, model_sha256, resolve_store_root, write_bytes_atomic
from tasks.transfer.model_io import source_model_of


def run(args: argparse.Namespace) -> int:
    """Register, carry, store; print ``name@vN``, the id and the registration figures."""

    options = TransferOptions(
        name=args.name,
        whole=args.whole,
        crop_radius_m=args.crop_radius,
        strict=args.strict,
        replan_grasp=args.replan_grasp,
        seed=args.seed,
        accept_ambiguous=args.accept_ambiguous,
        scale_range=tuple(args.scale_range) if args.scale_range else None,
    )
    store = Store(resolve_store_root(args.store))
    source = store.load(args.descriptor)
    source_points = source_model_of(store, source.object.model_sha256, source.object.model_uri, args.descriptor)
    target = read_target(store, args.model, seed=options.seed)
    sha = model_sha256(target.points)  # stored only once the transfer succeeded
    target_ref = ObjectRef(target.object_name, sha, len(target.points), str(store.model_path(sha)))
    result = carry(source, source_points, target.points, target_ref, target_label=target.label, options=options)
    info = result.descriptor.extra_provenance["transfer"]
    if (refused := refusal(result, options)) is not None:
        if args.json:
            outcome = {"refused": True, "reasons": list(result.reasons), "candidates": info["candidates"]}
            sys.stdout.write(json.dumps(outcome, indent=2) + "\n")
        raise TransferError(refused)
    store.put_model(target.points)
    put = store.put_descriptor(result.descriptor)
    if args.out:
        write_bytes_atomic(Path(args.out), result.descriptor.to_json().encode())
    reg = result.registration
    for warning in result.warnings:
        sys.stderr.write(f"pbd transfer: warning: {warning}\n")
    if args.json:
        out = {
            "ref": f"{put.name}@v{put.version}",
            "created": put.created,
            "id": put.id,
            "parent": source.id,
            "fitness": reg.best.fitness,
            "inlier_rmse_m": reg.best.inlier_rmse_m,
            "scale": reg.best.transform.scale,
            "axis_spread_deg": result.axis_spread_deg,
            "axis_spread_mm": result.axis_spread_mm,
            "crop_radius_m": reg.crop_radius_m,
            "poor": result.poor,
            "refused": False,
            "transfer": info,
        }
        sys.stdout.write(json.dumps(out, indent=2) + "\n")
        return 0
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
