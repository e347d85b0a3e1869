"""Closed-form UR IK (example-robot-data ur5) against Pinocchio FK."""

from __future__ import annotations

import itertools
import math

import numpy as np
import pinocchio as pin
import pytest
from scipy.optimize import brentq

from singplan.kinematics.closedform.ur import UrParameters, ur_solutions
from singplan.kinematics.configuration import classify
from singplan.kinematics.ik.solve import solve_all, ur_arm_for_point
from singplan.kinematics.ik.turns import _distinct
from singplan.kinematics.robot import load_robot

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
    params = UrParameters.from_model(robot.model, robot.tip_frame_id)
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


def _solves_pose(robot, q, seed=None, tol=1e-9) -> bool:
    """solve_all(fk(q)) holds a solution reproducing the pose (joints may be non-unique on a boundary)."""
    T = robot.fk(q)
    for x in solve_all(robot, T, seed=seed).q:
        F = robot.fk(x)
        if (np.linalg.norm(F.translation - T.translation) <= tol
                and np.linalg.norm(pin.log3(F.rotation.T @ T.rotation)) <= tol):
            return True
    return False


def _ur_shoulder_q(robot, q):
    """q with q2 moved so the wrist point lies on the shoulder's singular plane (x of frame 1 = 0)."""
    def x1(q2):
        qq = np.array(q, dtype=float)
        qq[1] = q2
        robot.fk(qq)
        return robot.data.oMi[1].actInv(robot.data.oMi[6].translation)[0]

    grid = np.linspace(-3, 3, 61)
    for a, b in itertools.pairwise(grid):
        if x1(a) * x1(b) < 0:
            out = np.array(q, dtype=float)
            out[1] = brentq(x1, a, b, xtol=1e-15)
            return out
    return None


@pytest.mark.slow  # 85 unseeded and seeded solve_all calls on +-360 deg joints (whole-turn variants)
def test_ur_closed_form_solves_every_reach_boundary() -> None:
    """Straight elbow, all-zero joints, q5 = 0 and +-1e-9, exact shoulder singularity; seeded random q."""
    robot = load_robot("ur5")
    assert _solves_pose(robot, np.zeros(6))  # on main: no solution at all
    rng = np.random.default_rng(7)
    for trial in range(6):
        q = rng.uniform(-3, 3, 6)
        cases = []
        for q3 in (0.0, 1e-9, -1e-7, math.pi):
            cases.append(np.r_[q[:2], q3, q[3:]])
        for q5 in (0.0, 1e-9, -1e-9):
            cases.append(np.r_[q[:4], q5, q[5]])
            cases.append(np.r_[q[:2], rng.uniform(-1e-3, 1e-3), q[3], q5, q[5]])  # near straight too
        shoulder = _ur_shoulder_q(robot, q)
        if shoulder is not None:
            cases += [shoulder, np.r_[shoulder[:4], 0.0, shoulder[5]]]
        for qq in cases:
            if trial == 0:  # unseeded solve_all lists every whole-turn variant: slow on +-360 deg joints
                assert _solves_pose(robot, qq), qq
            assert _solves_pose(robot, qq, seed=qq + 0.01), qq


@pytest.mark.parametrize("name", ["abb_irb6700_200_260", "kuka_kr6_r700_sixx", "fanuc_r2000ib_210f",
                                  "staubli_tx2_60"])
def test_opw_closed_form_solves_the_stretched_elbow_and_the_wrist_singularity(name: str) -> None:
    robot = load_robot(name)
    p = robot.opw
    rng = np.random.default_rng(11)
    checked = 0
    for _ in range(10):
        q = rng.uniform(np.maximum(robot.lower_rad, -3), np.minimum(robot.upper_rad, 3))
        for t3 in (-math.atan2(p.a2, p.c3), math.pi - math.atan2(p.a2, p.c3)):
            for q5 in (q[4], 0.0, 1e-9, -1e-9):
                qq = q.copy()
                qq[2] = math.remainder((t3 + p.offsets[2]) * p.signs[2], 2 * math.pi)
                qq[4] = q5
                if np.all(qq >= robot.lower_rad) and np.all(qq <= robot.upper_rad):
                    assert _solves_pose(robot, qq), qq  # on main: 3e-8 m off at the stretched elbow
                    checked += 1
    assert checked > 0


def test_distinct_keeps_the_rows_pairwise_allclose_would_keep() -> None:
    """The compiled de-duplication of solve_all against the pairwise np.allclose(atol=1e-9) it replaced."""
    rng = np.random.default_rng(5)
    base = rng.uniform(-6.0, 6.0, (40, 6))
    rows = [*base, *(base[rng.integers(0, 40, 60)] + rng.choice([0.0, 1e-10, 1e-6, 1e-3], (60, 6)))]
    expected: list[int] = []
    for k, row in enumerate(rows):
        if not any(np.allclose(row, rows[j], atol=1e-9) for j in expected):
            expected.append(k)
    assert _distinct(np.array(rows)).tolist() == expected and len(expected) < len(rows)
