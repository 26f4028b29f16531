"""What a simulated execution reports: per-primitive motion against the demonstration, contact, success, time."""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any, Literal

SUCCESS_FRACTION = 0.90
"""A driven joint must reach at least 90% of its demonstrated extent (the usual benchmark criterion)."""
STILL_LINEAR_M_S = 0.1
STILL_ANGULAR_RAD_S = 1.0
"""... and be still at the end: under 0.1 m/s (prismatic) or 1 rad/s (revolute), its mean speed over the last
0.1 s of the final hold."""
CONTACT_KEPT_FRACTION = 0.95
"""The hand kept contact if it touched the object at >= 95% of the control checks after the grasp and at the end."""

StopReason = Literal["extent reached", "stalled", "end of path"]


@dataclass(frozen=True)
class PrimitiveResult:
    """One executed primitive: ``target`` (the demonstrated extent, rad or m) and ``achieved`` joint motion in the
    demonstrated direction (for a joint's first primitive from the scene's start, so motion the grasp already
    caused counts); ``joint`` it drove; ``contact_fraction`` of control checks with hand-object contact;
    ``sim_time_s`` simulated seconds; ``stopped`` why execution moved on; ``end_speed`` joint speed at the end
    (rad/s or m/s: its displacement over the final hold's last 0.1 s); ``success`` = achieved >= 90% target and
    still at the end."""

    index: int
    kind: Literal["rotation", "translation"]
    joint: str
    target: float
    achieved: float
    contact_fraction: float
    sim_time_s: float
    stopped: StopReason
    end_speed: float
    success: bool

    @property
    def fraction(self) -> float:
        """achieved / target (1.0 for a zero target)."""
        return self.achieved / self.target if self.target > 0.0 else 1.0

    def to_dict(self) -> dict[str, Any]:
        """JSON-ready dict."""
        return {
            "index": self.index,
            "kind": self.kind,
            "joint": self.joint,
            "unit": "rad" if self.kind == "rotation" else "m",
            "target": self.target,
            "achieved": self.achieved,
            "fraction": self.fraction,
            "contact_fraction": self.contact_fraction,
            "sim_time_s": self.sim_time_s,
            "stopped": self.stopped,
            "end_speed": self.end_speed,
            "success": self.success,
        }


@dataclass(frozen=True)
class JointTrace:
    """The driven joints' positions over the chain: ``joints`` names, ``t_s`` (n,) simulated seconds since the
    start, ``q`` (n, k) joint positions (rad or m), one row per control check."""

    joints: tuple[str, ...] = ()
    t_s: tuple[float, ...] = ()
    q: tuple[tuple[float, ...], ...] = ()


@dataclass(frozen=True)
class SimulationResult:
    """A whole execution: per-primitive results, whether the grasp closed on the object, whether contact was
    kept, overall ``success``, simulated and wall-clock seconds, base placement (world, metres, [x,y,z,w]),
    ``grasp_mode`` ("constraint" or "friction"), the wall and CPU time of the physics and control loop alone
    (pre-grasp to the end, without loading and base placement), the process CPU time of the whole execution (a
    shared machine's load inflates wall time, not CPU time) and of pybullet's physics steps alone, the driven
    joints' trace (not in ``to_dict``), key-frame PNG paths and notes."""

    descriptor_id: str
    scene: str
    primitives: tuple[PrimitiveResult, ...]
    grasped: bool
    contact_fraction: float
    contact_kept: bool
    success: bool
    sim_time_s: float
    wall_time_s: float
    base_position: tuple[float, float, float]
    base_quat: tuple[float, float, float, float]
    grasp_mode: Literal["constraint", "friction"]
    loop_wall_time_s: float = 0.0
    loop_cpu_time_s: float = 0.0
    cpu_time_s: float = 0.0
    physics_cpu_time_s: float = 0.0
    trace: JointTrace = field(default_factory=JointTrace)
    frames: tuple[str, ...] = ()
    notes: tuple[str, ...] = field(default_factory=tuple)

    @property
    def real_time_factor(self) -> float:
        """Simulated seconds per wall-clock second."""
        return self.sim_time_s / self.wall_time_s if self.wall_time_s > 0 else float("inf")

    def to_dict(self) -> dict[str, Any]:
        """JSON-ready dict (the ``pbd simulate --json`` document)."""
        return {
            "descriptor": self.descriptor_id,
            "scene": self.scene,
            "success": self.success,
            "grasped": self.grasped,
            "contact_kept": self.contact_kept,
            "contact_fraction": self.contact_fraction,
            "grasp_mode": self.grasp_mode,
            "sim_time_s": self.sim_time_s,
            "wall_time_s": self.wall_time_s,
            "loop_wall_time_s": self.loop_wall_time_s,
            "loop_cpu_time_s": self.loop_cpu_time_s,
            "cpu_time_s": self.cpu_time_s,
            "physics_cpu_time_s": self.physics_cpu_time_s,
            "real_time_factor": self.real_time_factor,
            "base": {"position": list(self.base_position), "orientation": list(self.base_quat)},
            "primitives": [p.to_dict() for p in self.primitives],
            "frames": list(self.frames),
            "notes": list(self.notes),
        }
