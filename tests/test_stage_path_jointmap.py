"""planning.path.jointmap on its own: the Hermite blend against its end values and slopes (finite
differences), the piecewise-linear parts against numpy's interp, a map of several parts, and the
re-solves (position, orientation, axis) against Pinocchio's forward kinematics pose by pose."""

from __future__ import annotations

import numpy as np
import pinocchio as pin
import pytest
from hypothesis import assume, given, settings
from hypothesis import strategies as st
from hypothesis.extra.numpy import arrays

from singplan.kinematics.robot import Robot, load_robot
from singplan.planning.path.jointmap import (
    JointMap,
    JointPart,
    axis_solve,
    exact_orientation,
    exact_position,
    hermite,
    interpolate,
)

FAST = settings(max_examples=50, deadline=None, derandomize=True)
_values = arrays(float, (2, 3), elements=st.floats(-3.0, 3.0))


@FAST
@given(_values, _values, st.floats(0.0, 0.8), st.floats(0.05, 0.2))
def test_the_hermite_blend_meets_its_end_values_and_slopes(q: np.ndarray, slopes: np.ndarray, u0: float,
                                                           width: float) -> None:
    part = JointPart("blend", np.array([u0, u0 + width]), q, slopes)
    ends = hermite(part, np.array([u0, u0 + width]))
    np.testing.assert_allclose(ends, q, atol=1e-12)
    h = 1e-6 * width
    for u, slope in ((u0, slopes[0]), (u0 + width, slopes[1])):
        fd = (hermite(part, np.array([u + h]))[0] - hermite(part, np.array([u - h]))[0]) / (2 * h)
        np.testing.assert_allclose(fd, slope, atol=1e-5 * (1 + np.max(np.abs(q)) / width))
    # a cubic: its third finite difference is constant over the part
    u = np.linspace(u0, u0 + width, 9)
    third = np.diff(hermite(part, u), n=3, axis=0)
    np.testing.assert_allclose(third, np.broadcast_to(third[0], third.shape), atol=1e-9)


@FAST
@given(st.integers(2, 8).flatmap(lambda k: st.tuples(
    st.lists(st.floats(0.0, 1.0), min_size=k, max_size=k, unique=True),
    arrays(float, (k, 2), elements=st.floats(-3.0, 3.0)))), arrays(float, 12, elements=st.floats(-0.5, 1.5)))
def test_linear_parts_are_numpys_interpolation_and_constant_outside(ref: tuple[list[float], np.ndarray],
                                                                   u: np.ndarray) -> None:
    order = np.argsort(ref[0])
    u_ref, q_ref = np.array(ref[0])[order], ref[1][order]
    assume(np.min(np.diff(u_ref)) >= 1e-6)
    got = interpolate(JointPart("ptp", u_ref, q_ref), u)
    for j in range(2):
        np.testing.assert_allclose(got[:, j], np.interp(u, u_ref, q_ref[:, j]), atol=1e-12)


def test_a_map_of_several_parts_evaluates_each_on_its_own_stretch() -> None:
    robot = load_robot("abb_irb2400")
    a, b, c = np.zeros(6), np.full(6, 0.3), np.array([0.3, 0.1, 0.5, 0.3, 0.3, -0.2])
    slopes = np.array([np.full(6, 0.6), c - b])
    jmap = JointMap(robot, None, [JointPart("ptp", np.array([0.0, 0.5]), np.array([a, b])),
                                  JointPart("spline", np.array([0.5, 0.7, 1.0]), np.array([b, 0.5 * (b + c), c]),
                                            slopes)])
    u, q = jmap.reference()
    np.testing.assert_array_equal(u, [0.0, 0.5, 0.7, 1.0])  # the shared end once
    np.testing.assert_array_equal(q[[0, 1, 3]], [a, b, c])
    got = jmap.evaluate(np.array([-1.0, 0.25, 0.5, 0.6, 1.0, 2.0]))
    np.testing.assert_allclose(got[:3], [a, 0.5 * (a + b), b], atol=1e-15)
    np.testing.assert_allclose(got[[4, 5]], [c, c], atol=1e-12)  # clamped to [0, 1]
    assert not jmap.straight and jmap.off_path_parts == []  # a map with no path: nothing leaves it
    h = 1e-6  # the spline's end slopes are the part's
    np.testing.assert_allclose((jmap.evaluate(np.array([0.5 + h])) - jmap.evaluate(np.array([0.5]))) / h,
                               slopes[:1], atol=1e-4)


def _near(robot: Robot, rng: np.random.Generator, count: int) -> tuple[np.ndarray, np.ndarray]:
    """Joint values away from the limits and a small random change of them."""
    lo, hi = np.maximum(robot.lower_rad, -2.5), np.minimum(robot.upper_rad, 2.5)
    q = rng.uniform(lo + 0.3 * (hi - lo), hi - 0.3 * (hi - lo), size=(count, robot.n_joints))
    return q, q + rng.normal(0.0, 0.03, size=q.shape)


@pytest.mark.parametrize("name", ["abb_irb2400", "ur5"])  # the closed forms; other chains: damped Newton
def test_the_position_re_solve_reaches_each_target_and_keeps_the_wrist(name: str, rng: np.random.Generator) -> None:
    arm = load_robot(name)
    q_target, q_start = _near(arm, rng, 6)
    q_start[:, 3:] = q_target[:, 3:]  # the wrist right: the arm joints alone can reach the point
    targets = np.array([arm.fk(q).translation for q in q_target])
    q = exact_position(arm, q_start, targets)
    for k in range(len(q)):
        assert np.linalg.norm(arm.fk(q[k]).translation - targets[k]) < 1e-9
    np.testing.assert_array_equal(q[:, 3:], q_start[:, 3:])
    assert np.max(np.abs(q - q_start)) < 0.5  # the solution nearest the start, not another branch


@pytest.mark.parametrize("name", ["abb_irb2400", "ur5", "panda"])
def test_the_orientation_re_solve_reaches_each_rotation_with_the_wrist_alone(name: str,
                                                                           rng: np.random.Generator) -> None:
    arm = load_robot(name)
    q_target, q_start = _near(arm, rng, 6)
    q_start[:, :-3] = q_target[:, :-3]  # the arm joints right: the wrist alone can reach the rotation
    rotations = np.array([arm.fk(q).rotation for q in q_target])
    q = exact_orientation(arm, q_start, rotations)
    for k in range(len(q)):
        assert np.linalg.norm(pin.log3(arm.fk(q[k]).rotation.T @ rotations[k])) < 1e-9
    np.testing.assert_array_equal(q[:, :-3], q_start[:, :-3])


@pytest.mark.parametrize(("fixed", "exact"), [(3, "position"), (0, "orientation")])
def test_the_axis_solve_holds_its_joint_and_keeps_one_pose_component_exact(fixed: int, exact: str,
                                                                           rng: np.random.Generator) -> None:
    """With the held joint 0.05 rad off the pose's own value the pose is out of reach: the kept component
    is exact and only the other one is off (SEEDS 000: wrist zone A4 held, shoulder A1 held)."""
    robot = load_robot("abb_irb2400")
    q_target, q_start = _near(robot, rng, 5)
    q_start[:, fixed] = q_target[:, fixed] + 0.05
    T = np.array([robot.fk(q).homogeneous for q in q_target])
    q = axis_solve(robot, q_start, T, fixed, exact)
    np.testing.assert_array_equal(q[:, fixed], q_start[:, fixed])
    for k in range(len(q)):
        reached = robot.fk(q[k])
        position = np.linalg.norm(reached.translation - T[k][:3, 3])
        angle = np.linalg.norm(pin.log3(reached.rotation.T @ T[k][:3, :3]))
        kept, other = (position, angle) if exact == "position" else (angle, position)
        assert kept < 1e-9 < 1e-5 < other
