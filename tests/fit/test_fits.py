"""Fits recover known axes; the moment costs equal direct computation; a rigid motion moves the axis along."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from tasks.fit.geometry import angle_between_axes, point_line_distance
from tasks.fit.moments import prefix_moments, span_residuals
from tasks.fit.noise import noise_covariance, noise_sigma
from tasks.fit.rotation import circle_from_points_algebraic, fit_rotation
from tasks.fit.select import SelectParams, choose_bic, choose_eigen, eigenvalue_ratio, model_costs
from tasks.fit.translation import fit_translation, travels_agree


def _rot(axis: np.ndarray, angle: float) -> np.ndarray:
    k = axis / np.linalg.norm(axis)
    kx = np.array([[0, -k[2], k[1]], [k[2], 0, -k[0]], [-k[1], k[0], 0]])
    return np.eye(3) + np.sin(angle) * kx + (1 - np.cos(angle)) * kx @ kx


def _arc(rng: np.random.Generator, radius: float, sweep: float, noise: float, n: int = 300) -> np.ndarray:
    th = np.linspace(0.0, sweep, n)
    pts = np.column_stack([radius * np.cos(th), radius * np.sin(th), np.full(n, 0.05)])
    return pts + rng.normal(0.0, noise, pts.shape)


AXIS_DIR = np.array([0.3, -0.2, 0.93])
AXIS_POS = np.array([0.4, -0.1, 0.9])


def _placed(pts: np.ndarray) -> np.ndarray:
    r = _rot(np.cross([0, 0, 1.0], AXIS_DIR), np.arccos(AXIS_DIR[2] / np.linalg.norm(AXIS_DIR)))
    return pts @ r.T + AXIS_POS


def test_rotation_fit_recovers_a_known_axis_angle_and_radius() -> None:
    rng = np.random.default_rng(0)
    pts = _placed(_arc(rng, 0.35, 1.4, 0.0005))
    fit = fit_rotation([pts], 0.0015)
    axis = AXIS_DIR / np.linalg.norm(AXIS_DIR)
    assert angle_between_axes(fit.dir, axis) < np.radians(0.3)
    assert point_line_distance(fit.pos, AXIS_POS, axis) < 0.001
    assert abs(fit.angle_rad - 1.4) < 0.01
    assert abs(fit.radii[0] - 0.35) < 0.001
    assert 0.0003 < fit.rms_m < 0.0012
    assert fit.dir_std_rad < np.radians(0.5)


def test_rotation_sign_follows_the_motion() -> None:
    rng = np.random.default_rng(1)
    pts = _placed(_arc(rng, 0.2, 1.0, 0.0002))
    forward = fit_rotation([pts], 0.001)
    backward = fit_rotation([pts[::-1]], 0.001)
    axis = AXIS_DIR / np.linalg.norm(AXIS_DIR)
    assert float(np.dot(forward.dir, axis)) > 0.999
    assert float(np.dot(backward.dir, axis)) < -0.999
    assert forward.angle_rad > 0.9
    assert backward.angle_rad > 0.9


def test_joint_fit_of_two_markers_shares_one_axis() -> None:
    rng = np.random.default_rng(2)
    a = _placed(_arc(rng, 0.3, 0.6, 0.0005))
    b = _placed(_arc(rng, 0.45, 0.6, 0.0005) + np.array([0.0, 0.0, -0.2]))
    fit = fit_rotation([a, b], 0.0015)
    assert angle_between_axes(fit.dir, AXIS_DIR) < np.radians(0.6)
    assert sorted(round(r, 2) for r in fit.radii) == [0.3, 0.45]


def test_algebraic_circle_fit_and_eigenvalues() -> None:
    pts = _placed(_arc(np.random.default_rng(3), 0.5, 2.0, 0.0))
    c = circle_from_points_algebraic(pts)
    assert abs(c.radius - 0.5) < 1e-9
    assert c.rms_m < 1e-9
    assert c.eigenvalues[0] >= c.eigenvalues[1] >= c.eigenvalues[2] >= 0.0


def test_translation_fit_recovers_direction_and_distance() -> None:
    rng = np.random.default_rng(4)
    d = np.array([0.6, 0.8, 0.0])
    s = np.linspace(0.0, 0.3, 200)
    pts = np.array([0.1, 0.2, 0.7]) + s[:, None] * d + rng.normal(0, 0.0005, (200, 3))
    fit = fit_translation([pts, pts[::-1][::-1] + 0.1])
    assert angle_between_axes(fit.dir, d) < np.radians(0.2)
    assert abs(fit.distance_m - 0.3) < 0.002
    back = fit_translation([pts[::-1]])
    assert float(np.dot(back.dir, d)) < -0.999


def test_prefix_moment_costs_equal_direct_sums() -> None:
    rng = np.random.default_rng(5)
    pts = _placed(_arc(rng, 0.3, 1.5, 0.0005, n=400))
    res = span_residuals(prefix_moments(pts), np.array([0, 100]), np.array([400, 300]))
    for k, (a, b) in enumerate([(0, 400), (100, 300)]):
        q = pts[a:b] - pts[a:b].mean(axis=0)
        ev = np.linalg.eigvalsh(q.T @ q)
        assert np.isclose(res.still[k], ev.sum(), rtol=1e-9)
        assert np.isclose(res.line[k], ev[0] + ev[1], rtol=1e-7)
        assert np.isclose(res.radius[k], 0.3, atol=0.005)  # Kåsa shrinks partial arcs a little
        assert res.circle[k] < 2.0 * (b - a) * 3 * 0.0005**2


def test_noise_sigma_from_fourth_differences() -> None:
    rng = np.random.default_rng(6)
    pts = _placed(_arc(rng, 0.3, 1.0, 0.001, n=3000))
    assert 0.0009 < noise_sigma(pts) < 0.0011
    assert noise_sigma(pts[:4]) == 0.0


@pytest.mark.parametrize(("hz", "corr_s"), [(30.0, 0.05), (120.0, 0.03), (240.0, 0.08)])
def test_noise_correlated_in_time_is_seen_in_full(hz: float, corr_s: float) -> None:
    """A camera tracker's filtered noise (AR(1), 2 mm, correlated over tens of ms) on a still marker and on one
    that slides 0.4 m: the estimate is the noise's full standard deviation, not the part between samples."""
    rng = np.random.default_rng(11)
    t = np.arange(0.0, 20.0, 1.0 / hz)
    rho = np.exp(-(1.0 / hz) / corr_s)
    noise = np.zeros((len(t), 3))
    white = rng.normal(0.0, 0.002, (len(t), 3))
    noise[0] = white[0]
    for k in range(1, len(t)):
        noise[k] = rho * noise[k - 1] + np.sqrt(1.0 - rho**2) * white[k]
    s = np.clip((t - 8.0) / 3.0, 0.0, 1.0)
    slide = np.outer(0.4 * (10 * s**3 - 15 * s**4 + 6 * s**5), [1.0, 0.0, 0.0])
    for pts in (noise, slide + noise):
        assert 0.0015 < noise_sigma(pts, t) < 0.0027
        assert 0.0015**2 < np.trace(noise_covariance(pts, t)) / 3.0 < 0.0027**2


def test_model_choice_bic_and_eq3() -> None:
    n = np.array([300.0])
    costs = model_costs(
        n, np.array([1.0]), np.array([0.05]), np.array([1e-4]), sigma_still=0.0005, sigma_model=0.001, undefined=9.0
    )[0]
    assert choose_bic(costs, 1.0, SelectParams()) == "rotation"
    assert choose_bic(costs, 0.1, SelectParams()) == "translation"  # a 4 m "circle" on a drawer is a line
    still = model_costs(n, np.array([n[0] * 3 * 0.0005**2]), np.array([n[0] * 2 * 0.0005**2]), np.array([1.0]),
                        sigma_still=0.0005, sigma_model=0.002, undefined=9.0)[0]  # fmt: skip
    assert choose_bic(still, 0.0, SelectParams()) == "still"
    assert eigenvalue_ratio((1.0, 0.02, 0.0)) == 0.02
    assert choose_eigen((1.0, 0.02, 0.0), 0.05, 0.01) == "translation"
    assert choose_eigen((1.0, 0.06, 0.0), 0.05, 0.01) == "rotation"
    assert choose_eigen((1e-6, 0.0, 0.0), 0.05, 0.01) == "still"


@settings(max_examples=6, deadline=None)
@given(
    yaw=st.floats(-3.0, 3.0),
    tilt=st.floats(0.0, 1.2),
    shift=st.tuples(st.floats(-1, 1), st.floats(-1, 1), st.floats(-1, 1)),
)
def test_rigid_motion_of_input_moves_the_axis_with_it(yaw: float, tilt: float, shift: tuple[float, ...]) -> None:
    pts = _placed(_arc(np.random.default_rng(7), 0.3, 1.2, 0.0003))
    base = fit_rotation([pts], 0.001)
    r = _rot(np.array([0.0, 0.0, 1.0]), yaw) @ _rot(np.array([1.0, 0.0, 0.0]), tilt)
    t = np.asarray(shift)
    moved = fit_rotation([pts @ r.T + t], 0.001)
    assert angle_between_axes(moved.dir, r @ base.dir) < 1e-5
    assert point_line_distance(moved.pos, r @ base.pos + t, r @ base.dir) < 1e-6
    assert abs(moved.angle_rad - base.angle_rad) < 1e-6


@pytest.mark.parametrize("seed", [0, 1, 2])
def test_markers_of_a_sliding_part_travel_alike_and_a_turning_parts_do_not(seed: int) -> None:
    """Two markers sampled at their own jittered times (30 Hz, 2 mm noise) on a part moving 0.1 m: sliding, both
    travel 0.1 m; turning about an axis with the markers at 40 and 80 mm, one travels twice as far as the other."""
    rng = np.random.default_rng(seed)
    times = [np.sort(rng.uniform(0.0, 1.0, 30)) for _ in range(2)]
    slide = [0.1 * t + rng.normal(0.0, 0.002, len(t)) for t in times]
    turn = [r / 0.08 * 0.1 * t + rng.normal(0.0, 0.002, len(t)) for r, t in zip((0.04, 0.08), times, strict=True)]
    assert travels_agree(times, slide)
    assert not travels_agree(times, turn)
