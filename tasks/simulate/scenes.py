"""Built-in scenes (``tasks.scenes``, issue 3) as simulation set-ups."""

from __future__ import annotations

import numpy as np

from tasks.errors import SceneError
from tasks.simulate.execute import SceneSetup


def scene_setup(name: str, rng: np.random.Generator | None) -> SceneSetup:  # noqa: ARG001 - until scenes land
    """The set-up of built-in scene ``name`` (randomised by ``rng``); ``SceneError`` for an unknown name."""
    msg = f"unknown scene {name!r}: built-in scenes are not available yet (issue 3); use --urdf FILE"
    raise SceneError(msg)
