"""Compare a learned chain (descriptor primitive dicts) with a case's truth."""

from __future__ import annotations

from typing import Any

import numpy as np

from bench.learn_corpus.case import Case, TruthPrimitive
from bench.learn_corpus.rotations import Array, unit

PARALLEL_COS = 0.1
"""Below this |cos| between the learned axis and the truth's plane normal, the plane intersection is ill-posed
and the axis offset is measured as the learned line's distance from the truth's reference point."""


def _vec(value: Any) -> Array | None:
    if value is None:
        return None
    return np.asarray(value, dtype=np.float64).reshape(3)


def axis_offset_m(truth: TruthPrimitive, pos: Array, direction: Array) -> float:
    """Distance (m) between the truth's axis and the learned line ``(pos, direction)``, measured in the plane
    through the truth's ``pos`` (the foot of its marker's centroid) perpendicular to the truth's axis."""
    assert truth.pos is not None
    d_t, d_l = unit(truth.dir), unit(direction)
    cos = float(np.dot(d_l, d_t))
    if abs(cos) > PARALLEL_COS:
        hit = pos + d_l * float(np.dot(truth.pos - pos, d_t)) / cos
        return float(np.linalg.norm(hit - truth.pos))
    rel = truth.pos - pos
    return float(np.linalg.norm(rel - np.dot(rel, d_l) * d_l))


def _learned_radius(prim: dict[str, Any], marker: str | None) -> float | None:
    """The learned radius of ``marker`` (fit.radii_m as a dict, or a list aligned with ``markers``), else the
    first one."""
    radii = (prim.get("fit") or {}).get("radii_m")
    if radii is None:
        return None
    if isinstance(radii, dict):
        if marker is not None and marker in radii:
            return float(radii[marker])
        return float(next(iter(radii.values()))) if radii else None
    values = [float(r) for r in np.atleast_1d(np.asarray(radii, dtype=np.float64))]
    names = list(prim.get("markers") or [])
    if marker is not None and marker in names and len(names) == len(values):
        return values[names.index(marker)]
    return values[0] if values else None


def _overlap(a: TruthPrimitive, b: dict[str, Any]) -> float:
    lo = max(a.t_start, float(b.get("t_start", -np.inf)))
    hi = min(a.t_end, float(b.get("t_end", np.inf)))
    return hi - lo


def _pairs(chain: list[dict[str, Any]], truth: tuple[TruthPrimitive, ...], right: bool) -> list[tuple[int, int]]:
    """In order when the kinds match; otherwise each truth primitive with the same-kind learned primitive that
    overlaps it most in time (if any)."""
    if right:
        return [(i, i) for i in range(len(truth))]
    out = []
    for i, t in enumerate(truth):
        same = [j for j, p in enumerate(chain) if p.get("kind") == t.kind and "t_start" in p and _overlap(t, p) > 0]
        if same:
            out.append((i, max(same, key=lambda j: _overlap(t, chain[j]))))
    return out


def score(chain: list[dict[str, Any]], case: Case) -> dict[str, Any]:
    """How ``chain`` compares with ``case.truth``.

    ``right``: the same kinds in the same order; ``radius_ok``: every matched rotation's radius within
    ``case.radius_tol_m`` (None when not scored); ``right_strict``: both. Per matched primitive: ``direction_deg``
    (sign-aware, 0-180), ``position_mm`` (rotations, when ``case.check_axis``), ``extent_error`` (rad or m,
    learned minus true), ``radius_error_mm`` (learned minus true), ``t_start_error_s``, ``t_end_error_s``.
    """
    kinds = [str(p.get("kind")) for p in chain]
    right = kinds == list(case.kinds)
    rows = []
    radius_ok: bool | None = None
    for i, j in _pairs(chain, case.truth, right):
        t, p = case.truth[i], chain[j]
        row: dict[str, Any] = {"truth": i, "learned": j, "kind": t.kind}
        direction = _vec(p.get("dir"))
        if direction is not None:
            cos = float(np.clip(np.dot(unit(direction), unit(t.dir)), -1.0, 1.0))
            row["direction_deg"] = float(np.degrees(np.arccos(cos)))
        pos = _vec(p.get("pos"))
        if case.check_axis and t.kind == "rotation" and t.pos is not None and pos is not None and direction is not None:
            row["position_mm"] = 1000.0 * axis_offset_m(t, pos, direction)
        if p.get("extent") is not None:
            row["extent_error"] = float(p["extent"]) - t.extent
        for key in ("t_start", "t_end"):
            if p.get(key) is not None:
                row[f"{key}_error_s"] = float(p[key]) - getattr(t, key)
        if t.kind == "rotation" and t.radius_m is not None:
            learned = _learned_radius(p, t.radius_marker)
            if learned is not None:
                row["radius_error_mm"] = 1000.0 * (learned - t.radius_m)
                if case.radius_tol_m is not None:
                    ok = abs(learned - t.radius_m) <= case.radius_tol_m
                    radius_ok = ok if radius_ok is None else radius_ok and ok
            elif case.radius_tol_m is not None:
                radius_ok = False
        rows.append(row)
    return {
        "case": case.name,
        "right": right,
        "radius_ok": radius_ok,
        "right_strict": right and radius_ok is not False,
        "kinds_truth": list(case.kinds),
        "kinds_learned": kinds,
        "n_truth": len(case.truth),
        "n_learned": len(chain),
        "primitives": rows,
    }
