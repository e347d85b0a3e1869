"""A Robot is not changed after it is made: the task's limits make another robot."""

from __future__ import annotations

import math

import numpy as np
import pytest

from singplan.kinematics.limits import DEFAULT_ACCELERATION_RAD_S2
from singplan.kinematics.robot import load_robot
from singplan.planning.orchestration.redundancy import hold_joint
from singplan.planning.orchestration.targets import load_task_robot
from singplan.task.load import parse_task

TASK = {"robot": "abb_irb2400", "start": {"joints_deg": [0, 10, 20, 0, 30, 0]},
        "moves": [{"lin": {"to": {"xyz": [1.0, 0.2, 0.8]}}}], "limits": {"acceleration": [1, 2, 3, 4, 5, 6]}}


def test_the_task_s_accelerations_make_a_robot_of_their_own() -> None:
    robot = load_task_robot(parse_task(TASK))
    np.testing.assert_array_equal(robot.acceleration_rad_s2, [1, 2, 3, 4, 5, 6])
    again = load_robot("abb_irb2400")  # a robot loaded afterwards keeps its own default
    np.testing.assert_array_equal(again.acceleration_rad_s2, np.full(6, DEFAULT_ACCELERATION_RAD_S2))


def test_limit_arrays_are_read_only() -> None:
    robot = load_robot("abb_irb2400")
    for values in (robot.lower_rad, robot.upper_rad, robot.velocity_rad_s, robot.acceleration_rad_s2):
        with pytest.raises(ValueError, match="read-only"):
            values[0] = 0.0


def test_with_acceleration_leaves_the_robot_and_keeps_its_recognition() -> None:
    robot = load_robot("abb_irb2400")
    family = robot.recognition
    faster = robot.with_acceleration(25.0)
    np.testing.assert_array_equal(faster.acceleration_rad_s2, np.full(6, 25.0))
    np.testing.assert_array_equal(robot.acceleration_rad_s2, np.full(6, DEFAULT_ACCELERATION_RAD_S2))
    assert faster.recognition is family and faster.T_tip_tcp == robot.T_tip_tcp
    assert faster.with_tool(robot.T_tip_tcp).acceleration_rad_s2.tolist() == [25.0] * 6


def test_a_held_joint_s_chain_keeps_the_other_joints_accelerations() -> None:
    panda = load_robot("panda").with_acceleration(np.arange(1.0, 8.0))
    held = hold_joint(panda, panda.joint_names[2], math.radians(10.0))
    np.testing.assert_array_equal(held.reduced.acceleration_rad_s2, [1, 2, 4, 5, 6, 7])
    np.testing.assert_array_equal(panda.acceleration_rad_s2, np.arange(1.0, 8.0))
