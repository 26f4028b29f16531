"""Score a learned chain against a recording's truth file (``truth.json``): per true primitive, the direction
error (deg), the axis position error (mm, perpendicular to the true axis; rotations), the extent error (deg or mm)
and the boundary offsets (s). Primitives are matched in order by kind (longest common subsequence)."""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np


@dataclass(frozen=True)
class PrimitiveError:
    """Errors of one matched primitive: ``kind``; ``direction_deg``; ``position_mm`` (rotations, else None);
    ``extent_error`` in deg (rotation) or mm (translation), signed learned minus true; boundary offsets (s)."""

    kind: str
    direction_deg: float
    position_mm: float | None
    extent_error: float
    t_start_s: float | None
    t_end_s: float | None


@dataclass(frozen=True)
class ChainScore:
    """Whether the kinds match in order, the learned and true kinds, and the matched primitives' errors."""

    kinds_right: bool
    learned: tuple[str, ...]
    truth: tuple[str, ...]
    errors: tuple[PrimitiveError, ...]


def align_kinds(got: list[str], want: list[str]) -> list[tuple[int, int]]:
    """Longest common subsequence of two kind sequences: matched index pairs (learned index, true index)."""
    n, m = len(got), len(want)
    table = np.zeros((n + 1, m + 1), dtype=np.int64)
    for i in range(n - 1, -1, -1):
        for j in range(m - 1, -1, -1):
            table[i, j] = table[i + 1, j + 1] + 1 if got[i] == want[j] else max(table[i + 1, j], table[i, j + 1])
    pairs, i, j = [], 0, 0
    while i < n and j < m:
        if got[i] == want[j]:
            pairs.append((i, j))
            i, j = i + 1, j + 1
        elif table[i + 1, j] >= table[i, j + 1]:
            i += 1
        else:
            j += 1
    return pairs


def _offset(a: Any, b: Any) -> float | None:
    return None if a is None or b is None else float(a) - float(b)


def score_chain(learned: list[dict[str, Any]], truth: dict[str, Any]) -> ChainScore:
    """Compare a learned chain (DESCRIPTOR.md primitive dicts) with ``truth["chain"]``."""
    want = list(truth["chain"])
    got_kinds = [str(p["kind"]) for p in learned]
    want_kinds = [str(p["kind"]) for p in want]
    errors = []
    for i, j in align_kinds(got_kinds, want_kinds):
        p, t = learned[i], want[j]
        d, td = np.asarray(p["dir"], dtype=np.float64), np.asarray(t["dir"], dtype=np.float64)
        direction = float(np.degrees(np.arccos(np.clip(np.dot(d, td), -1.0, 1.0))))
        position = None
        if t["kind"] == "rotation":
            w = np.asarray(p["pos"], dtype=np.float64) - np.asarray(t["pos"], dtype=np.float64)
            position = float(np.linalg.norm(w - np.dot(w, td) * td) * 1000.0)
            extent = float(np.degrees(p["extent"] - t["extent"]))
        else:
            extent = float((p["extent"] - t["extent"]) * 1000.0)
        errors.append(
            PrimitiveError(
                t["kind"],
                direction,
                position,
                extent,
                _offset(p.get("t_start"), t.get("t_start")),
                _offset(p.get("t_end"), t.get("t_end")),
            )
        )
    return ChainScore(got_kinds == want_kinds, tuple(got_kinds), tuple(want_kinds), tuple(errors))
