"""Small references passed between the pipeline's Prefect tasks and summarised in the report.

Tasks pass these (ids and paths), never arrays: Prefect persists task results as pickles inside JSON, so the
data itself stays in the store's Parquet, JSON and npz files.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any, Literal

Status = Literal["new", "unchanged", "changed", "failed"]


@dataclass(frozen=True)
class RecordingRef:
    """An ingested recording: its content id (16 hex) and the path it was read from."""

    recording_id: str
    source: str
    lost_messages: int = 0
    warnings: tuple[str, ...] = ()


@dataclass(frozen=True)
class DescriptorRef:
    """One stored descriptor version: ``descriptors/<name>/v<version>.json`` with content id ``id``."""

    name: str
    version: int
    id: str
    path: str
    created: bool

    @property
    def ref(self) -> str:
        """The ``name@vN`` reference of this version."""
        return f"{self.name}@v{self.version}"

    @property
    def previous(self) -> str | None:
        """``name@v(N-1)`` when this is a new version on top of an older one, else None."""
        return f"{self.name}@v{self.version - 1}" if self.created and self.version > 1 else None

    @property
    def status(self) -> Status:
        """new (first version), changed (a new version on top of an older one) or unchanged."""
        if not self.created:
            return "unchanged"
        return "new" if self.version == 1 else "changed"


@dataclass(frozen=True)
class SimulationRef:
    """Outcome of executing a descriptor in simulation; joint traces, when recorded, in the npz at ``trace_path``.

    ``achieved`` and ``target`` hold one value per executed primitive (rad or m), ``joints`` the joint names.
    """

    descriptor_id: str
    scene: str
    success: bool
    achieved: tuple[float, ...]
    target: tuple[float, ...]
    joints: tuple[str, ...] = ()
    trace_path: str | None = None
    detail: str = ""
    skipped: str | None = None
    """Why the descriptor was not executed (no built-in scene for its object), None when it was."""


@dataclass(frozen=True)
class EntryResult:
    """Everything the report says about one recording of a run."""

    source: str
    recording: RecordingRef | None = None
    descriptor: DescriptorRef | None = None
    simulation: SimulationRef | None = None
    diff: dict[str, Any] | None = None
    error: str | None = None
    extra: dict[str, Any] = field(default_factory=dict)

    @property
    def status(self) -> Status:
        """new / unchanged / changed against the previous version, or failed."""
        if self.error is not None or self.descriptor is None:
            return "failed"
        return self.descriptor.status
