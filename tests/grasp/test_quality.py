"""Grasp wrench space: epsilon and volume of known contact sets."""

from __future__ import annotations

import numpy as np

from tasks.grasp.quality import grasp_quality

CENTER = np.zeros(3)


def test_six_contacts_on_cube_faces_are_force_closure() -> None:
    pos = np.array([[0.05, 0, 0], [-0.05, 0, 0], [0, 0.05, 0], [0, -0.05, 0], [0, 0, 0.05], [0, 0, -0.05]])
    q = grasp_quality(pos, -pos / 0.05, CENTER, 0.05 * np.sqrt(3), mu=0.5)
    assert q.force_closure
    assert q.epsilon > 0.1
    assert q.volume > 0.0
    assert q.contacts == 6


def test_three_finger_pinch_of_a_sphere_is_force_closure() -> None:
    angles = np.radians([90.0, 210.0, 330.0])
    pos = 0.03 * np.stack([np.cos(angles), np.sin(angles), np.zeros(3)], axis=1)
    q = grasp_quality(pos, -pos / 0.03, CENTER, 0.03, mu=0.5)
    assert q.force_closure
    assert q.epsilon > 0.0


def test_one_finger_contact_has_zero_epsilon() -> None:
    q = grasp_quality(np.array([[0.05, 0.0, 0.0]]), np.array([[-1.0, 0.0, 0.0]]), CENTER, 0.05)
    assert not q.force_closure
    assert q.epsilon == 0.0
    assert q.volume == 0.0


def test_two_antipodal_point_contacts_cannot_resist_torsion() -> None:
    pos = np.array([[0.05, 0.0, 0.0], [-0.05, 0.0, 0.0]])
    q = grasp_quality(pos, -pos / 0.05, CENTER, 0.05)
    assert not q.force_closure
    assert q.epsilon == 0.0


def test_frictionless_contacts_on_one_side_are_not_force_closure() -> None:
    pos = np.array([[0.05, y, z] for y in (-0.02, 0.02) for z in (-0.02, 0.02)])
    q = grasp_quality(pos, np.tile([-1.0, 0.0, 0.0], (4, 1)), CENTER, 0.06, mu=0.5)
    assert not q.force_closure
    assert q.epsilon == 0.0
