"""pbd stages: pure computation per stage (``tasks/<stage>/core.py``-style modules) and thin Prefect wrappers.

Importing this package is light: no Prefect, open3d or pybullet is imported until a stage needs it.
"""

__all__: list[str] = []
