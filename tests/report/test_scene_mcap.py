"""The axes MCAP: foxglove.SceneUpdate messages that put the fitted axes where the descriptor says."""

from __future__ import annotations

import io
import json

import numpy as np
from hypothesis import given, settings
from hypothesis import strategies as st
from mcap.reader import make_reader

from schemas.descriptor import Descriptor, ObjectRef, Primitive
from tasks.report.plots import quat_to_matrix
from tasks.report.scene_mcap import SCENE_SCHEMA_NAME, SCENE_TOPIC, axes_mcap_bytes, quat_x_to, scene_update


def _descriptor() -> Descriptor:
    chain = (
        Primitive("rotation", (0.5, 0.0, 1.0), (0.0, 0.0, 1.0), 1.2, 0.5, 2.0, ("/mocap/m0",)),
        Primitive("translation", None, (0.0, 1.0, 0.0), 0.3, 2.5, 3.5, ("/mocap/m1",)),
    )
    return Descriptor("open-microwave", "open", ObjectRef("microwave"), None, chain)


@settings(max_examples=60, deadline=None)
@given(st.lists(st.floats(-1, 1), min_size=3, max_size=3).filter(lambda v: np.linalg.norm(v) > 1e-3))
def test_quat_x_to_turns_x_onto_the_direction(direction: list[float]) -> None:
    d = np.asarray(direction) / np.linalg.norm(direction)
    rotated_x = quat_to_matrix(quat_x_to(d))[:, 0]
    np.testing.assert_allclose(rotated_x, d, atol=1e-6)


def test_quat_x_to_handles_the_opposite_direction() -> None:
    np.testing.assert_allclose(quat_to_matrix(quat_x_to((-1.0, 0.0, 0.0)))[:, 0], [-1.0, 0.0, 0.0], atol=1e-12)


def test_axes_mcap_round_trip() -> None:
    desc = _descriptor()
    start_ns = 1_700_000_000_123_456_789
    update = scene_update(desc, start_ns, "world", {1: (0.1, 0.2, 0.3)})
    data = axes_mcap_bytes([(start_ns, update)])
    reader = make_reader(io.BytesIO(data))
    messages = list(reader.iter_messages())
    assert len(messages) == 1
    schema, channel, message = messages[0]
    assert schema is not None
    assert schema.name == SCENE_SCHEMA_NAME
    assert schema.encoding == "jsonschema"
    assert channel.topic == SCENE_TOPIC
    assert channel.message_encoding == "json"
    assert message.log_time == start_ns
    decoded = json.loads(message.data)
    entities = decoded["entities"]
    assert [e["id"] for e in entities] == ["open-microwave/0", "open-microwave/1"]
    assert entities[0]["timestamp"] == {"sec": 1_700_000_000, "nsec": 123_456_789}
    assert entities[0]["frame_id"] == "world"
    rot_pose = entities[0]["arrows"][0]["pose"]
    assert rot_pose["position"] == {"x": 0.5, "y": 0.0, "z": 1.0}
    q = rot_pose["orientation"]
    np.testing.assert_allclose(quat_to_matrix((q["x"], q["y"], q["z"], q["w"]))[:, 0], [0, 0, 1], atol=1e-12)
    assert len(entities[0]["lines"]) == 1  # the line through the rotation axis
    trans_pose = entities[1]["arrows"][0]["pose"]
    assert trans_pose["position"] == {"x": 0.1, "y": 0.2, "z": 0.3}  # starts where the segment starts
    assert entities[1]["arrows"][0]["shaft_length"] + entities[1]["arrows"][0]["head_length"] == 0.3
