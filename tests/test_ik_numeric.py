"""Numeric all-branch IK (singplan.kinematics.ik.numeric) against a brute-force reference.

The reference knows nothing of the solver's seeds: it runs damped Gauss-Newton from 1000
uniformly random starts over the whole joint torus at once, with its own forward kinematics
and geometric Jacobian in numpy (no Pinocchio), keeps the starts that converge and sorts them
into branches modulo whole turns, then keeps the branches that have a variant inside the limits.
"""

from __future__ import annotations

import io
import math
import re
from pathlib import Path

import numpy as np
import pinocchio as pin
import pytest

from singplan.cli import main
from singplan.kinematics.ik.numeric import all_branches, halton, into_limits
from singplan.kinematics.ik.solve import closed_form_branches, solve_all
from singplan.kinematics.robot import Robot, load_robot, robots_dir

TWO_PI = 2.0 * math.pi
POSE_TOL = 1e-9  # [m] and [rad]: every solution must reproduce its pose to this
SAME_RAD = 1e-6  # two solutions closer than this modulo whole turns are one branch
N_STARTS = 1000


def _wrap(a: np.ndarray) -> np.ndarray:
    return a - TWO_PI * np.round(a / TWO_PI)


def _pose_error(robot: Robot, q: np.ndarray, T: pin.SE3) -> tuple[float, float]:
    """Position [m] and rotation [rad] error of FK(q) against T."""
    T_q = robot.fk(q)
    return (float(np.linalg.norm(T_q.translation - T.translation)),
            float(np.linalg.norm(pin.log3(T_q.rotation.T @ T.rotation))))


def _axis_rotations(axis: np.ndarray, angles: np.ndarray) -> np.ndarray:
    """Rodrigues' rotations about one unit axis for N angles (N, 3, 3)."""
    K = np.array([[0.0, -axis[2], axis[1]], [axis[2], 0.0, -axis[0]], [-axis[1], axis[0], 0.0]])
    s, c = np.sin(angles)[:, None, None], np.cos(angles)[:, None, None]
    return np.eye(3) + s * K + (1.0 - c) * (K @ K)


def _fk_and_jacobian(robot: Robot, q: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """TCP positions (N, 3), rotations (N, 3, 3) and world-frame geometric Jacobians (N, 6, n)."""
    n_rows = len(q)
    R, p = np.broadcast_to(np.eye(3), (n_rows, 3, 3)), np.zeros((n_rows, 3))
    axes, origins = [], []
    for placement, axis, iq in robot._chain_steps:
        p = p + R @ placement.translation
        R = R @ placement.rotation
        axes.append(R @ axis)
        origins.append(p)
        R = R @ _axis_rotations(axis, q[:, iq])
    tool = robot.model.frames[robot.tip_frame_id].placement * robot.T_tip_tcp
    p_tcp, R_tcp = p + R @ tool.translation, R @ tool.rotation
    J = np.empty((n_rows, 6, robot.n_joints))
    for j, (z, o) in enumerate(zip(axes, origins, strict=True)):
        J[:, :3, j], J[:, 3:, j] = np.cross(z, p_tcp - o), z
    return p_tcp, R_tcp, J


def brute_force_branches(robot: Robot, T: pin.SE3, rng: np.random.Generator) -> list[np.ndarray]:
    """Every branch inside the limits that damped Gauss-Newton reaches from N_STARTS random starts."""
    q = rng.uniform(-math.pi, math.pi, size=(N_STARTS, robot.n_joints))
    for _ in range(60):
        p, R, J = _fk_and_jacobian(robot, q)
        R_err = T.rotation @ np.transpose(R, (0, 2, 1))
        w = 0.5 * np.stack([R_err[:, 2, 1] - R_err[:, 1, 2], R_err[:, 0, 2] - R_err[:, 2, 0],
                            R_err[:, 1, 0] - R_err[:, 0, 1]], axis=1)
        err = np.concatenate([T.translation - p, w], axis=1)
        JT = np.transpose(J, (0, 2, 1))
        step = np.linalg.solve(JT @ J + 1e-9 * np.eye(robot.n_joints), (JT @ err[:, :, None]))[:, :, 0]
        scale = np.minimum(1.0, 0.5 / np.maximum(np.linalg.norm(step, axis=1), 1e-300))
        q = q + scale[:, None] * step
    branches: list[np.ndarray] = []
    for qk in _wrap(q):
        if max(_pose_error(robot, qk, T)) < POSE_TOL and has_variant_inside(robot, qk) and not any(
                np.all(np.abs(_wrap(qk - b)) < SAME_RAD) for b in branches):
            branches.append(qk)
    return branches


def has_variant_inside(robot: Robot, q: np.ndarray) -> bool:
    k_lo = np.ceil((robot.lower_rad - q) / TWO_PI - 1e-12)
    k_hi = np.floor((robot.upper_rad - q) / TWO_PI + 1e-12)
    return bool(np.all(k_lo <= k_hi))


def found_in(branch: np.ndarray, rows: list[np.ndarray]) -> bool:
    return any(np.all(np.abs(_wrap(branch - r)) < SAME_RAD) for r in rows)


@pytest.fixture(scope="module")
def offset_wrist_robot(tmp_path_factory: pytest.TempPathFactory) -> Robot:
    """The FANUC M-10iA with axis 6 moved 50 mm off axis 5: no spherical wrist, no closed form."""
    text = (robots_dir() / "fanuc_m10ia.urdf").read_text()
    joint6 = re.search(r'<joint name="joint_6" type="revolute">.*?</joint>', text, re.S)
    assert joint6 is not None
    edited = joint6.group(0).replace('<origin xyz="0.1 0.0 0.0"', '<origin xyz="0.1 0.0 0.05"')
    assert edited != joint6.group(0)
    path = Path(tmp_path_factory.mktemp("urdf")) / "offset_wrist.urdf"
    path.write_text(text.replace(joint6.group(0), edited))
    robot = load_robot(path)
    assert robot.opw is None
    assert len(closed_form_branches(robot, robot.fk(np.zeros(6)).homogeneous[None])[0]) == 0
    return robot


def test_offset_wrist_is_not_spherical(offset_wrist_robot: Robot) -> None:
    """Axes 5 and 6 of the edited arm do not meet (distance of the two lines > 1 cm)."""
    placements = offset_wrist_robot.joint_placements(np.zeros(6))
    steps = offset_wrist_robot._chain_steps
    a5, a6 = placements[4].rotation @ steps[4][1], placements[5].rotation @ steps[5][1]
    normal = np.cross(a5, a6)
    gap_m = abs(float(np.dot(placements[5].translation - placements[4].translation, normal))) / np.linalg.norm(normal)
    assert gap_m > 0.01


@pytest.mark.slow  # a brute-force reference search at 30 poses
def test_finds_every_reference_branch_of_an_offset_wrist_arm(offset_wrist_robot: Robot) -> None:
    """At 30 random reachable poses the solver finds every branch the brute force finds."""
    robot = offset_wrist_robot
    rng = np.random.default_rng(11)
    reference_total = found_total = 0
    for _ in range(30):
        T = robot.fk(rng.uniform(robot.lower_rad, robot.upper_rad))
        reference = brute_force_branches(robot, T, rng)
        rows, _ = all_branches(robot, T)
        for q in rows:
            assert robot.within_limits(q)
            assert max(_pose_error(robot, q, T)) < POSE_TOL
        assert len(reference) >= 1  # the pose came from FK inside the limits
        reference_total += len(reference)
        found_total += sum(found_in(b, rows) for b in reference)
    assert found_total == reference_total, f"found {found_total} of {reference_total} reference branches"


@pytest.mark.parametrize("name", [pytest.param("fanuc_m10ia", marks=pytest.mark.slow), "kuka_kr6_r900_2"])
def test_same_branches_as_the_closed_form_on_opw_arms(name: str) -> None:
    """On OPW arms the numeric solver returns exactly the closed form's branches inside the limits."""
    robot = load_robot(name)
    rng = np.random.default_rng(5)
    for _ in range(15):
        T = robot.fk(rng.uniform(robot.lower_rad, robot.upper_rad))
        closed = [c for c in closed_form_branches(robot, T.homogeneous[None])[0]
                  if np.all(np.isfinite(c)) and has_variant_inside(robot, c)]
        rows, _ = all_branches(robot, T)
        assert len(rows) == len(closed)
        assert all(found_in(c, rows) for c in closed)


def test_unreachable_pose_gives_no_branch_and_is_deterministic() -> None:
    robot = load_robot("fanuc_m10ia")
    assert all_branches(robot, pin.SE3(np.eye(3), np.array([5.0, 0.0, 0.5])))[0] == []
    T = robot.fk(np.radians([10.0, 20.0, -30.0, 40.0, 50.0, 60.0]))
    first, second = all_branches(robot, T)[0], all_branches(robot, T)[0]
    assert len(first) == len(second) and all(np.array_equal(a, b) for a, b in zip(first, second, strict=True))


def test_halton_and_into_limits() -> None:
    points = halton(64, 7)
    assert points.shape == (64, 7) and np.all((points > 0.0) & (points < 1.0))
    assert len(np.unique(points[:, 0])) == 64
    lower, upper = np.radians([-170.0, -10.0]), np.radians([170.0, 300.0])
    assert np.allclose(into_limits(np.radians([350.0, -70.0]), lower, upper), np.radians([-10.0, 290.0]))
    assert np.allclose(into_limits(np.radians([175.0, 0.0]), lower, upper), np.radians([170.0, 0.0]))


PANDA_ARGS = ["ik", "panda", "--xyz", "0.4", "0", "0.4", "--rpy-deg", "180", "0", "0"]


def test_cli_ik_solves_the_panda() -> None:
    """`singplan ik panda` lists solutions of a pose least squares reaches; each row reproduces it."""
    out = io.StringIO()
    assert main(PANDA_ARGS, out=out, err=io.StringIO()) == 0
    lines = out.getvalue().splitlines()
    count = int(lines[0].split()[0])
    assert count >= 1 and len(lines) == count + 2
    robot = load_robot("panda")
    T = pin.SE3(pin.rpy.rpyToMatrix(math.pi, 0.0, 0.0), np.array([0.4, 0.0, 0.4]))
    for line in lines[2:]:
        q = np.radians([float(v) for v in line.split()[-11:-4]])  # label, 7 joints, 4 distance columns
        assert robot.within_limits(q, tol=1e-4)
        assert _pose_error(robot, q, T)[0] < 1e-3  # the printout has 3 decimals [deg]


def test_panda_solutions_are_exact_distinct_and_nearest_first() -> None:
    robot = load_robot("panda")
    T = pin.SE3(pin.rpy.rpyToMatrix(math.pi, 0.0, 0.0), np.array([0.4, 0.0, 0.4]))
    seed = np.radians([0.0, 0.0, 0.0, -120.0, 0.0, 120.0, 45.0])
    sols = solve_all(robot, T, seed=seed)
    assert len(sols) == 1 and sols.labels == ("-",)  # a 7R arm has no configuration labels: its nearest point
    for q in sols.q:
        assert robot.within_limits(q) and max(_pose_error(robot, q, T)) < POSE_TOL
    # the seed's own neighbourhood: the nearest solution lies on the seed's symmetric plane (q1 = q3 = q5 = 0)
    assert np.allclose(sols.q[0][[0, 2, 4]], 0.0, atol=1e-6)
    assert into_limits(sols.q[0], robot.lower_rad, robot.upper_rad) == pytest.approx(sols.q[0])
    unlabelled, _ = all_branches(robot, T, seed)  # without labels: one point of the family, the nearest found
    assert len(unlabelled) == 1 and max(_pose_error(robot, unlabelled[0], T)) < POSE_TOL
