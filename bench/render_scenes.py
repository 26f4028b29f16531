"""Pictures of the four built-in scenes (nominal instances) for the README: ``docs/scenes/<name>.png``.

.venv/bin/python bench/render_scenes.py [--out docs/scenes] [--width 480] [--height 360] [--seed N]
"""

from __future__ import annotations

import argparse
from pathlib import Path

from tasks.scenes.catalog import SCENE_NAMES, build_scene
from tasks.scenes.render import render_scene


def main(argv: list[str] | None = None) -> int:
    """Render every scene and print the files written with their sizes."""
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--out", type=Path, default=Path("docs/scenes"))
    parser.add_argument("--width", type=int, default=480)
    parser.add_argument("--height", type=int, default=360)
    parser.add_argument("--seed", type=int, default=None, help="a randomised instance instead of the nominal one")
    args = parser.parse_args(argv)
    for name in SCENE_NAMES:
        path = render_scene(
            build_scene(name, args.seed), args.out / f"{name}.png", args.width, args.height, overwrite=True
        )
        print(f"{path}  {path.stat().st_size / 1024:.0f} kB")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
