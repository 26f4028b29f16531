"""Flow ``transfer-descriptor``: a stored descriptor carried onto a moved, scaled copy of its object model."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from flows.cli import main
from flows.transfer_descriptor import transfer_descriptor_flow
from schemas.descriptor import Descriptor, ObjectRef, Primitive
from tasks.store import Store
from tasks.synth.record import synthesize
from tests.transfer import shapes

HINGE = np.array([0.5, 0.0, 1.0])


def _door_model(rng: np.random.Generator) -> np.ndarray:
    """A door leaf's surface with a handle block's (metres, world frame, 0.5 mm of noise): asymmetric enough to
    register uniquely."""
    parts = shapes.box(np.array([0.6, 0.02, 0.8]), np.array([0.3, 0.0, 0.0]))
    parts += shapes.box(np.array([0.05, 0.07, 0.1]), np.array([0.525, -0.045, 0.0]))
    points, _ = shapes.sample_parts(parts, 6000, rng)
    return points + rng.normal(scale=5e-4, size=points.shape) + HINGE


def test_transfer_carries_the_axis_and_records_the_parent(prefect_harness: None, tmp_path: Path) -> None:
    store = Store(tmp_path / "store")
    model = _door_model(np.random.default_rng(0))
    sha, path = store.put_model(model)
    chain = (Primitive("rotation", tuple(HINGE), (0.0, 0.0, 1.0), 1.2, 0.5, 2.5),)
    source = store.put_descriptor(
        Descriptor("open-door", "open", ObjectRef("door", sha, len(model), str(path)), None, chain)
    )
    yaw = 0.3
    rot = np.array([[np.cos(yaw), -np.sin(yaw), 0.0], [np.sin(yaw), np.cos(yaw), 0.0], [0.0, 0.0, 1.0]])
    offset, scale = np.array([2.0, 1.0, 0.9]), 1.1
    np.save(tmp_path / "cupboard.npy", (model - model.mean(axis=0)) @ rot.T * scale + offset)

    summary = transfer_descriptor_flow("open-door@v1", str(tmp_path / "cupboard.npy"), store=str(store.root))

    (entry,) = summary["entries"]
    assert entry["descriptor"] == "open-door-to-cupboard@v1"
    carried = store.load("open-door-to-cupboard@v1")
    assert carried.parent == source.id
    expected_pos = rot @ (HINGE - model.mean(axis=0)) * scale + offset
    np.testing.assert_allclose(carried.chain[0].pos, expected_pos, atol=0.01)  # type: ignore[arg-type]
    np.testing.assert_allclose(np.abs(carried.chain[0].dir), [0.0, 0.0, 1.0], atol=0.01)
    assert entry["simulation_skipped"] is not None or entry["simulation_success"] is not None
    assert summary["report"] is not None and Path(summary["report"]).is_file()


@pytest.mark.slow
def test_transfer_to_a_synth_recording_simulates_in_the_instance_it_names(
    prefect_harness: None, tmp_path: Path
) -> None:
    """A descriptor learned on bottle instance 4, carried to the sample recording (bottle instance 1, whose meta
    names scene and seed), is executed in instance 1, not in the nominal bottle."""
    store = Store(tmp_path / "store")
    rec_a = synthesize("bottle", 4, tmp_path / "bottle-4.mcap")
    assert main(["learn", str(rec_a), "--store", str(store.root), "--name", "unscrew-4"]) == 0
    target = Path(__file__).resolve().parents[2] / "data" / "recordings" / "bottle.mcap"

    summary = transfer_descriptor_flow("unscrew-4@v1", str(target), store=str(store.root), report=False)

    (entry,) = summary["entries"]
    assert entry["descriptor"] == "unscrew-4-to-bottle@v1"
    assert entry["simulation_skipped"] is None
    assert entry["simulation_success"] is True
    carried = store.load("unscrew-4-to-bottle@v1")
    assert (store.root / "simulations" / f"{carried.id[:16]}-bottle-s1.npz").is_file()  # instance 1's trace


def _stored_door(store: Store) -> None:
    """``open-door@v1``: a hinge on the door model of ``_door_model``, stored with its model."""
    model = _door_model(np.random.default_rng(0))
    sha, path = store.put_model(model)
    chain = (Primitive("rotation", tuple(HINGE), (0.0, 0.0, 1.0), 1.2, 0.5, 2.5),)
    store.put_descriptor(Descriptor("open-door", "open", ObjectRef("door", sha, len(model), str(path)), None, chain))


def test_transfer_flow_takes_the_cli_options(prefect_harness: None, tmp_path: Path) -> None:
    """``accept_ambiguous`` and ``scale_range`` as ``pbd transfer --accept-ambiguous --scale-range``: a poor
    registration (a noise cloud) fails the run naming why, and is stored as a best guess when accepted; an
    impossible range fails the run in one line before any task; a range the target lies outside finds nothing."""
    store = Store(tmp_path / "store")
    _stored_door(store)
    noise = tmp_path / "noise.npy"
    np.save(noise, np.random.default_rng(4).uniform(-0.3, 0.3, size=(1500, 3)))
    run = {"store": str(store.root), "report": False, "scale_range": (0.1, 10.0), "return_state": True}

    refused = transfer_descriptor_flow("open-door@v1", str(noise), **run)
    assert refused.is_failed()
    assert "refused (accept_ambiguous writes the best guess)" in str(refused.result(raise_on_failure=False))
    assert store.versions("open-door-to-noise") == []

    accepted = transfer_descriptor_flow("open-door@v1", str(noise), accept_ambiguous=True, **run)
    assert accepted.is_completed()
    (entry,) = accepted.result()["entries"]
    assert entry["descriptor"] == "open-door-to-noise@v1"
    assert store.load("open-door-to-noise@v1").extra_provenance["transfer"]["refused"] is True

    bad = transfer_descriptor_flow("open-door@v1", str(noise), **{**run, "scale_range": (2.0, 1.0)})
    assert bad.is_failed() and "--scale-range 2 1: need 0 < LO < HI" in str(bad.result(raise_on_failure=False))
    door = tmp_path / "door.npy"
    np.save(door, _door_model(np.random.default_rng(1)))
    outside = transfer_descriptor_flow("open-door@v1", str(door), **{**run, "scale_range": (3.0, 4.0)})
    assert outside.is_failed()
    assert "no alignment of the models at a scale within 3..4" in str(outside.result(raise_on_failure=False))
