"""Closed-form UR IK (example-robot-data ur5) against Pinocchio FK."""

from __future__ import annotations

import numpy as np
import pinocchio as pin

from singplan.configuration import classify
from singplan.ik import solve_all
from singplan.ik_ur import UrParameters, ur_arm_for_point, ur_solutions

from .conftest import random_q


def pose_error(a: pin.SE3, b: pin.SE3) -> float:
    return float(np.abs(pin.log6(a.actInv(b)).vector).max())


def test_ur5_ik_recovers_q_and_reproduces_the_pose(robots, rng) -> None:
    robot = robots["ur5"].with_tool(pin.SE3(np.eye(3), np.array([0.0, 0.0, 0.1])))
    for q in random_q(robot, rng, 200):
        target = robot.fk(q)
        sols = solve_all(robot, target, seed=q)
        for q_sol in sols.q:
            assert pose_error(robot.fk(q_sol), target) < 1e-9
        match = [k for k, s in enumerate(sols.q) if np.allclose(s, q, atol=1e-7)]
        assert match
        assert sols.labels[match[0]] == classify(robot, q).label


def test_ur5_generic_pose_has_eight_distinct_labels(robots, rng) -> None:
    robot = robots["ur5"]
    params = UrParameters.from_robot(robot)
    eight = 0
    for q in random_q(robot, rng, 100):
        sols = ur_solutions(params, robot.fk(q).homogeneous)
        finite = sols[np.all(np.isfinite(sols), axis=1)]
        if len(finite) == 8:
            eight += 1
            assert len({classify(robot, s).label for s in finite}) == 8
    assert eight > 50


def test_ur5_exact_wrist_singular_pose_round_trips(robots) -> None:
    robot = robots["ur5"]
    q_mid = np.array([0.3, -1.2, 1.5, -0.3, 0.0, 0.4])  # q5 = 0: axes 4 and 6 parallel
    target = robot.fk(q_mid)
    sols = solve_all(robot, target, seed=q_mid)
    assert not np.any(np.isnan(sols.q))
    for q_sol in sols.q:
        assert pose_error(robot.fk(q_sol), target) < 1e-9
    assert any(np.allclose(s, q_mid, atol=1e-9) for s in sols.q)


def test_ur5_flange_point_solve_reaches_the_target_with_the_wrist_held(robots, rng) -> None:
    robot = robots["ur5"].with_tool(pin.SE3(np.eye(3), np.array([0.02, -0.01, 0.12])))
    q = np.array(random_q(robot, rng, 200))
    exact = ur_arm_for_point(robot, q, np.array([robot.fk(qk).translation for qk in q]))
    np.testing.assert_allclose(exact, q, atol=1e-9)  # the seed's own solution is the nearest
    moved = q.copy()
    moved[:, :3] += rng.uniform(-0.05, 0.05, size=(len(q), 3))  # targets of nearby arm joints
    targets = np.array([robot.fk(qk).translation for qk in moved])
    out = ur_arm_for_point(robot, q, targets)
    assert np.all(np.isfinite(out))  # each target has a solution: the moved joints
    for qk, target in zip(out, targets, strict=True):
        assert np.linalg.norm(robot.fk(qk).translation - target) < 1e-9
    np.testing.assert_array_equal(out[:, 3:], q[:, 3:])
