"""One configuration labelling everywhere, and the IK's list without whole-turn duplicates.

On a singularity a distance's sign is round-off; ``classify``, the IK's list (``solve_all``,
``singplan ik``) and the planner's labels all read it by one rule
(:func:`singplan.kinematics.configuration.positive_sides`). The references here are independent of
singplan's solvers: a Levenberg-Marquardt written on Pinocchio alone, from many random seeds
(brute force), and forward kinematics.
"""

from __future__ import annotations

import io
import math

import numpy as np
import pinocchio as pin
import pytest

from singplan.cli import main
from singplan.kinematics.angles import wrap_to_pi
from singplan.kinematics.configuration import LABEL_ZERO, classify, distances_batch, labels_batch, positive_sides
from singplan.kinematics.ik.solve import solve_all
from singplan.kinematics.robot import Robot, load_robot

from .conftest import erd_urdf


def _robot(name: str) -> Robot:
    return load_robot(erd_urdf(name)) if name == "ur10" else load_robot(name)


def _lm(robot: Robot, T: pin.SE3, q: np.ndarray) -> np.ndarray | None:
    """Levenberg-Marquardt on the SE(3) log error, Pinocchio's FK and Jacobian only (the reference)."""
    model, data = robot.model, robot.model.createData()
    frame = robot.tip_frame_id
    target = T * robot.T_tip_tcp.inverse()  # the tip's pose
    for _ in range(200):
        pin.forwardKinematics(model, data, q)
        current = pin.updateFramePlacement(model, data, frame)
        err = pin.log6(current.actInv(target)).vector
        if np.linalg.norm(err) < 1e-12:
            return q
        J = pin.computeFrameJacobian(model, data, q, frame, pin.LOCAL)
        J = pin.Jlog6(current.actInv(target)) @ J
        q = q + J.T @ np.linalg.solve(J @ J.T + 1e-10 * np.eye(6), err)
    return None


def _distinct_mod_turns(rows: list[np.ndarray], tol: float) -> list[np.ndarray]:
    out: list[np.ndarray] = []
    for row in rows:
        if all(np.max(np.abs(wrap_to_pi(row - other))) > tol for other in out):
            out.append(row)
    return out


def _brute_force(robot: Robot, T: pin.SE3, count: int, seed: int) -> list[np.ndarray]:
    rng = np.random.default_rng(seed)
    found = [_lm(robot, T, q0) for q0 in rng.uniform(-math.pi, math.pi, (count, robot.n_joints))]
    return _distinct_mod_turns([wrap_to_pi(q) for q in found if q is not None], 1e-6)


@pytest.mark.parametrize("name", ["ur5", "ur10", "abb_irb2400"])
def test_the_list_is_every_solution_once(name: str) -> None:
    """At random poses the seeded list holds each brute-force solution (modulo whole turns, inside
    the limits) exactly once, each row labelled as ``classify`` labels it."""
    robot = _robot(name)
    rng = np.random.default_rng(11)
    checked = 0
    while checked < 3:
        q = rng.uniform(np.maximum(robot.lower_rad, -math.pi), np.minimum(robot.upper_rad, math.pi))
        if np.min(np.abs(distances_batch(robot, q[None])[0])) < 0.05:
            continue  # a near-singular pose: the brute force's continuum of solutions is the next test's
        T = robot.fk(q)
        listed = solve_all(robot, T, seed=np.zeros(robot.n_joints))
        reference = [r for r in _brute_force(robot, T, 150, checked)
                     if any(robot.within_limits(r + 2 * math.pi * k) for k in (-1, 0, 1))]
        assert len(listed) == len(_distinct_mod_turns(list(listed.q), 1e-6))  # no row twice
        for r in reference:
            assert sum(np.max(np.abs(wrap_to_pi(listed.q - r)), axis=1) < 1e-6) == 1
        assert len(listed) == len(reference)
        assert list(listed.labels) == [classify(robot, row).label for row in listed.q]
        checked += 1


def _singular_configurations(robot: Robot, rng: np.random.Generator) -> list[np.ndarray]:
    """q = 0, the OPW zero, and random joints with q5 = 0 or the elbow stretched (q3 at its zero)."""
    out = [np.zeros(robot.n_joints)]
    if robot.opw is not None:
        out.append(robot.opw.offsets * robot.opw.signs)
    for _ in range(6):
        q = rng.uniform(-2.0, 2.0, robot.n_joints)
        q[4] = out[-1][4]
        out.append(q)
        q = q.copy()
        p = robot.opw
        q[2] = out[0][2] if p is None else out[1][2] - math.atan2(p.a2, p.c3) * p.signs[2]
        out.append(q)
    return [q for q in out if robot.within_limits(q)]


@pytest.mark.parametrize("name", ["ur5", "ur10", "abb_irb2400", "kuka_kr6_r900_2"])
def test_singular_poses_have_one_label_and_no_duplicates(name: str) -> None:
    """On wrist and elbow singularities (the UR5 at q = 0 among them): the listed rows reproduce the
    pose, differ from one another beyond round-off modulo whole turns, carry classify's labels, and
    the row at the configuration itself (seeded there) carries its label."""
    robot = _robot(name)
    for q in _singular_configurations(robot, np.random.default_rng(5)):
        T = robot.fk(q)
        listed = solve_all(robot, T, seed=q)
        assert len(listed) == len(_distinct_mod_turns(list(listed.q), LABEL_ZERO))
        for row in listed.q:
            assert (robot.fk(row).inverse() * T).isIdentity(1e-9)
        assert list(listed.labels) == [classify(robot, row).label for row in listed.q]
        apart = np.max(np.abs(wrap_to_pi(listed.q - q)), axis=1)
        assert np.sum(apart < LABEL_ZERO) <= 1  # q itself is listed once (or, where the elbow is
        # stretched too, as another split of q4 and q6: the arm's round-off leaves them undefined)
        assert listed.labels[int(np.argmin(apart))] == classify(robot, q).label


def test_the_ur5_at_zero_reads_the_same_in_classify_and_ik() -> None:
    """The issue's case: classify said F U N, ``singplan ik`` F D F and listed two rows 360 deg apart."""
    robot = load_robot("ur5")
    assert classify(robot, np.zeros(6)).label == "F U N"
    T = robot.fk(np.zeros(6))
    rpy = np.degrees(pin.rpy.matrixToRpy(T.rotation))
    for rpy_deg in (rpy, np.round(rpy, 6)):  # the exact pose, and as a user types it
        out = io.StringIO()
        assert main(["ik", "ur5", "--xyz", *map(str, T.translation), "--rpy-deg", *map(str, rpy_deg)],
                    out=out, err=io.StringIO()) == 0
        rows = out.getvalue().splitlines()[2:]
        assert rows[0].startswith("F U N ")
        assert [float(v) for v in rows[0].split()[3:9]] == pytest.approx([0] * 6, abs=1e-6)
        joints = np.radians([[float(v) for v in row.split()[3:9]] for row in rows])
        assert len(_distinct_mod_turns(list(joints), 1e-6)) == len(rows)


def test_positive_sides_reads_round_off_as_on_the_singularity() -> None:
    d = np.array([[0.0, 0.0, 0.0], [-1e-8, -1e-8, -1e-8], [-2 * LABEL_ZERO, -2 * LABEL_ZERO, -2 * LABEL_ZERO],
                  [-math.pi + 1e-9, 1.0, math.pi], [-math.pi + 2 * LABEL_ZERO, 1.0, -math.pi + 1e-12],
                  [np.nan, np.nan, np.nan]])
    expected = [[True] * 3, [True] * 3, [False] * 3, [True] * 3, [False, True, True], [False] * 3]
    assert positive_sides(d).tolist() == expected


@pytest.mark.parametrize("name", ["ur5", "abb_irb2400"])
def test_the_planner_s_labels_are_classify_s(name: str) -> None:
    """The batch labels the planner records go by the same rule, row by row, near every boundary."""
    robot = _robot(name)
    rng = np.random.default_rng(3)
    q = rng.uniform(-2.0, 2.0, (400, 6))
    q[:, 4] = rng.choice([0.0, LABEL_ZERO, -LABEL_ZERO, -2 * LABEL_ZERO, 1e-9, -1e-9, math.pi, -math.pi], 400)
    assert labels_batch(robot, q) == [classify(robot, row).label for row in q]
