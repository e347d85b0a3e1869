"""time_move on its own: end steps of a rest-to-rest move, and moves of any size."""

from __future__ import annotations

import numpy as np
import pytest

from singplan.kinematics.robot import load_robot
from singplan.planning.path.jointmap import JointMap, JointPart
from singplan.planning.timing.move import time_move
from singplan.planning.timing.ratios import end_step_ratio
from singplan.planning.timing.records import MoveLimits


def _ptp(robot, q0: np.ndarray, q1: np.ndarray) -> JointMap:
    return JointMap(robot, None, [JointPart("ptp", np.array([0.0, 1.0]), np.array([q0, q1]))])


@pytest.mark.parametrize("size_rad", [1e-9, 1e-6, 1e-3, 0.3, 2.0])
def test_a_rest_to_rest_move_of_any_size_is_timed_within_the_limits(size_rad: float) -> None:
    robot = load_robot("abb_irb2400")
    q0 = np.radians([0, 10, 20, 0, 30, 0])
    q1 = q0 + size_rad * np.array([1.0, -0.5, 0.3, 0.0, 0.2, 1.0])
    amax = np.full(6, 10.0)
    limits = MoveLimits(robot.velocity_rad_s, amax, 0.0, None)
    tm = time_move(_ptp(robot, q0, q1), limits, 0.004, 0, max_samples=100_000)
    np.testing.assert_allclose(tm.q[[0, -1]], [q0, q1], atol=1e-15)
    assert tm.speed_ratio <= 1.0 and tm.accel_ratio <= 1.0
    # from rest, one period at amax covers amax dt^2 / 2: any seam then stays within amax
    assert end_step_ratio(tm.q, 0.004, amax) <= 1.0 + 1e-12


def test_a_move_that_changes_nothing_is_one_period_at_rest() -> None:
    robot = load_robot("abb_irb2400")
    q0 = np.radians([0, 10, 20, 0, 30, 0])
    tm = time_move(_ptp(robot, q0, q0), MoveLimits(robot.velocity_rad_s, np.full(6, 10.0), 0.0, None), 0.004, 0,
                   max_samples=100_000)
    assert tm.duration_s == 0.004 and np.array_equal(tm.q, [q0, q0])
