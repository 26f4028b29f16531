"""The four built-in demonstration scenes after the paper's experiments (Dang & Allen, Section V): by name.

``build_scene(name, None)`` is the nominal instance; ``build_scene(name, seed)`` a randomised one (placement,
sizes, demonstrated extents) drawn with ``np.random.default_rng(seed)``; ``draw_scene`` takes the generator
itself, so ``draw_scene(name, np.random.default_rng(s))`` is the same instance as ``build_scene(name, s)``.
"""

from __future__ import annotations

from collections.abc import Callable

import numpy as np

from tasks.errors import SceneError
from tasks.scenes import bottle, door, microwave, sliding_door
from tasks.scenes.scene import Scene

SCENE_NAMES: tuple[str, ...] = ("microwave", "sliding-door", "door", "bottle")
"""The built-in scenes: open a microwave, slide a cabinet door, open a door by its lever, unscrew a bottle cap."""

_BUILDERS: dict[str, Callable[[np.random.Generator | None, int | None], Scene]] = {
    "microwave": microwave.build,
    "sliding-door": sliding_door.build,
    "door": door.build,
    "bottle": bottle.build,
}


def _builder(name: str) -> Callable[[np.random.Generator | None, int | None], Scene]:
    if name not in _BUILDERS:
        msg = f"unknown scene {name!r}: the built-in scenes are {', '.join(SCENE_NAMES)}"
        raise SceneError(msg)
    return _BUILDERS[name]


def build_scene(name: str, seed: int | None) -> Scene:
    """Scene ``name``: nominal for ``seed`` None, else randomised by ``np.random.default_rng(seed)``;
    ``SceneError`` naming the valid scenes for an unknown name."""
    builder = _builder(name)
    return builder(None if seed is None else np.random.default_rng(seed), seed)


def draw_scene(name: str, rng: np.random.Generator | None, seed: int | None = None) -> Scene:
    """Scene ``name`` randomised by ``rng`` (None = nominal); ``seed`` is only recorded in ``Scene.seed``."""
    return _builder(name)(rng, seed)
