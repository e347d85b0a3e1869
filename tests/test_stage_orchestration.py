"""Small stages of planning.orchestration on their own: the fly-by ramps against their defining
properties by finite differences, a held joint of a 7-joint arm against Pinocchio's full model, the
PTP duration bound against the closed form per joint and against the timing it bounds, and a move that
stops on its path timed in pieces from rest to rest."""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from hypothesis.extra.numpy import arrays

from singplan.kinematics.robot import Robot, load_robot
from singplan.planning.crossing.methods import Ptp
from singplan.planning.orchestration.blending import RAMPS, Ramp, ramps
from singplan.planning.orchestration.move_plan import plan_move
from singplan.planning.orchestration.planner import ptp_duration_bound_s
from singplan.planning.orchestration.redundancy import HeldJoint, hold_joint
from singplan.planning.orchestration.stops import stops, time_in_pieces
from singplan.planning.orchestration.targets import load_task_robot, start_joints
from singplan.planning.path.jointmap import JointMap, JointPart
from singplan.planning.timing.move import time_move
from singplan.planning.timing.records import MoveLimits
from singplan.task.load import load_task

H = 1e-5


def _derivatives(kind: Ramp, v: float) -> np.ndarray:
    """(alpha, beta) and their first and second derivatives at v by central differences, (3, 2)."""
    x = np.array([v - H, v, v + H])
    alpha, beta = ramps(x, kind)
    f = np.stack([alpha, beta], axis=1)
    return np.array([f[1], (f[2] - f[0]) / (2 * H), (f[2] - 2 * f[1] + f[0]) / H**2])


@pytest.mark.parametrize("kind", RAMPS)
def test_the_ramps_go_from_the_incoming_move_to_the_outgoing_one_and_mirror_each_other(kind: Ramp) -> None:
    v = np.linspace(0.0, 1.0, 101)
    alpha, beta = ramps(v, kind)
    np.testing.assert_allclose(ramps(np.array([0.0, 1.0]), kind), [[0.0, 1.0], [0.0, 1.0]], atol=1e-15)
    np.testing.assert_allclose(beta, 1.0 - ramps(1.0 - v, kind)[0], atol=1e-15)  # beta(v) = 1 - alpha(1 - v)
    assert np.all(np.diff(alpha) >= 0.0) and np.all(np.diff(beta) >= 0.0)
    # the incoming move keeps its speed into the blend (alpha'(0) = beta'(1) = 2: its path parameter runs on
    # at the rate it had, over the blend's half length) and each ramp is at rest where it hands over
    start, end = _derivatives(kind, H), _derivatives(kind, 1.0 - H)
    assert start[1, 0] == pytest.approx(2.0, abs=1e-3) and end[1, 1] == pytest.approx(2.0, abs=1e-3)
    assert abs(end[1, 0]) < 1e-3 and abs(start[1, 1]) < 1e-3


def test_the_quartic_ramps_are_c2_at_the_seams_and_the_quadratic_has_constant_acceleration() -> None:
    for v in (H, 1.0 - H):  # second derivatives where the blend meets the moves: 0 for the quartic (C2 seams)
        assert np.max(np.abs(_derivatives("quartic", v)[2])) < 1e-3
    for v in (0.1, 0.5, 0.9):
        np.testing.assert_allclose(_derivatives("quadratic", v)[2], [-2.0, 2.0], atol=1e-4)


@pytest.fixture(scope="module")
def panda_held() -> tuple[Robot, HeldJoint]:
    robot = load_robot("panda")
    return robot, hold_joint(robot, robot.joint_names[2], 0.4)


@settings(max_examples=30, deadline=None, derandomize=True)
@given(arrays(float, 6, elements=st.floats(-1.5, 1.5)))
def test_a_held_joint_chain_is_the_full_arm_with_that_joint_put_back(panda_held: tuple[Robot, HeldJoint],
                                                                     q6: np.ndarray) -> None:
    robot, held = panda_held
    q7 = held.expand(q6)
    assert q7[2] == 0.4 and held.joint == robot.joint_names[2]
    np.testing.assert_array_equal(held.reduce(q7), q6)
    full, reduced = robot.fk(q7), held.reduced.fk(q6)
    np.testing.assert_allclose(reduced.translation, full.translation, atol=1e-12)
    np.testing.assert_allclose(reduced.rotation, full.rotation, atol=1e-12)
    # and the Jacobian is the full one without the held joint's column
    np.testing.assert_allclose(held.reduced.jacobian(q6), np.delete(robot.jacobian(q7), 2, axis=1), atol=1e-12)


@settings(max_examples=40, deadline=None, derandomize=True)
@given(arrays(float, 6, elements=st.floats(-2.0, 2.0)), arrays(float, 6, elements=st.floats(0.3, 3.0)),
       arrays(float, 6, elements=st.floats(1.0, 20.0)))
def test_the_ptp_bound_is_the_slowest_joints_own_time(step: np.ndarray, v: np.ndarray, a: np.ndarray) -> None:
    q0 = np.zeros(6)
    bound = ptp_duration_bound_s(q0, step, MoveLimits(v, a, 0.0, None))
    alone = []
    for d, vj, aj in zip(np.abs(step), v, a, strict=True):  # each joint from rest to rest on its own
        t_ramp = vj / aj
        alone.append(2.0 * math.sqrt(d / aj) if d <= vj * t_ramp else d / vj + t_ramp)
    assert bound == pytest.approx(max(alone), rel=1e-12, abs=1e-15)


def test_no_timing_of_a_ptp_beats_its_bound_and_one_joint_alone_meets_it() -> None:
    robot = load_robot("abb_irb2400")
    q0 = np.radians([0, 10, 20, 0, 30, 0])
    limits = MoveLimits(robot.velocity_rad_s, np.full(6, 8.0), 0.0, None)
    for step in ([0.9, -0.2, 0.3, 0.0, 0.1, 0.4], [0.01, 0.2, 0.0, 0.0, 0.0, 1.2], [0.0, 0.0, 0.7, 0.0, 0.0, 0.0]):
        q1 = q0 + np.array(step)
        jmap = JointMap(robot, None, [JointPart("ptp", np.array([0.0, 1.0]), np.array([q0, q1]))])
        timed = time_move(jmap, limits, 0.004, 0, 100_000)
        bound = ptp_duration_bound_s(q0, q1, limits)
        assert bound <= timed.duration_s
        if np.count_nonzero(step) == 1:  # one joint: the line is that joint's own rest-to-rest time
            assert timed.duration_s <= bound * 1.001 + 0.004


def test_a_move_that_jumps_is_timed_in_pieces_at_rest_on_each_end_of_the_jump() -> None:
    """The ptp baseline on the demo's wrist hit (SEEDS 004): the move stops where the joint line starts
    and where it ends; from rest, one period within amax covers at most amax dt^2 / 2 on each side."""
    task = load_task(Path(__file__).resolve().parents[1] / "singplan" / "demo_task.yaml")
    robot = load_task_robot(task)
    q0 = start_joints(task, robot)
    pm = plan_move(robot, task, 0, task.moves[0], robot.fk(q0), q0, Ptp())
    (jump,) = pm.crossings
    assert jump.stops and stops(pm.crossings)
    period = 0.004
    tm = time_in_pieces(pm.jmap, pm.crossings, pm.limits, period, 0, 1_000_000)
    assert tm.speed_ratio <= 1.0 and tm.accel_ratio <= 1.0 and np.all(np.diff(tm.u) >= 0.0)
    np.testing.assert_allclose(tm.q, pm.jmap.evaluate(tm.u), atol=1e-9)  # every sample on the joint map
    at_rest = pm.limits.acceleration_rad_s2 * period**2 / 2.0 * (1 + 1e-9)
    for u, q in ((jump.blend.u0, jump.blend.q[0]), (jump.blend.u1, jump.q_exit)):
        (k,) = np.nonzero(tm.u == u)[0]  # one sample on each end of the jump
        np.testing.assert_allclose(tm.q[k], q, atol=1e-12)
        assert np.all(np.abs(tm.q[k] - tm.q[k - 1]) <= at_rest) and np.all(np.abs(tm.q[k + 1] - tm.q[k]) <= at_rest)
    # the joint line between: straight in joint space
    inside = (tm.u >= jump.blend.u0) & (tm.u <= jump.blend.u1)
    line = jump.q_exit - jump.blend.q[0]
    along = (tm.q[inside] - jump.blend.q[0]) @ line / (line @ line)
    np.testing.assert_allclose(tm.q[inside], jump.blend.q[0] + np.outer(along, line), atol=1e-9)
