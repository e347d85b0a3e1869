"""The one damped least-squares home (kinematics.ik.numeric) and the re-solves that call it."""

from __future__ import annotations

import math

import numpy as np
import pinocchio as pin
import pytest

from singplan.kinematics.ik.numeric import damped_solve, damped_solve_rows, damped_step, pose_error
from singplan.kinematics.robot import load_robot
from singplan.planning.crossing.nullspace import hold_pose
from singplan.planning.path.jointmap import axis_solve, exact_orientation, position_solve


def test_damped_step_minimises_the_damped_residual_in_each_form() -> None:
    rng = np.random.default_rng(4)
    for rows, cols in [(6, 6), (3, 3), (5, 6), (6, 5)]:
        J, err = rng.normal(size=(rows, cols)), rng.normal(size=rows)
        for damping in (1e-6, 1e-2, 1.0):
            normal, stacked = damped_step(J, err, damping), damped_step(J, err, damping, stacked=True)
            np.testing.assert_allclose(normal, stacked, rtol=1e-8, atol=1e-10)
            gradient = J.T @ (J @ normal - err) + damping * normal  # zero at the minimum
            assert float(np.max(np.abs(gradient))) < 1e-9
        np.testing.assert_allclose(damped_step(J, err, 0.0), np.linalg.lstsq(J, err, rcond=None)[0], atol=0.0)


def test_a_batch_of_damped_steps_equals_each_step_alone() -> None:
    rng = np.random.default_rng(5)
    for rows, cols in [(6, 6), (3, 3), (5, 6), (6, 5)]:
        J, err = rng.normal(size=(7, rows, cols)), rng.normal(size=(7, rows))
        for damping in (0.0, 1e-6, 1.0):
            alone = np.array([damped_step(J[k], err[k], damping) for k in range(7)])
            # (6, 5) at damping 1e-6: JJ^T + 1e-6 I has condition ~1e6, round-off grows alike
            np.testing.assert_allclose(damped_step(J, err, damping), alone, rtol=1e-7, atol=1e-9)



def test_a_batch_drops_the_small_singular_values_one_step_drops() -> None:
    """A Jacobian one round-off from rank-deficient: the batch's pseudo-inverse cuts where one row's
    lstsq does (eps * max(m, n)), so no step grows to 1e14 along the vanishing direction."""
    rng = np.random.default_rng(6)
    U, _ = np.linalg.qr(rng.normal(size=(6, 6)))
    V, _ = np.linalg.qr(rng.normal(size=(6, 6)))
    J = U @ np.diag([1.0, 0.8, 0.6, 0.4, 0.2, 1.17e-15]) @ V.T  # 1e-15 (pinv's default) < 1.17e-15 < 6 eps
    err = rng.normal(size=6)
    alone = damped_step(J, err, 0.0)
    np.testing.assert_allclose(damped_step(J[None], err[None], 0.0)[0], alone, atol=1e-12)
    assert float(np.max(np.abs(alone))) < 100.0
    with pytest.raises(ValueError, match="stacked"):
        damped_step(J[None], err[None], 1e-3, stacked=True)


def test_a_batch_of_tall_least_squares_steps_is_the_pseudo_inverses_rank_deficient_rows_included() -> None:
    """The batch's QR steps (tall J of full rank, condition up to ~1e6 as the axis method's weighted
    rows have) equal the pseudo-inverse's; rows a column short of full rank, in the same batch, get
    the pseudo-inverse's minimum-norm step rather than a step blown up by a vanishing pivot."""
    rng = np.random.default_rng(7)
    J = rng.normal(size=(60, 6, 5)) * np.array([1e4, 1e4, 1e4, 1.0, 1.0, 0.01])[None, :, None]
    J[::7, :, 4] = J[::7, :, 2]  # rank 4
    err = rng.normal(size=(60, 6))
    pinv = np.einsum("kij,kj->ki", np.linalg.pinv(J, rcond=np.finfo(float).eps * 6), err)
    steps = damped_step(J, err, 0.0)
    np.testing.assert_allclose(steps, pinv, rtol=1e-9, atol=1e-12 * float(np.max(np.abs(pinv))))
    assert float(np.max(np.abs(steps[::7]))) < 1e3


def test_damped_solve_rows_drops_each_row_when_it_is_done() -> None:
    """Rows of a diagonal linear system: each row's error leaves the batch below ``tol``, and each
    row's result is what damped_solve gives it alone."""
    A = np.array([np.diag([1.0, 2.0, 4.0]), np.diag([1.0, 1.0, 1.0]), np.diag([3.0, 0.5, 2.0])])
    targets = np.array([[3.0, -1.0, 2.0], [0.0, 0.0, 0.0], [1.0, 2.0, -3.0]])
    asked: list[np.ndarray] = []

    def residual(q: np.ndarray, at: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        asked.append(at.copy())
        return targets[at] - np.einsum("kij,kj->ki", A[at], q), A[at]

    q = damped_solve_rows(residual, np.zeros((3, 3)), np.arange(3), damping=1e-3, tol=1e-13, iterations=60)
    np.testing.assert_allclose(np.einsum("kij,kj->ki", A, q), targets, atol=1e-13)
    assert 1 not in asked[1]  # row 1 starts at its target: gone after the first look
    for k in range(3):
        alone = damped_solve(lambda qk, k=k: (targets[k] - A[k] @ qk, A[k]), np.zeros(3), slice(None),
                             damping=1e-3, tol=1e-13, iterations=60)
        np.testing.assert_allclose(q[k], alone, atol=1e-14)



def test_damped_solve_rows_drops_each_row_when_its_step_is_small() -> None:
    """step_tol alone: an exact linear solve moves every row once; the next step of each is zero,
    so each row is asked twice and then leaves the batch, whatever ``iterations`` allows."""
    A = np.array([np.diag([1.0, 2.0, 4.0]), np.diag([3.0, 0.5, 2.0])])
    targets = np.array([[3.0, -1.0, 2.0], [1.0, 2.0, -3.0]])
    asked: list[np.ndarray] = []

    def residual(q: np.ndarray, at: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        asked.append(at.copy())
        return targets[at] - np.einsum("kij,kj->ki", A[at], q), A[at]

    q = damped_solve_rows(residual, np.zeros((2, 3)), np.arange(3), step_tol=1e-12, iterations=50)
    assert [a.tolist() for a in asked] == [[0, 1], [0, 1]]
    np.testing.assert_allclose(np.einsum("kij,kj->ki", A, q), targets, atol=1e-15)


def test_damped_solve_caps_steps_and_stops_on_the_error_or_the_step() -> None:
    A, target = np.diag([1.0, 2.0, 4.0]), np.array([3.0, -1.0, 2.0])
    calls: list[np.ndarray] = []

    def residual(q: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        calls.append(q.copy())
        return target - A @ q, A

    q = damped_solve(residual, np.zeros(3), slice(None), max_step=0.5, tol=1e-14, iterations=50)
    steps = np.abs(np.diff(np.array(calls), axis=0)).max(axis=1)
    assert float(steps.max()) <= 0.5 + 1e-15 and steps[0] == pytest.approx(0.5)  # capped, not scaled up
    np.testing.assert_allclose(A @ q, target, atol=1e-14)
    calls.clear()
    q = damped_solve(residual, np.zeros(3), [0, 2], step_tol=1e-12, iterations=50)  # joint 1 held
    assert q[1] == 0.0 and len(calls) == 2  # an exact linear solve, then a step under step_tol
    np.testing.assert_allclose(q[[0, 2]], [3.0, 0.5], atol=1e-15)


@pytest.fixture(scope="module")
def arm_cases() -> list[tuple[np.ndarray, np.ndarray, pin.SE3]]:
    """(q start, q goal, goal pose) of the ABB IRB 2400: goals a few degrees from the starts, seeded."""
    robot = load_robot("abb_irb2400")
    rng = np.random.default_rng(12)
    out = []
    for _ in range(8):
        q_goal = rng.uniform(-1.0, 1.0, 6) * np.array([2.0, 0.8, 0.8, 2.0, 1.5, 2.0]) + np.array([0, 0, 0, 0, 0.8, 0])
        out.append((q_goal + rng.uniform(-0.05, 0.05, 6), q_goal, robot.fk(q_goal)))
    return out


def test_the_re_solves_reach_their_targets(arm_cases: list[tuple[np.ndarray, np.ndarray, pin.SE3]]) -> None:
    robot = load_robot("abb_irb2400")
    for q0, q_goal, T in arm_cases:
        q = position_solve(robot, q0, T.translation[None])[0]  # a batch of one (N, n)
        assert float(np.linalg.norm(robot.fk(q).translation - T.translation)) < 1e-11
        np.testing.assert_array_equal(q[3:], q0[3:])  # only the arm joints move
        q = exact_orientation(robot, q0, T.rotation[None])[0]  # a batch of one (N, n)
        assert float(np.linalg.norm(pin.log3(robot.fk(q).rotation.T @ T.rotation))) < 1e-12
        np.testing.assert_array_equal(q[:3], q0[:3])
        start = q0.copy()
        start[3] = q_goal[3]  # five joints reach a full pose only with the held one at a solution's value
        q = hold_pose(robot, start, T.homogeneous, joint=3)
        assert float(np.max(np.abs(pose_error(robot, q, T.homogeneous)))) < 1e-12 and q[3] == q_goal[3]


def test_the_orientation_re_solve_of_a_batch_equals_each_sample_alone(
        arm_cases: list[tuple[np.ndarray, np.ndarray, pin.SE3]]) -> None:
    robot = load_robot("abb_irb2400")
    q0 = np.array([case[0] for case in arm_cases])
    R = np.array([case[2].rotation for case in arm_cases])
    alone = np.array([exact_orientation(robot, q0[k], R[k][None])[0] for k in range(len(q0))])
    np.testing.assert_allclose(exact_orientation(robot, q0, R), alone, atol=1e-12)


def test_axis_solve_keeps_the_held_joint_and_the_exact_component(
        arm_cases: list[tuple[np.ndarray, np.ndarray, pin.SE3]]) -> None:
    robot = load_robot("abb_irb2400")
    for q0, q_goal, T in arm_cases:
        q = axis_solve(robot, q0, T.homogeneous, fixed=3, exact="position")[0]  # a batch of one (N, n)
        assert float(np.linalg.norm(robot.fk(q).translation - T.translation)) < 1e-11 and q[3] == q0[3]
        # held 3 deg at most off the goal's value, the orientation error stays a few degrees
        assert math.degrees(float(np.linalg.norm(pin.log3(robot.fk(q).rotation.T @ T.rotation)))) < 10.0
        held = q_goal.copy()
        held[3] = q0[3]
        q = axis_solve(robot, held, T.homogeneous, fixed=3, exact="orientation")[0]
        assert float(np.linalg.norm(pin.log3(robot.fk(q).rotation.T @ T.rotation))) < 1e-12
