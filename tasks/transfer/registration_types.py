"""What the registration takes and gives: its settings, one refined alignment, and the outcome.

Lengths in metres (target frame unless named otherwise).
"""

from __future__ import annotations

from dataclasses import dataclass

from tasks.transfer.similarity import Similarity

SIMILAR_SCALE_RANGE = (0.6, 1.7)
"""Scales (target size over source size) a similar object can have: a hand and grasp that worked on the
demonstrated object still fit one 0.6 to 1.7 times its size; beyond that it is another object, and a fit at such
a scale is a part of one model matched onto a part of the other."""


@dataclass(frozen=True)
class RegistrationParams:
    """Settings of ``register_models``; lengths in metres unless named otherwise."""

    scale_range: tuple[float, float] = SIMILAR_SCALE_RANGE
    """Alignments at a scale outside this range are dropped (``pbd transfer --scale-range LO HI``)."""
    crop_radius_m: float | None = None
    """Radius of the functional region around each focus point; None: ``auto_crop_frac`` x source diagonal."""
    auto_crop_frac: float = 0.18
    whole: bool = False
    """Align the whole source model instead of its functional region."""
    fine_voxel_frac: float = 1.0 / 150.0
    """Fine voxel as a fraction of the target's bounding-box diagonal."""
    keep: int | None = None
    """Distinct global candidates refined on the functional part, best coarse score first (None: all of them).
    The coarse score, in normalised space where a partial scan's centroid and radius are not the whole model's,
    does not rank a box's orientations: the fine stage, in metres and both ways, must see each of them."""
    symmetry_candidates: int = 4
    """The best this many also get their half-turns about the source's principal axes refined."""
    ransac_iterations: int = 30_000
    ransac_runs: int = 2
    poor_fitness: float = 0.35
    """Below this final fitness (fraction of used source points with a target point within the threshold) the
    registration is poor."""
    poor_plane_frac: float = 0.45
    """Above this point-to-plane RMSE, as a fraction of the final correspondence threshold, it is poor as well:
    two instances of a built-in scene (other sizes, the same design) fit at 0.14-0.36, a sideboard turned by 90
    degrees at 0.44 (and its two-way score gives it away)."""
    poor_score: float = 0.55
    """Below this two-way score over the scanned surface (``scoring.scan_explained_score``: how much of the scan
    the model explains, and of the model where the scan saw it) it is poor: the right fit of a similar object
    explains most of both, a shrunken source sitting on a patch of the target leaves most of the scan
    unexplained."""
    poor_rank_score: float = 0.3
    """Below this ranking score (the functional part's and the grasped part's two-way fit) it is poor as well:
    right alignments of the benchmark's pairs score 0.6 and more, a sliding door shrunk onto half of another one
    0.12 (its whole-model score 0.59 passes)."""
    min_crop_points: int = 150
    context_weight: float = 0.3
    """Total weight of the rest of the model against the functional part's in the final refinement (0: the
    functional part alone)."""
    max_crop_rescale: float = 1.5
    """The functional-part refinement may change the whole-model scale by at most this factor (else rigid)."""
    grip_frac: float = 0.08
    """Radius of the grasped part's ball around each grip point, as a fraction of the source's diagonal ..."""
    grip_max_m: float = 0.06
    """... and at most this (metres, source frame): about what a Barrett hand closes around, so that on a door
    the lever still fills half the ball rather than a tenth of it."""
    grip_threshold_factor: float = 2.0
    """The grip balls match within this many correspondence thresholds: they tell whether the grasped part is
    there at all (a box's knob or its mirror image's bare face), not how finely it fits, which the functional
    score judges (at 1x a thin mug handle's fit varies by 0.1 between two equally right alignments)."""
    grip_floor: float = 0.05
    """Added to both one-way fitnesses of the grip balls, so a scan missing the grasped part scores all alike."""


@dataclass(frozen=True)
class Alignment:
    """One refined alignment of the source onto the target."""

    transform: Similarity
    fitness: float
    """Fraction of the used source points (functional part or whole) with a target point within ``threshold_m``."""
    inlier_rmse_m: float
    """RMS distance of those inlier pairs, metres (target frame)."""
    plane_rmse_m: float
    """RMS point-to-plane distance of the inlier pairs (raw source points against the target's surface), metres:
    about the scan noise for a good fit, a sizeable fraction of the threshold for a wrong or unrelated one."""
    normal_agreement: float
    """Fraction of the inlier pairs whose surface normals agree (unsigned, within 25 degrees)."""
    model_score: float
    """Geometric mean of the whole models' two one-way fitnesses (how much of each the other explains)."""
    score: float
    """Ranking score: geometric mean of the source->target and the local target->source fitness."""
    start: str
    """Which global start it came from (``pca-<k>``, ``ransac-<k>``, ``fgr``, ``init``)."""
    explained_score: float
    """The whole models' two-way fit over the surface the scan saw (``scoring.scan_explained_score``)."""


@dataclass(frozen=True)
class Registration:
    """Outcome of ``register_models``: the best alignment and the runner-ups (best first)."""

    best: Alignment
    alignments: tuple[Alignment, ...]
    threshold_m: float
    """Final correspondence threshold, metres (target frame)."""
    fine_voxel_m: float
    spacing_m: float
    """Median nearest-neighbour spacing of the target's points, metres."""
    crop_radius_m: float | None
    """Radius of the functional region used, metres (source frame); None when the whole model was used."""
    source_points_used: int
    poor: bool
    warnings: tuple[str, ...]
