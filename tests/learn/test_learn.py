"""learn_descriptor on synthetic demonstrations with known chains and on real Sturm tracks; bad input."""

from __future__ import annotations

import dataclasses
from pathlib import Path

import numpy as np
import pytest

from tasks.errors import FitError
from tasks.fit.geometry import angle_between_axes, point_line_distance
from tasks.learn.api import default_name, learn_chain, learn_descriptor, model_sha256
from tasks.learn.params import LearnParams
from tasks.recording.load import MarkerTrack, RecordingData
from tests.conftest import REAL
from tests.learn.synthetic import START_NS, make_demo, to_recording

STURM = REAL / "sturm" / "mechanisms_iros_2010"
RNG = np.random.default_rng


def sturm_recording(path: Path, hz: float = 30.0) -> RecordingData:
    """A Sturm log as one PointStamped-like marker at ``hz`` (in memory)."""
    pts = np.loadtxt(path)
    stamps = START_NS + np.round(np.arange(len(pts)) * 1e9 / hz).astype(np.int64)
    marker = MarkerTrack("/gripper", stamps, pts)
    return RecordingData(path.stem, path.parent, {"start_ns": START_NS}, {"/gripper": marker}, {}, None, {})


@pytest.mark.parametrize(("scene", "seed"), [("microwave", 0), ("drawer", 1), ("bottle", 2), ("door", 3)])
def test_synthetic_scenes_give_the_true_chain(scene: str, seed: int) -> None:
    demo = make_demo(scene, RNG(seed), noise_m=0.0005, hz=100.0)
    desc = learn_descriptor(to_recording(demo), LearnParams(), rng=RNG(0))
    assert [p.kind for p in desc.chain] == [t.kind for t in demo.chain]
    for got, truth in zip(desc.chain, demo.chain, strict=True):
        assert angle_between_axes(np.array(got.dir), truth.dir) < np.radians(1.0)
        assert got.extent >= 0.0
        if truth.kind == "rotation":
            assert got.pos is not None
            assert point_line_distance(np.array(got.pos), truth.pos, truth.dir) < 0.003
            assert abs(got.extent - truth.extent) < np.radians(1.5)
        else:
            assert abs(got.extent - truth.extent) < 0.002
        assert got.t_start is not None and got.t_end is not None
        assert got.t_start < truth.t_end and got.t_end > truth.t_start
        assert got.fit["rms_m"] < 0.002
        assert "dir_std_rad" in got.fit
        judged = set(got.fit["scores"]) | set(got.fit.get("ruled_out", []))
        assert judged == {"still", "translation", "rotation", "undefined"}
    assert desc.name == f"open-{scene}"
    assert desc.parameters["segmenter"] == "changepoint"
    assert len(desc.code_version) == 12


def test_same_input_same_id_and_marker_order_does_not_matter() -> None:
    demo = make_demo("door", RNG(5), hz=60.0)
    rec = to_recording(demo)
    first = learn_descriptor(rec, LearnParams(), rng=RNG(0))
    again = learn_descriptor(rec, LearnParams(), rng=RNG(0))
    shuffled = dataclasses.replace(rec, markers=dict(reversed(list(rec.markers.items()))))
    other = learn_descriptor(shuffled, LearnParams(), rng=RNG(0))
    assert first.id == again.id == other.id
    assert [p.markers for p in first.chain] == [p.markers for p in other.chain]


def test_thumb_and_object_are_one_primitive() -> None:
    demo = make_demo("drawer", RNG(6), hz=60.0)
    desc = learn_descriptor(to_recording(demo), LearnParams(), rng=RNG(0))
    assert len(desc.chain) == 1
    assert set(desc.chain[0].markers) == {"/mocap/drawer_0", "/mocap/drawer_1", "/mocap/thumb"}


@pytest.mark.parametrize(
    ("folder", "log", "kind", "radius"),
    [("left_door", "001", "rotation", 0.344), ("right_door", "005", "rotation", 0.385),
     ("dishwasher", "004", "rotation", 0.656), ("drawer", "007", "translation", None)],
)  # fmt: skip
def test_real_sturm_tracks_are_classified_right(folder: str, log: str, kind: str, radius: float | None) -> None:
    rec = sturm_recording(STURM / folder / f"{log}.log")
    result = learn_chain(rec, LearnParams(), RNG(0))
    assert [p.kind for p in result.chain] == [kind]
    if radius is not None:
        assert abs(result.chain[0].fit["radii_m"][0] - radius) < 0.03


@pytest.mark.slow
def test_paper_baseline_runs_with_given_k() -> None:
    rec = sturm_recording(STURM / "drawer" / "002.log")
    result = learn_chain(rec, LearnParams.paper_baseline(k=1), RNG(0))
    assert [p.kind for p in result.chain] == ["translation"]
    demo = make_demo("microwave", RNG(7), hz=50.0)
    base = learn_chain(to_recording(demo), LearnParams.paper_baseline(k=5), RNG(0))
    assert len(base.segments) >= 2
    assert all(s.kind in ("still", "rotation", "translation", "undefined") for s in base.segments)


def test_object_model_reference_and_default_names() -> None:
    demo = make_demo("microwave", RNG(8), hz=50.0)
    model = RNG(1).normal(size=(20, 3))  # fewer points than a grasp needs: the reference is kept, no grasp planned
    rec = dataclasses.replace(to_recording(demo), object_model=model)
    desc = learn_descriptor(rec, LearnParams(), name="my demo!", rng=RNG(0))
    assert desc.grasp is None
    assert any(w.startswith("no grasp:") for w in desc.extra_provenance["warnings"])
    assert desc.name == "my-demo"
    assert desc.object.model_sha256 == model_sha256(model)
    assert desc.object.model_points == 20
    bare = dataclasses.replace(rec, meta={}, info={"start_ns": START_NS, "source": "/x/open_door.bag"})
    assert default_name(bare) == "open_door"


# -- bad input -----------------------------------------------------------------------------------------------


def _rec(markers: dict[str, MarkerTrack]) -> RecordingData:
    return RecordingData("bad", Path("bad"), {"start_ns": START_NS}, markers, {}, None, {})


def _track(name: str, pts: np.ndarray, hz: float = 100.0) -> MarkerTrack:
    return MarkerTrack(name, START_NS + np.round(np.arange(len(pts)) * 1e9 / hz).astype(np.int64), pts)


def test_no_markers_is_an_error() -> None:
    with pytest.raises(FitError, match="recording bad has no marker tracks"):
        learn_chain(_rec({}), LearnParams(), RNG(0))


def test_all_markers_still_is_an_error_naming_them() -> None:
    still = RNG(0).normal(0.0, 0.0003, (300, 3))
    with pytest.raises(FitError, match=r"every marker is still \(/m/a, /m/b\)"):
        learn_chain(_rec({"/m/a": _track("/m/a", still), "/m/b": _track("/m/b", still + 1.0)}), LearnParams(), RNG(0))


def test_all_nan_markers_are_an_error_and_one_nan_marker_a_warning() -> None:
    nan = np.full((50, 3), np.nan)
    with pytest.raises(FitError, match="marker /m/a: every sample is NaN"):
        learn_chain(_rec({"/m/a": _track("/m/a", nan)}), LearnParams(), RNG(0))
    demo = make_demo("drawer", RNG(9), hz=50.0)
    rec = to_recording(demo)
    markers = dict(rec.markers)
    markers["/mocap/lost"] = _track("/mocap/lost", nan)
    pts = markers["/mocap/drawer_0"].points.copy()
    pts[100:110] = np.nan  # a dropout
    markers["/mocap/drawer_0"] = dataclasses.replace(markers["/mocap/drawer_0"], points=pts)
    result = learn_chain(dataclasses.replace(rec, markers=markers), LearnParams(), RNG(0))
    assert [p.kind for p in result.chain] == ["translation"]
    assert "marker /mocap/lost: every sample is NaN, infinite or beyond 1000 m; left out" in result.warnings
    assert "marker /mocap/drawer_0: 10 NaN samples dropped" in result.warnings


def test_infinite_and_absurd_samples_are_dropped_and_backward_stamps_warned() -> None:
    demo = make_demo("drawer", RNG(9), hz=50.0)
    rec = to_recording(demo)
    markers = dict(rec.markers)
    track = markers["/mocap/drawer_0"]
    pts = track.points.copy()
    pts[100:103] = np.inf
    pts[200:202] = 1e300  # a corrupt sample, not a motion
    stamps = track.stamps_ns.copy()
    stamps[[250, 251]] = stamps[[251, 250]]  # two samples out of order
    markers["/mocap/drawer_0"] = dataclasses.replace(track, points=pts, stamps_ns=stamps)
    result = learn_chain(dataclasses.replace(rec, markers=markers), LearnParams(), RNG(0))
    assert [p.kind for p in result.chain] == ["translation"]
    assert "marker /mocap/drawer_0: 3 infinite samples, 2 samples beyond 1000 m dropped" in result.warnings
    assert "marker /mocap/drawer_0: 1 time stamps go backwards; samples sorted by time" in result.warnings
    huge = np.full((50, 3), 1e300)
    with pytest.raises(FitError, match="marker /m/a: every sample is NaN, infinite or beyond 1000 m"):
        learn_chain(_rec({"/m/a": _track("/m/a", huge)}), LearnParams(), RNG(0))


def test_too_few_samples_and_too_short_recordings_are_errors() -> None:
    with pytest.raises(FitError, match=r"marker /m/a t=0.000..0.040 s: only 5 samples"):
        learn_chain(_rec({"/m/a": _track("/m/a", np.zeros((5, 3)))}), LearnParams(), RNG(0))
    short = np.linspace(0.0, 0.1, 20)[:, None] * np.ones(3)
    with pytest.raises(FitError, match=r"marker /m/a t=0.000..0.190 s: recording lasts 0.190 s"):
        learn_chain(_rec({"/m/a": _track("/m/a", short)}), LearnParams(), RNG(0))


def test_spectral_k_larger_than_the_samples_is_an_error() -> None:
    pts = np.linspace(0.0, 0.3, 40)[:, None] * np.array([1.0, 0.0, 0.0])
    with pytest.raises(FitError, match=r"marker /m/a t=0.000..0.390 s: k=60 segments but only 40 samples"):
        learn_chain(_rec({"/m/a": _track("/m/a", pts)}), LearnParams.paper_baseline(k=60), RNG(0))


def test_rigid_body_orientations_give_the_turn() -> None:
    from scipy.spatial.transform import Rotation

    from tasks.recording.load import PoseTrack

    rng = RNG(12)
    t = np.arange(0.0, 5.0, 0.01)
    s = np.clip((t - 1.5) / 2.0, 0.0, 1.0)
    angle = 2.5 * (10 * s**3 - 15 * s**4 + 6 * s**5)
    axis_pos = np.array([0.3, -0.2, 0.9])
    pts = axis_pos + np.column_stack([0.01 * np.cos(angle), 0.01 * np.sin(angle), np.zeros_like(t)])
    pts += rng.normal(0.0, 0.0005, pts.shape)
    quats = Rotation.from_rotvec(np.outer(angle, [0.0, 0.0, 1.0])) * Rotation.from_rotvec([0.002, 0.0, 0.0])
    stamps = START_NS + np.round(t * 1e9).astype(np.int64)
    name = "/mocap/cap_body"
    rec = RecordingData(
        "pose", Path("pose"), {"start_ns": START_NS}, {name: MarkerTrack(name, stamps, pts)},
        {name: PoseTrack(name, "markers", stamps, pts, quats.as_quat())}, None, {},
    )  # fmt: skip
    (prim,) = learn_chain(rec, LearnParams(), RNG(0)).chain
    assert prim.kind == "rotation"
    assert abs(prim.extent - 2.5) < np.radians(0.2)
    assert angle_between_axes(np.array(prim.dir), np.array([0.0, 0.0, 1.0])) < np.radians(2.0)
