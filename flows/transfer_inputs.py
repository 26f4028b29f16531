"""The inputs of a transfer, one definition for ``pbd transfer``, the ``transfer`` task and the
``transfer-descriptor`` flow: the options (checked once, in one place) and the target model read from a file or a
recording. No Prefect here, so ``pbd transfer`` starts without it.
"""

from __future__ import annotations

import dataclasses
import re
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from schemas.descriptor import Descriptor, ObjectRef
from tasks.arrays import Points
from tasks.errors import TransferError
from tasks.store import Store
from tasks.transfer.api import RegistrationParams, TransferResult, transfer_descriptor
from tasks.transfer.model_io import is_recording_ref, read_model_file, read_recording_model


@dataclass(frozen=True)
class TransferOptions:
    """What a transfer is asked to do besides its source and target (``pbd transfer``'s options)."""

    name: str | None = None
    """Name of the carried descriptor (default ``<source>-to-<target object>``)."""
    whole: bool = False
    """Align the whole source model, not only its functional region."""
    crop_radius_m: float | None = None
    """Radius of the functional region (m); None: the registration's default share of the model's size."""
    strict: bool = False
    """A failed grasp re-planning is an error."""
    replan_grasp: bool = False
    """Re-plan the grasp on the target model."""
    seed: int = 0
    """Seed of the registration's sampling (and of reading a mesh as points)."""
    accept_ambiguous: bool = False
    """Store the best guess even when the registration is poor, ambiguous or loose."""
    scale_range: tuple[float, float] | None = None
    """Target/source size ratios allowed (None: the registration's default)."""

    def __post_init__(self) -> None:
        """``TransferError`` (one line, naming the option as ``pbd transfer`` spells it; the flow's parameters
        are ``crop_radius_m`` and ``scale_range``) for a radius or a scale range that cannot be."""
        if self.crop_radius_m is not None and not self.crop_radius_m > 0.0:
            msg = f"--crop-radius {self.crop_radius_m}: must be positive (metres)"
            raise TransferError(msg)
        if self.scale_range is not None:
            if len(self.scale_range) != 2:
                msg = f"--scale-range {' '.join(str(v) for v in self.scale_range)}: need two ratios LO HI"
                raise TransferError(msg)
            lo, hi = (float(v) for v in self.scale_range)
            if not 0.0 < lo < hi:
                msg = f"--scale-range {lo:g} {hi:g}: need 0 < LO < HI"
                raise TransferError(msg)
            object.__setattr__(self, "scale_range", (lo, hi))

    def registration(self) -> RegistrationParams:
        """The registration's settings these options ask for."""
        scale = self.scale_range or RegistrationParams().scale_range
        return RegistrationParams(crop_radius_m=self.crop_radius_m, whole=self.whole, scale_range=scale)

    def to_dict(self) -> dict[str, Any]:
        """JSON-ready options (a cache key's parameters)."""
        out = dataclasses.asdict(self)
        out["scale_range"] = list(self.scale_range) if self.scale_range else None
        return out


def carry(
    source: Descriptor,
    source_points: Points,
    target_points: Points,
    target: ObjectRef,
    *,
    target_label: str,
    options: TransferOptions,
) -> TransferResult:
    """``tasks.transfer.api.transfer_descriptor`` with ``options``: ``source`` (its model ``source_points``) onto
    ``target_points`` (both (n, 3) metres), named ``options.name`` or ``<source>-to-<target object>``."""
    return transfer_descriptor(
        source,
        source_points,
        target_points,
        target,
        name=options.name or f"{source.name}-to-{label(target.name)}",
        params=options.registration(),
        strict=options.strict,
        replan_grasp=options.replan_grasp,
        target_label=target_label,
        rng=np.random.default_rng(options.seed),
    )


def refusal(result: TransferResult, options: TransferOptions, accept: str = "--accept-ambiguous") -> str | None:
    """Why the transfer is refused (a poor, ambiguous or loose registration not accepted), else None; ``accept``
    names the option that accepts it."""
    if result.poor and not options.accept_ambiguous:
        return f"refused ({accept} writes the best guess): {'; '.join(result.reasons)}"
    return None


def label(text: str) -> str:
    """A name usable in descriptor names (``[A-Za-z0-9._-]``)."""
    return re.sub(r"[^A-Za-z0-9._-]+", "-", text).strip("-._") or "model"


@dataclass(frozen=True)
class TargetModel:
    """A transfer's target: its points (metres), the label in the provenance (path or recording id), the object's
    name, and the ingested recording it came from (None for a model file)."""

    points: Points
    label: str
    object_name: str
    recording_id: str | None = None


def read_target(store: Store, model: str, seed: int = 0) -> TargetModel:
    """The target model ``model``: an ingested recording (id or file with an object model), else a model file."""
    if is_recording_ref(store, model):
        points, recording, object_name = read_recording_model(store, model)
        return TargetModel(points, recording, object_name, recording)
    path = Path(model)
    return TargetModel(read_model_file(path, seed=seed), str(path), label(path.stem))
