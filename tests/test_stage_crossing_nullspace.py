"""planning.crossing.nullspace's solvers on their own, against geometry: the singular configuration it
finds keeps the pose (Pinocchio FK) with the singular distance zero, a held joint stays put while the
others restore the pose, and a self-motion on a spherical wrist turns A4 and A6 against each other
(axes 4 and 6 collinear) with the pose kept at every reference step (tests/test_nullspace.py: the UR5)."""

from __future__ import annotations

import math

import numpy as np
import pinocchio as pin
import pytest

from singplan.kinematics.configuration import singularity_distances
from singplan.kinematics.robot import load_robot
from singplan.planning.crossing.nullspace import hold_pose, self_motion, singular_config

ROBOT = load_robot("abb_irb2400")


def _pose_gap(q: np.ndarray, T: np.ndarray) -> tuple[float, float]:
    reached = ROBOT.fk(q)
    return (float(np.linalg.norm(reached.translation - T[:3, 3])),
            float(np.linalg.norm(pin.log3(reached.rotation.T @ T[:3, :3]))))


def _wrist_singular(q: np.ndarray) -> np.ndarray:
    """q with A5 where the wrist distance is zero (ABB: A5 = 0)."""
    out = q.copy()
    out[4] = 0.0
    assert abs(singularity_distances(ROBOT, out).wrist_rad) < 1e-9
    return out


@pytest.mark.parametrize("miss_rad", [0.02, -0.05])
def test_the_singular_configuration_keeps_a_singular_pose_with_the_distance_zero(miss_rad: float) -> None:
    q_hit = _wrist_singular(np.radians([10, 20, 15, 40, 30, -30]))
    T = ROBOT.fk(q_hit).homogeneous
    start = q_hit + np.array([0.01, -0.01, 0.01, 0.02, miss_rad, -0.02])
    q = singular_config(ROBOT, start, T, "wrist")
    assert abs(singularity_distances(ROBOT, q).wrist_rad) < 1e-9
    position, angle = _pose_gap(q, T)
    assert position < 1e-9 and angle < 1e-9


def test_holding_a_joint_restores_the_pose_with_the_others() -> None:
    q_goal = np.radians([10, 20, 15, 40, 30, -30])
    T = ROBOT.fk(q_goal).homogeneous
    start = q_goal + np.array([0.02, -0.01, 0.015, 0.0, -0.02, 0.03])  # A4 right, the others off
    q = hold_pose(ROBOT, start, T, 3)
    assert q[3] == start[3]
    position, angle = _pose_gap(q, T)
    assert position < 1e-12 and angle < 1e-12


def test_a_self_motion_at_a_wrist_singularity_turns_a4_against_a6_and_keeps_the_pose() -> None:
    q0 = _wrist_singular(np.radians([10, 20, 15, 40, 30, -30]))
    T = ROBOT.fk(q0).homogeneous
    motion = self_motion(ROBOT, q0, T, 3, math.radians(90.0))
    assert motion[-1, 3] - motion[0, 3] == pytest.approx(math.radians(90.0), abs=1e-12)
    for q in motion:
        position, angle = _pose_gap(q, T)
        assert position < 1e-9 and angle < 1e-9
    # axes 4 and 6 collinear: A6 turns back by what A4 turns (the ABB's axes point the same way there),
    # the arm joints and A5 stay
    np.testing.assert_allclose(motion[:, 3] + motion[:, 5], motion[0, 3] + motion[0, 5], atol=1e-9)
    np.testing.assert_allclose(motion[:, :3], np.broadcast_to(q0[:3], (len(motion), 3)), atol=1e-9)
    np.testing.assert_allclose(motion[:, 4], 0.0, atol=1e-9)
