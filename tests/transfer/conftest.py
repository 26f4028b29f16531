"""Fixtures of the transfer tests: a bottle model and a descriptor learned on it (cap twist)."""

from __future__ import annotations

import numpy as np
import pytest

from schemas.descriptor import Descriptor, Grasp, ObjectRef, Primitive
from tasks.store import Store
from tests.transfer import shapes


@pytest.fixture(scope="session")
def bottle_model() -> shapes.ShapeModel:
    """A sampled bottle (metres, object frame, z up) with its cap axis."""
    return shapes.bottle(np.random.default_rng(7), n=3000)


def make_descriptor(model: shapes.ShapeModel, sha: str | None, uri: str | None = None) -> Descriptor:
    """A cap-twist descriptor on ``model``: a rotation about the cap axis, a lift, a grasp above the cap."""
    top = model.axis_pos
    return Descriptor(
        name="twist-cap",
        action="twist",
        object=ObjectRef("bottle", sha, len(model.points) if sha else 0, uri),
        grasp=Grasp("barrett", (0.4, -0.1), (float(top[0]), float(top[1]), float(top[2] + 0.05)), (1.0, 0.0, 0.0, 0.0)),
        chain=(
            Primitive("rotation", (float(top[0]), float(top[1]), float(top[2])), (0.0, 0.0, 1.0), 3.0, 0.5, 2.0),
            Primitive("translation", None, (0.0, 0.0, 1.0), 0.04, 2.0, 2.5),
        ),
        recording_id="0123456789abcdef",
        parameters={"k": "auto"},
        code_version="test",
    )


@pytest.fixture
def stored_descriptor(store: Store, bottle_model: shapes.ShapeModel) -> Descriptor:
    """The cap-twist descriptor stored with its model in the test store."""
    sha, path = store.put_model(bottle_model.points)
    desc = make_descriptor(bottle_model, sha, str(path))
    store.put_descriptor(desc)
    return desc
