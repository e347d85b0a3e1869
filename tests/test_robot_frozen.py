"""A Robot is not changed after it is made; the task's joint acceleration limits live in the task only."""

from __future__ import annotations

import math

import numpy as np
import pytest

from singplan.kinematics.held import hold_joint
from singplan.kinematics.robot import load_robot
from singplan.planning.orchestration.redundancy import reduce_task
from singplan.planning.orchestration.targets import load_task_robot, move_limits
from singplan.task.load import parse_task
from singplan.task.schema import DEFAULT_ACCELERATION_RAD_S2

TASK = {"robot": "abb_irb2400", "start": {"joints_deg": [0, 10, 20, 0, 30, 0]},
        "moves": [{"lin": {"to": {"xyz": [1.0, 0.2, 0.8]}}}], "limits": {"acceleration": [1, 2, 3, 4, 5, 6]}}


def test_the_task_s_accelerations_are_the_timing_limits() -> None:
    task = parse_task(TASK)
    robot = load_task_robot(task)
    assert not hasattr(robot, "acceleration_rad_s2")  # one home: the task's limits
    np.testing.assert_array_equal(move_limits(robot, task, task.moves[0], 1.0).acceleration_rad_s2, [1, 2, 3, 4, 5, 6])


def test_one_value_is_every_joint_s() -> None:
    limits = parse_task({**TASK, "limits": {}}).limits
    np.testing.assert_array_equal(limits.joint_accelerations(6), np.full(6, DEFAULT_ACCELERATION_RAD_S2))


def test_limit_arrays_are_read_only() -> None:
    robot = load_robot("abb_irb2400")
    for values in (robot.lower_rad, robot.upper_rad, robot.velocity_rad_s):
        with pytest.raises(ValueError, match="read-only"):
            values[0] = 0.0


def test_with_tool_leaves_the_robot_and_keeps_its_recognition() -> None:
    robot = load_robot("abb_irb2400")
    family = robot.recognition
    other = robot.with_tool(robot.T_tip_tcp)
    assert other is not robot and other.recognition is family and other.T_tip_tcp == robot.T_tip_tcp


def test_a_held_joint_s_chain_keeps_the_other_joints_accelerations() -> None:
    panda = load_robot("panda")
    task = parse_task({"robot": "panda", "start": {"joints_deg": [0, -30, 10, -120, 0, 90, 45]},
                       "moves": [{"lin": {"to": {"xyz": [0.4, 0.1, 0.5]}}}],
                       "limits": {"acceleration": [1, 2, 3, 4, 5, 6, 7]}})
    held = hold_joint(panda, panda.joint_names[2], math.radians(10.0))
    np.testing.assert_array_equal(reduce_task(held, task).limits.joint_accelerations(6), [1, 2, 4, 5, 6, 7])
    assert task.limits.acceleration_rad_s2 == (1, 2, 3, 4, 5, 6, 7)
