"""OPW closed-form IK against Pinocchio FK and the independent py-opw-kinematics."""

from __future__ import annotations

import math

import numpy as np
import pinocchio as pin
import pytest
from py_opw_kinematics import KinematicModel
from py_opw_kinematics import Robot as OpwRobot

from singplan.kinematics.angles import wrap_to_pi
from singplan.kinematics.configuration import classify
from singplan.kinematics.ik.solve import opw_arm_for_point, opw_batch, solve_all
from singplan.kinematics.robot import Robot

from .conftest import OPW_NAMES, random_q


def oracle(robot: Robot) -> OpwRobot:
    """py-opw-kinematics built from the registry's OPW parameters (offsets in rad with degrees=False)."""
    p = robot.opw
    assert p is not None
    model = KinematicModel(a1=p.a1, a2=p.a2, b=p.b, c1=p.c1, c2=p.c2, c3=p.c3, c4=p.c4,
                           offsets=tuple(p.offsets_rad), flip_axes=tuple(s < 0 for s in p.sign_corrections))
    return OpwRobot(model, degrees=False)


def pose_error(a: pin.SE3, b: pin.SE3) -> float:
    return float(np.abs(pin.log6(a.actInv(b)).vector).max())


@pytest.mark.parametrize("name", OPW_NAMES)
def test_fk_equals_independent_opw_fk(name: str, robots, rng) -> None:
    robot, ref = robots[name], oracle(robots[name])
    qs = random_q(robot, rng, 1000)
    ref_T = ref.batch_forward(qs).as_matrix()  # (1000, 4, 4)
    for q, T in zip(qs, ref_T, strict=True):
        mine = robot.fk(q).homogeneous
        assert np.abs(mine[:3, 3] - T[:3, 3]).max() < 1e-9
        assert np.linalg.norm(pin.log3(mine[:3, :3].T @ T[:3, :3])) < 1e-9


# three arms in the default run, the other seven with the slow tests (150 solve_all calls each: 1-2 s an arm
# on a loaded machine, more on the arms with +-360 deg joints)
_RECOVERS_FAST = {"abb_irb2400", "kuka_kr6_r900_2", "fanuc_lrmate200id"}


@pytest.mark.parametrize("name", [pytest.param(n, marks=() if n in _RECOVERS_FAST else pytest.mark.slow)
                                  for n in OPW_NAMES])
def test_ik_recovers_q_with_its_label_and_every_solution_reproduces_the_pose(name: str, robots, rng) -> None:
    tool = pin.SE3(pin.rpy.rpyToMatrix(0.1, 0.4, -0.3), np.array([0.01, -0.02, 0.12]))
    robot = robots[name].with_tool(tool)
    for q in random_q(robot, rng, 150):
        target = robot.fk(q)
        sols = solve_all(robot, target)
        assert len(sols) >= 1
        for q_sol in sols.q:
            assert pose_error(robot.fk(q_sol), target) < 1e-9
            assert robot.within_limits(q_sol)
        match = [k for k, q_sol in enumerate(sols.q) if np.allclose(q_sol, q, atol=1e-7)]
        assert match, f"{np.degrees(q)} not among the solutions"
        assert sols.labels[match[0]] == classify(robot, q).label


@pytest.mark.parametrize("name", OPW_NAMES)
def test_generic_pose_has_eight_distinct_labels_and_the_oracle_count(name: str, robots, rng) -> None:
    robot, ref = robots[name], oracle(robots[name])
    checked = 0
    for q in random_q(robot, rng, 100):
        T = robot.fk(q).homogeneous
        sols = opw_batch(robot.opw, T[None])[0]
        finite = sols[np.all(np.isfinite(sols), axis=1)]
        theirs = np.array(ref.inverse(ref.forward(tuple(q))))
        assert len(finite) == len(theirs)
        for t in theirs:
            assert np.min(np.abs(wrap_to_pi(finite - t)).max(axis=1)) < 1e-9
        if len(finite) == 8:
            assert len({classify(robot, s).label for s in finite}) == 8
            checked += 1
    assert checked > 20


@pytest.mark.parametrize("name", OPW_NAMES)
def test_branch_index_always_carries_the_same_label(name: str, robots, rng) -> None:
    """The geometric classifier agrees with the OPW branch structure on every arm."""
    robot = robots[name]
    seen: dict[int, set[str]] = {}
    for q in random_q(robot, rng, 60):
        sols = opw_batch(robot.opw, robot.fk(q).homogeneous[None])[0]
        for k in range(8):
            if np.all(np.isfinite(sols[k])):
                seen.setdefault(k, set()).add(classify(robot, sols[k]).label)
    assert all(len(labels) == 1 for labels in seen.values())
    assert seen[0] == {"F U N"} and seen[7] == {"B D F"}


def test_batch_matches_single_pose_solutions(robots, rng) -> None:
    robot = robots["kuka_kr6_r900_2"]
    qs = random_q(robot, rng, 50)
    T = np.array([robot.fk(q).homogeneous for q in qs])
    batch = opw_batch(robot.opw, T)
    assert batch.shape == (50, 8, 6)
    for k in range(50):
        single = opw_batch(robot.opw, T[k][None])[0]
        np.testing.assert_array_equal(np.isnan(single), np.isnan(batch[k]))
        np.testing.assert_allclose(single[np.isfinite(single)], batch[k][np.isfinite(batch[k])], atol=0)


def test_unreachable_pose_gives_nan_rows_and_no_solution(robots) -> None:
    robot = robots["abb_irb2400"]
    far = pin.SE3(np.eye(3), np.array([5.0, 0.0, 1.0]))
    assert np.all(np.isnan(opw_batch(robot.opw, far.homogeneous[None])))
    assert len(solve_all(robot, far)) == 0


@pytest.mark.parametrize("name", OPW_NAMES)
def test_exact_wrist_singular_pose_keeps_every_branch_and_the_seed_q4(name: str, robots, rng) -> None:
    robot = robots[name]
    for q in random_q(robot, rng, 20):
        q[4] = robot.opw.offsets_rad[4] * robot.opw.sign_corrections[4]  # q5_opw = 0: axes 4 and 6 collinear
        target = robot.fk(q)
        canonical = opw_batch(robot.opw, target.homogeneous[None])[0]
        finite = np.all(np.isfinite(canonical), axis=1)
        assert finite.any() and np.array_equal(finite[:4], finite[4:])  # no wrist branch is lost
        sols = solve_all(robot, target, seed=q)
        assert len(sols) >= 1 and not np.any(np.isnan(sols.q))
        for q_sol in sols.q:
            assert pose_error(robot.fk(q_sol), target) < 1e-9
        assert any(np.allclose(q_sol, q, atol=1e-9) for q_sol in sols.q), "seed's q4 not kept"


def test_two_pi_variants_are_expanded_within_limits_and_the_seed_picks_one(robots) -> None:
    robot = robots["abb_irb2400"]  # joint 6: +-400 deg
    q = np.radians([10.0, 20.0, 10.0, 30.0, 40.0, 50.0])
    target = robot.fk(q)
    sols = solve_all(robot, target)
    same_branch = [s for s in sols.q if np.allclose(s[:5], q[:5], atol=1e-9)]
    q6_values = sorted(round(math.degrees(s[5]), 6) for s in same_branch)
    assert q6_values == [-310.0, 50.0]  # 410 deg is past the +-400 deg limit
    seeded = solve_all(robot, target, seed=np.radians([10, 20, 10, 30, 40, -300]))
    picked = [s for s in seeded.q if np.allclose(s[:5], q[:5], atol=1e-9)]
    assert len(picked) == 1 and math.isclose(math.degrees(picked[0][5]), -310.0, abs_tol=1e-6)


@pytest.mark.parametrize("name", OPW_NAMES)
def test_arm_solve_for_a_flange_point_puts_the_tcp_on_target_with_the_wrist_held(name: str, robots, rng) -> None:
    """SEEDS 001's closed-form arm solve, checked with Pinocchio's FK of the whole chain."""
    tool = pin.SE3(pin.rpy.rpyToMatrix(0.2, -0.1, 0.3), np.array([0.02, -0.03, 0.12]))
    robot = robots[name].with_tool(tool)
    q = random_q(robot, rng, 200)
    targets = np.array([robot.fk(x).translation for x in q])
    seeds = q.copy()
    seeds[:, :3] += rng.normal(0.0, 0.05, size=(len(q), 3))
    out = opw_arm_for_point(robot.opw, seeds, tool.translation, targets)
    assert np.array_equal(out[:, 3:], seeds[:, 3:])  # the wrist is held
    error_m = [np.linalg.norm(robot.fk(x).translation - t) for x, t in zip(out, targets, strict=True)]
    assert max(error_m) < 1e-9
    recovered = np.max(np.abs(out[:, :3] - q[:, :3]), axis=1) < 1e-7
    assert recovered.mean() > 0.97  # the seed's own arm solution, unless another one is as near
