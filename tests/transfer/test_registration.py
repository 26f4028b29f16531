"""Registration recovers a known similarity; a descriptor's axes move with it."""

from __future__ import annotations

from dataclasses import replace

import numpy as np
import open3d as o3d
import pytest

from schemas.descriptor import ObjectRef
from tasks.errors import GraspError, TransferError
from tasks.transfer.api import RegistrationParams, register_models, transfer_descriptor
from tasks.transfer.carry import carry_grasp, grip_points
from tasks.transfer.clouds import check_model
from tasks.transfer.global_starts import global_starts
from tasks.transfer.similarity import Similarity, angle_between_deg, point_line_distance
from tests.transfer import shapes

from .conftest import make_descriptor

FAST = RegistrationParams(ransac_iterations=20_000, ransac_runs=1, keep=6)
ANY_SCALE = RegistrationParams(ransac_iterations=20_000, ransac_runs=1, keep=6, scale_range=(0.1, 10.0))
"""For unrelated targets: the fit itself is judged, not the scale bound."""


def _rotation_angle_deg(a: np.ndarray, b: np.ndarray) -> float:
    return float(np.degrees(np.arccos(np.clip((np.trace(a.T @ b) - 1.0) / 2.0, -1.0, 1.0))))


@pytest.mark.parametrize(("scale", "seed"), [(0.8, 11), pytest.param(1.3, 12, marks=pytest.mark.slow)])
def test_known_similarity_is_recovered(bottle_model: shapes.ShapeModel, scale: float, seed: int) -> None:
    rng = np.random.default_rng(seed)
    truth = Similarity(scale, shapes.random_rotation(rng), np.array([0.3, -0.2, 0.5]))
    target = truth.apply_points(bottle_model.points) + rng.normal(scale=3e-4, size=bottle_model.points.shape)
    reg = register_models(bottle_model.points, target, focus=bottle_model.focus, params=FAST, rng=rng)
    est = reg.best.transform
    assert est.scale == pytest.approx(scale, rel=0.02)  # fitted on the cap region: the axis is what is sharp
    # a bottle is symmetric about its axis: compare what is defined, the axis and the points on it
    axis_true = truth.apply_direction(bottle_model.axis_dir)
    assert angle_between_deg(est.apply_direction(bottle_model.axis_dir), axis_true) < 1.0
    assert np.linalg.norm(est.apply_point(bottle_model.axis_pos) - truth.apply_point(bottle_model.axis_pos)) < 1e-3
    assert reg.best.fitness > 0.8
    assert not reg.poor
    assert reg.crop_radius_m is not None


@pytest.mark.slow
def test_asymmetric_shape_recovers_the_full_rotation() -> None:
    rng = np.random.default_rng(21)
    mug = shapes.mug(rng, n=4000)
    truth = Similarity(1.3, shapes.random_rotation(rng), np.array([-0.1, 0.4, 0.2]))
    target = truth.apply_points(mug.points) + rng.normal(scale=3e-4, size=mug.points.shape)
    reg = register_models(mug.points, target, params=RegistrationParams(whole=True, keep=6), rng=rng)
    assert _rotation_angle_deg(reg.best.transform.rotation, truth.rotation) < 1.0
    assert reg.best.transform.scale == pytest.approx(1.3, rel=0.01)
    assert np.linalg.norm(reg.best.transform.translation - truth.translation) < 2e-3
    assert reg.crop_radius_m is None


def test_descriptor_moves_with_the_object(bottle_model: shapes.ShapeModel) -> None:
    rng = np.random.default_rng(31)
    truth = Similarity(0.8, shapes.random_rotation(rng), np.array([1.0, 2.0, 0.5]))
    target = truth.apply_points(bottle_model.points) + rng.normal(scale=3e-4, size=bottle_model.points.shape)
    desc = make_descriptor(bottle_model, "a" * 64)
    ref = ObjectRef("bottle-b", "b" * 64, len(target), "models/b.parquet")
    out = transfer_descriptor(desc, bottle_model.points, target, ref, params=FAST, target_label="b.ply", rng=rng)
    new = out.descriptor
    rot, tra = new.chain
    assert angle_between_deg(np.array(rot.dir), truth.apply_direction(np.array([0.0, 0.0, 1.0]))) < 1.0
    assert point_line_distance(truth.apply_point(bottle_model.axis_pos), np.array(rot.pos), np.array(rot.dir)) < 1e-3
    assert rot.extent == pytest.approx(3.0)
    assert tra.extent == pytest.approx(0.04 * 0.8, rel=0.01)
    assert new.parent == desc.id
    assert new.name == "twist-cap-to-bottle-b"
    assert new.object == ref
    assert new.grasp is not None
    assert desc.grasp is not None
    # the hand keeps its size: the wrist offset from the grasped part (the cap's top) turns but does not scale
    (anchor,) = grip_points(desc, bottle_model.points)
    wrist = truth.apply_point(anchor) + truth.rotation @ (np.array(desc.grasp.wrist_position) - anchor)
    assert np.linalg.norm(np.array(new.grasp.wrist_position) - wrist) < 2e-3
    scaled = truth.apply_point(np.array(desc.grasp.wrist_position))
    assert np.linalg.norm(np.array(new.grasp.wrist_position) - scaled) > 5e-3  # 0.2 x the 50 mm offset
    info = new.to_dict()["provenance"]["transfer"]
    assert info["scale"] == pytest.approx(0.8, rel=0.01)
    assert info["fitness"] > 0.8
    assert info["source"]["id"] == desc.id
    assert info["target_model"] == "b.ply"
    assert info["axis_spread_deg"] < 1.0
    rot_info, tra_info = info["axes"]  # the cap's axis placed and checked; a translation has no axis point
    assert rot_info["region_points"] > 40
    assert rot_info["back_fitness"] > 0.9
    assert rot_info["placed_by"] == rot_info["direction_by"] == "symmetry"  # the cap on its bottle's body axis
    assert tra_info["direction_by"] != "symmetry"
    assert tra_info["region_points"] == 0
    assert tra_info["back_fitness"] is None
    assert np.array(info["transform"]).shape == (4, 4)


@pytest.mark.slow
def test_unrelated_target_is_poor_and_strict_refuses(bottle_model: shapes.ShapeModel) -> None:
    rng = np.random.default_rng(41)
    noise = rng.uniform(-0.2, 0.2, size=(1500, 3))
    desc = make_descriptor(bottle_model, "a" * 64)
    ref = ObjectRef("noise", "c" * 64, len(noise))
    out = transfer_descriptor(desc, bottle_model.points, noise, ref, params=ANY_SCALE, rng=rng)
    assert out.poor
    assert any(w.startswith("poor registration") for w in out.warnings)
    assert out.descriptor.to_dict()["provenance"]["transfer"]["poor"] is True
    with pytest.raises(TransferError, match=r"poor registration: .* \(--strict\)"):
        transfer_descriptor(desc, bottle_model.points, noise, ref, params=ANY_SCALE, strict=True, rng=rng)


@pytest.mark.slow
def test_replan_grasp_plans_on_the_target(bottle_model: shapes.ShapeModel) -> None:
    rng = np.random.default_rng(51)
    target = bottle_model.points * 1.1
    desc = make_descriptor(bottle_model, "a" * 64)
    ref = ObjectRef("b", "d" * 64, len(target))
    out = transfer_descriptor(desc, bottle_model.points, target, ref, params=FAST, replan_grasp=True, rng=rng)
    carried = carry_grasp(desc.grasp, out.registration.best.transform) if desc.grasp else None
    assert out.descriptor.grasp is not None and carried is not None
    assert out.descriptor.grasp.quality != carried.quality  # planned anew: its own qualities
    assert not any("re-planning failed" in w for w in out.warnings)


@pytest.mark.slow
def test_replan_failure_warns_or_refuses_under_strict(
    bottle_model: shapes.ShapeModel, monkeypatch: pytest.MonkeyPatch
) -> None:
    from tasks.grasp import api as grasp_api

    def refuse(*args: object, **kwargs: object) -> None:
        raise GraspError("nothing reachable")

    monkeypatch.setattr(grasp_api, "plan_grasp", refuse)  # the planner is not under test here
    rng = np.random.default_rng(53)
    pts = bottle_model.points
    desc = make_descriptor(bottle_model, "a" * 64)
    ref = ObjectRef("b", "d" * 64, len(pts))
    out = transfer_descriptor(desc, pts, pts, ref, params=FAST, replan_grasp=True, rng=rng)
    assert "grasp re-planning failed (nothing reachable); kept the carried grasp" in out.warnings
    assert out.descriptor.grasp is not None and out.descriptor.grasp.eigengrasps == (0.4, -0.1)
    with pytest.raises(TransferError, match="grasp re-planning on the target model failed: nothing reachable"):
        transfer_descriptor(desc, pts, pts, ref, params=FAST, replan_grasp=True, strict=True, rng=rng)


@pytest.mark.slow
def test_replan_without_force_closure_keeps_the_carried_grasp(bottle_model: shapes.ShapeModel) -> None:
    rng = np.random.default_rng(54)
    desc = make_descriptor(bottle_model, "a" * 64)
    assert desc.grasp is not None
    top = bottle_model.axis_pos
    # a palm 0.4 m above the cap approaching sideways: the planner closes the hand on nothing (0 contacts)
    away = replace(desc.grasp, wrist_position=(float(top[0]), float(top[1]), float(top[2] + 0.4)),
                   wrist_orientation=(0.0, 0.7071068, 0.0, 0.7071068))  # fmt: skip
    desc = desc.with_grasp(away)
    target = bottle_model.points * 1.1
    ref = ObjectRef("b", "d" * 64, len(target))
    out = transfer_descriptor(desc, bottle_model.points, target, ref, params=FAST, replan_grasp=True, rng=rng)
    assert "the re-planned grasp has no force closure (0 contacts); kept the carried grasp" in out.warnings
    assert out.descriptor.grasp is not None
    assert out.descriptor.grasp.eigengrasps == (0.4, -0.1)  # the carried one
    assert not out.poor  # the registration itself is fine
    with pytest.raises(TransferError, match=r"no force closure \(0 contacts\) \(--strict\)"):
        transfer_descriptor(
            desc, bottle_model.points, target, ref, params=FAST, replan_grasp=True, strict=True,
            rng=np.random.default_rng(54),
        )  # fmt: skip


def test_replan_without_a_grasp_warns(bottle_model: shapes.ShapeModel) -> None:
    rng = np.random.default_rng(52)
    desc = make_descriptor(bottle_model, "a" * 64).with_grasp(None)
    ref = ObjectRef("b", "d" * 64, len(bottle_model.points))
    pts = bottle_model.points
    out = transfer_descriptor(desc, pts, pts, ref, params=FAST, replan_grasp=True, rng=rng)
    assert "no grasp to re-plan: the source descriptor has none" in out.warnings
    assert out.descriptor.grasp is None


@pytest.mark.parametrize(
    ("points", "match"),
    [
        (np.zeros((10, 2)), r"source model: expected shape \(n, 3\)"),
        (np.ones((20, 3)), "source model: 20 finite points, need at least 30"),
        (np.ones((40, 3)), "source model: all points coincide"),
        (np.full((100, 3), np.nan), "source model: 0 finite points"),
    ],
)
def test_unusable_clouds_are_refused(points: np.ndarray, match: str) -> None:
    with pytest.raises(TransferError, match=match):
        check_model(points, "source model")


@pytest.mark.slow
def test_flat_sheet_has_no_alignment_at_a_similar_objects_scale(bottle_model: shapes.ShapeModel) -> None:
    rng = np.random.default_rng(71)
    sheet = np.column_stack([rng.uniform(-0.1, 0.1, 3000), rng.uniform(-0.1, 0.1, 3000), np.zeros(3000)])
    with pytest.raises(TransferError, match=r"no alignment of the models at a scale within 0\.6\.\.1\.7"):
        register_models(bottle_model.points, sheet, focus=bottle_model.focus, params=FAST, rng=rng)


def test_global_starts_repeat_whatever_ran_before(bottle_model: shapes.ShapeModel) -> None:
    """The same clouds and seed give the same candidates, with other registrations run in between: open3d's
    parallel RANSAC would draw its seeded samples in whatever order its threads reach the generator."""
    rng = np.random.default_rng(12)
    fat = shapes.bottle(rng, n=3000, radius=0.042, cap_radius=0.021)
    target = Similarity(1.1, shapes.random_rotation(rng), np.array([0.3, 0.1, -0.2])).apply_points(fat.points)
    target, _ = shapes.partial_scan(target, fat.normals, rng, 0.6, view=False)
    other = shapes.mug(np.random.default_rng(2), n=3000).points
    params = RegistrationParams(ransac_iterations=100_000, ransac_runs=2)
    runs = []
    threads = o3d.utility.get_max_threads()
    for k in range(3):
        if k:
            global_starts(other, target, span_t=0.3, params=params, rng=np.random.default_rng(k), init=None)
        got = global_starts(
            bottle_model.points, target, span_t=0.3, params=params, rng=np.random.default_rng(5), init=None
        )
        runs.append([(name, t.matrix()) for name, t in got])
    for run in runs[1:]:
        assert [n for n, _ in run] == [n for n, _ in runs[0]]
        for (_, a), (_, b) in zip(run, runs[0], strict=True):
            np.testing.assert_array_equal(a, b)
    assert o3d.utility.get_max_threads() == threads


def test_every_distinct_orientation_of_a_box_reaches_the_fine_stage() -> None:
    """The coarse stage works in normalised space, where a partial scan's centroid and radius are not the whole
    model's: its score does not rank a box's orientations, so it only removes duplicates and the fine stage sees
    every one of them (a cut at the best ten can drop the true one)."""
    rng = np.random.default_rng(31)
    model = shapes.drawer(rng, n=4000)
    truth = Similarity(0.94, shapes.random_rotation(rng), np.array([0.2, -0.1, 0.6]))
    scan, _ = shapes.partial_scan(
        truth.apply_points(model.points), model.normals @ truth.rotation.T, rng, 0.5, view=True
    )
    scan = scan + rng.normal(scale=1.5e-3, size=scan.shape)
    params = RegistrationParams(ransac_iterations=20_000, ransac_runs=1)
    starts = global_starts(model.points, scan, span_t=0.5, params=params, rng=rng, init=None)
    own = [t for name, t in starts if "flip" not in name]
    assert len(own) > 10  # the 24 orientations of the principal axes, less those that converge together
    assert min(_rotation_angle_deg(t.rotation, truth.rotation) for _, t in starts) < 10.0


def test_a_model_listing_each_point_twice_is_the_model_listed_once(bottle_model: shapes.ShapeModel) -> None:
    """A mesh exported with each vertex repeated per face: its repeated points are kept once, in their first
    places (the median spacing of a cloud of pairs is 0, and its normals would have no neighbourhood)."""
    twice = np.repeat(bottle_model.points, 2, axis=0)
    np.testing.assert_array_equal(check_model(twice, "target model"), bottle_model.points)
    few = np.repeat(bottle_model.points[:20], 3, axis=0)
    with pytest.raises(TransferError, match="target model: 20 distinct points, need at least 30"):
        check_model(few, "target model")
