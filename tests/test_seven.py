"""7-axis arms: a held redundant joint (task key `redundancy`), minimum-norm tracking without it,
no configuration labels, `singplan ik --hold`; plans judged by the independent checker (those
marked slow: CI runs them with ``python -m pytest -q -m slow``)."""

from __future__ import annotations

import io
import itertools
import json
import math
from pathlib import Path
from typing import Any

import numpy as np
import pinocchio as pin
import pytest
import yaml

from singplan.cli import main
from singplan.kinematics.held import HeldJoint, hold_joint
from singplan.kinematics.robot import Robot, load_robot
from singplan.planning.orchestration.targets import task_arm
from singplan.planning.path.pieces import move_piece
from singplan.results.plan import plan
from singplan.task.load import parse_task

from .conftest import erd_urdf
from .shared import run_checker

HELD_TOL_RAD = 1e-9
POSE_TOL_M, POSE_TOL_RAD = 1e-9, 1e-9


def _pose(robot: Robot, q_deg: list[float]) -> dict[str, list[float]]:
    T = robot.fk(np.radians(q_deg))
    return {"xyz": T.translation.tolist(), "rpy_deg": np.degrees(pin.rpy.matrixToRpy(T.rotation)).tolist()}


def _panda_task(moves: list[dict[str, Any]], **extra: Any) -> dict[str, Any]:
    return {"robot": "panda", "start": {"joints_deg": PANDA_START},
            "redundancy": {"joint": "panda_joint3", "value_deg": 0.0}, "moves": moves, **extra}


# With joint 3 held at 0, the chain's configuration label "wrist" flips at joint 6 = 180 deg (joints 5 and 7
# parallel); its Jacobian is singular near joint 6 = 192 deg (the smallest singular value falls to ~0.001).
# A LIN and a CIRC from 165 to 195 deg pass both.
PANDA_START = [0.0, -20.0, 0.0, -110.0, 0.0, 165.0, -45.0]
PANDA_THROUGH = [10.0, -10.0, 0.0, -100.0, 0.0, 195.0, -45.0]
PANDA_VIA = [5.0, -12.0, 0.0, -104.0, 4.0, 178.0, -45.0]


def _run_checked(tmp_path: Path, task: dict[str, Any]) -> tuple[dict[str, Any], str]:
    """Plan through the CLI into tmp_path/out and run the independent checker on it."""
    task_file = tmp_path / "task.yaml"
    task_file.write_text(yaml.safe_dump(task))
    err = io.StringIO()
    code = main(["plan", str(task_file), "-o", str(tmp_path / "out"), "--quiet", "--no-report", "--no-replay"],
                out=io.StringIO(), err=err)
    assert code == 0, err.getvalue()
    traj = json.loads((tmp_path / "out" / "trajectory.json").read_text())
    run = run_checker(task_file, tmp_path / "out", "--quiet")
    assert run.returncode == 0, run.stdout + run.stderr
    return traj, run.stdout


def _held_error_rad(traj: dict[str, Any], joint: str, value_deg: float) -> float:
    j = traj["joint_names"].index(joint)
    return float(np.max(np.abs(np.array(traj["q"])[:, j] - math.radians(value_deg))))


def test_xarm7_from_example_robot_data_loads_and_holds_a_joint() -> None:
    xarm = load_robot(erd_urdf("xarm7"))
    assert xarm.n_joints == 7 and xarm.family == "seven"
    assert np.all(np.isfinite(xarm.lower_rad)) and np.all(xarm.lower_rad < xarm.upper_rad)
    held = hold_joint(xarm, "joint3", math.radians(20.0))
    assert held.reduced.n_joints == 6 and "joint3" not in held.reduced.joint_names
    assert held.reduced.family == "general6"  # no closed form fits the xArm's offsets
    rng = np.random.default_rng(7)
    for q in rng.uniform(np.maximum(held.reduced.lower_rad, -3), np.minimum(held.reduced.upper_rad, 3), (20, 6)):
        error = held.full.fk(held.expand(q)).actInv(held.reduced.fk(q))
        assert np.linalg.norm(error.translation) < 1e-12 and np.linalg.norm(pin.log3(error.rotation)) < 1e-12
    assert xarm.n_joints == 7  # the arm itself is left as it was


def _smallest_singular_value(held: HeldJoint, q: np.ndarray) -> float:
    """Smallest singular value of the 6R chain's TCP Jacobian along samples q (K, 7)."""
    return min(float(np.linalg.svd(held.reduced.jacobian(held.reduce(qk)), compute_uv=False)[-1]) for qk in q)


@pytest.mark.slow
def test_held_lin_through_the_singular_region_passes_the_checker(tmp_path: Path) -> None:
    panda = load_robot("panda")
    task = _panda_task([{"lin": {"to": _pose(panda, PANDA_THROUGH), "speed": 0.1}}])
    traj, _ = _run_checked(tmp_path, task)
    assert traj["joint_names"] == list(panda.joint_names)
    assert traj["task"]["redundancy"] == {"joint": "panda_joint3", "value_deg": 0.0}
    assert _held_error_rad(traj, "panda_joint3", 0.0) <= HELD_TOL_RAD
    assert np.all(np.array(traj["qd"])[:, 2] == 0.0) and np.all(np.array(traj["qdd"])[:, 2] == 0.0)
    crossings = [s for s in traj["segments"] if s["kind"] == "crossing"]
    assert crossings and crossings[0]["singularity"] == "wrist"
    assert traj["metrics"]["max_position_error_mm"] <= 0.01
    held = hold_joint(panda, "panda_joint3", 0.0)
    assert _smallest_singular_value(held, np.array(traj["q"])) < 0.005  # the path really passes the singularity


@pytest.mark.slow
def test_held_circ_and_ptp_pass_the_checker(tmp_path: Path) -> None:
    panda = load_robot("panda")
    task = _panda_task([{"circ": {"via": {"xyz": _pose(panda, PANDA_VIA)["xyz"]}, "to": _pose(panda, PANDA_THROUGH),
                                  "speed": 0.1}},
                        {"ptp": {"to": {"joints_deg": list(PANDA_START)}}}])
    traj, _ = _run_checked(tmp_path, task)
    assert _held_error_rad(traj, "panda_joint3", 0.0) <= HELD_TOL_RAD
    assert _smallest_singular_value(hold_joint(panda, "panda_joint3", 0.0), np.array(traj["q"])) < 0.01
    assert [s["kind"] for s in traj["segments"]][-1] == "ptp"
    assert any(s["kind"] == "crossing" and s["move"] == 0 for s in traj["segments"])


@pytest.mark.slow
def test_xarm7_held_lin_passes_the_checker(tmp_path: Path) -> None:
    xarm = load_robot(erd_urdf("xarm7"))
    start = [0.0, 20.0, 30.0, 60.0, 0.0, 40.0, 0.0]
    task = {"robot": str(xarm.urdf_path), "start": {"joints_deg": start},
            "redundancy": {"joint": "joint3", "value_deg": 30.0},
            "moves": [{"lin": {"to": _pose(xarm, [20.0, 30.0, 30.0, 70.0, 10.0, 30.0, 10.0]), "speed": 0.2}}]}
    traj, _ = _run_checked(tmp_path, task)
    assert _held_error_rad(traj, "joint3", 30.0) <= HELD_TOL_RAD


def _min_norm_reference(robot: Robot, poses: np.ndarray, q0: np.ndarray) -> np.ndarray:
    """q_dot = J^+ x_dot integrated in the poses' small steps (N, 4, 4), each corrected back onto the pose."""
    q, out = q0.copy(), [q0.copy()]
    for T0, T1 in itertools.pairwise(poses):
        twist = np.concatenate([T1[:3, 3] - T0[:3, 3], pin.log3(T1[:3, :3] @ T0[:3, :3].T)])
        q = q + np.linalg.pinv(robot.jacobian(q)) @ twist
        T = robot.fk(q)
        q = q + np.linalg.pinv(robot.jacobian(q)) @ np.concatenate(
            [T1[:3, 3] - T.translation, pin.log3(T1[:3, :3] @ T.rotation.T)])
        out.append(q.copy())
    return np.array(out)


@pytest.mark.slow  # plans a LIN and differentiates every sample
def test_lin_without_redundancy_follows_the_minimum_norm_joint_velocity() -> None:
    start = [0.0, -45.0, 0.0, -135.0, 0.0, 90.0, 45.0]
    task = parse_task({"robot": "panda", "start": {"joints_deg": start},
                       "moves": [{"lin": {"to": {"xyz": [0.5, 0.2, 0.3]}, "speed": 0.2}}]})
    traj = plan(task)
    robot = load_robot("panda")
    piece = move_piece(0, task.moves[0], robot.fk(np.radians(start)))
    ref = _min_norm_reference(robot, piece.poses(np.linspace(0.0, 1.0, 20_001)), np.radians(start))
    assert traj.metrics.max_position_error_mm <= 0.01 and traj.metrics.max_orientation_error_deg <= 0.01
    # the same end joints and the same joint-space path length as the fine minimum-norm integration
    assert np.max(np.abs(traj.q[-1] - ref[-1])) < math.radians(0.1)
    length = float(np.sum(np.linalg.norm(np.diff(traj.q, axis=0), axis=1)))
    ref_length = float(np.sum(np.linalg.norm(np.diff(ref, axis=0), axis=1)))
    assert abs(length - ref_length) < 1e-3 * ref_length
    assert {s.config_before for s in traj.segments} == {"-"} and not traj.events
    assert "distances" not in traj.samples  # no 6R singular distances: nothing (no NaN) stored


@pytest.mark.parametrize(("robot", "redundancy", "field", "words"), [
    ("ur5", {"joint": "wrist_1_joint", "value_deg": 0}, "redundancy", "7-joint"),
    ("panda", {"joint": "panda_joint9", "value_deg": 0}, "redundancy.joint", "panda_joint7"),
    ("panda", {"joint": "panda_joint4", "value_deg": 0}, "redundancy.value_deg", "outside its limits"),
    ("panda", {"joint": "panda_joint3", "value_deg": 10}, "start.joints_deg[2]", "holds it at 10"),
    ("panda", {"joint": "panda_joint3", "speed": 1}, "redundancy", "speed"),
    ("panda", None, "moves[0].lin.config", "no configuration labels"),
])
def test_bad_redundancy_and_labels_exit_2_naming_the_field(tmp_path: Path, robot: str, redundancy: Any,
                                                           field: str, words: str) -> None:
    start = PANDA_START if robot == "panda" else [0, -90, 90, 0, 45, 0]
    move: dict[str, Any] = {"to": {"xyz": [0.4, 0.0, 0.5]}, **({"config": "F U N"} if redundancy is None else {})}
    task = {"robot": robot, "start": {"joints_deg": start}, "moves": [{"lin": move}],
            **({"redundancy": redundancy} if redundancy is not None else {})}
    task_file = tmp_path / "task.yaml"
    task_file.write_text(yaml.safe_dump(task))
    err = io.StringIO()
    assert main(["plan", str(task_file), "-o", str(tmp_path / "out")], out=io.StringIO(), err=err) == 2
    assert field in err.getvalue() and words in err.getvalue()
    assert not (tmp_path / "out").exists()


def _ik_rows(argv: list[str]) -> np.ndarray:
    out = io.StringIO()
    assert main(argv, out=out, err=io.StringIO()) == 0
    return np.radians([[float(v) for v in line.split()[-11:-4]] for line in out.getvalue().splitlines()[2:]])


def test_ik_with_and_without_a_held_joint_reaches_the_issue_pose() -> None:
    panda = load_robot("panda")
    T = pin.SE3(pin.rpy.rpyToMatrix(math.pi, 0.0, 0.0), np.array([0.4, 0.0, 0.4]))
    args = ["ik", "panda", "--xyz", "0.4", "0", "0.4", "--rpy-deg", "180", "0", "0"]
    for argv, held_deg in ((args, None), ([*args, "--hold", "panda_joint3=20"], 20.0)):
        rows = _ik_rows(argv)
        assert len(rows) >= 1
        for q in rows:
            assert np.linalg.norm(panda.fk(q).translation - T.translation) < 1e-4  # 3 printed decimals [deg]
            if held_deg is not None:
                assert q[2] == pytest.approx(math.radians(held_deg), abs=1e-9)
    err = io.StringIO()
    assert main([*args, "--hold", "panda_joint3"], out=io.StringIO(), err=err) == 2 and "--hold" in err.getvalue()
    err = io.StringIO()
    assert main([*args, "--hold", "elbow=0"], out=io.StringIO(), err=err) == 2 and "--hold.joint" in err.getvalue()


SRS_AXES = ["0 0 1", "0 1 0", "0 0 1", "0 -1 0", "0 0 1", "0 1 0", "0 0 1"]
SRS_OFFSETS_M = [0.0, 0.34, 0.0, 0.4, 0.0, 0.4, 0.0]  # along z from the previous joint (KUKA iiwa-like)


def _srs_urdf(path: Path) -> Path:
    """A 7R arm with spherical shoulder and wrist (S-R-S): with joint 3 at 0 the rest is an OPW arm."""
    links = "".join(f'<link name="l{k}"/>' for k in range(8)) + '<link name="tool0"/>'
    joints = "".join(
        f'<joint name="a{k + 1}" type="revolute"><parent link="l{k}"/><child link="l{k + 1}"/>'
        f'<origin xyz="0 0 {SRS_OFFSETS_M[k]}"/><axis xyz="{SRS_AXES[k]}"/>'
        f'<limit lower="-2.9" upper="2.9" velocity="1.5" effort="100"/></joint>' for k in range(7))
    joints += ('<joint name="flange" type="fixed"><parent link="l7"/><child link="tool0"/>'
               '<origin xyz="0 0 0.126"/></joint>')
    path.write_text(f'<robot name="srs7">{links}{joints}</robot>')
    return path


def test_a_held_srs_arm_is_an_opw_arm_and_auto_crosses_its_wrist_with_wrist_joint(tmp_path: Path) -> None:
    arm = load_robot(_srs_urdf(tmp_path / "srs7.urdf"))
    assert hold_joint(arm, "a3", 0.0).reduced.family == "opw"
    assert hold_joint(arm, "a3", 0.3).reduced.family == "general6"  # axes 2 and 4 no longer parallel
    task = {"robot": str(arm.urdf_path), "start": {"joints_deg": [0, 30, 0, -70, 10, 20, 0]},
            "redundancy": {"joint": "a3", "value_deg": 0.0},
            "moves": [{"lin": {"to": _pose(arm, [10, 35, 0, -60, 10, -20, 0]), "speed": 0.2}}]}  # q6 passes 0
    traj, _ = _run_checked(tmp_path, task)
    crossing = next(s for s in traj["segments"] if s["kind"] == "crossing")
    assert crossing["singularity"] == "wrist" and crossing["method"] == "wrist-joint"
    assert _held_error_rad(traj, "a3", 0.0) <= HELD_TOL_RAD


def test_a_pose_start_is_solved_with_the_joint_held(tmp_path: Path) -> None:
    task = {"robot": "panda", "start": {"pose": {"xyz": [0.4, 0.1, 0.5], "rpy_deg": [180, 0, 0]}, "config": "F U N"},
            "redundancy": {"joint": "panda_joint3", "value_deg": 20.0},
            "moves": [{"lin": {"to": {"xyz": [0.5, 0.0, 0.4]}, "speed": 0.2}}]}
    traj, _ = _run_checked(tmp_path, task)
    assert _held_error_rad(traj, "panda_joint3", 20.0) <= HELD_TOL_RAD
    assert traj["segments"][0]["config_before"] == "F U N"


def test_minimum_norm_tracking_past_a_joint_limit_exits_3_naming_move_and_joint(tmp_path: Path) -> None:
    # turning the hand 195 deg about its axis drives joint 7 (at 45 deg) past its 166 deg limit
    task = {"robot": "panda", "start": {"joints_deg": [0, -45, 0, -135, 0, 90, 45]},
            "moves": [{"lin": {"to": {"xyz": [0.35, 0.0, 0.55], "rpy_deg": [180, 0, -150]}, "speed": 0.2}}]}
    task_file = tmp_path / "task.yaml"
    task_file.write_text(yaml.safe_dump(task))
    err = io.StringIO()
    assert main(["plan", str(task_file), "-o", str(tmp_path / "out")], out=io.StringIO(), err=err) == 3
    assert "move 0 (lin)" in err.getvalue() and "panda_joint7 to 166.2" in err.getvalue()
    assert "along the path" in err.getvalue() and not (tmp_path / "out").exists()


@pytest.mark.parametrize(("acceleration", "jerk"), [(list(range(11, 18)), list(range(101, 108))), (13.0, 150.0)])
def test_the_chain_s_task_drops_the_held_joint_s_limits(acceleration: Any, jerk: Any) -> None:
    task = parse_task(_panda_task([{"ptp": {"to": {"joints_deg": PANDA_THROUGH}}}],
                                  limits={"acceleration": acceleration, "jerk": jerk}))
    arm = task_arm(task)
    assert arm.held is not None and arm.held.index == 2
    per_joint = isinstance(acceleration, list)
    want_acc = [11.0, 12.0, 14.0, 15.0, 16.0, 17.0] if per_joint else [13.0]
    want_jerk = [101.0, 102.0, 104.0, 105.0, 106.0, 107.0] if per_joint else [150.0]
    assert list(arm.task.limits.acceleration_rad_s2) == want_acc
    assert arm.task.limits.jerk_rad_s3 is not None and list(arm.task.limits.jerk_rad_s3) == want_jerk
    assert arm.task.limits.joint_accelerations(arm.robot.n_joints).tolist() == want_acc * (6 // len(want_acc))
    assert arm.task.start_joints_deg == tuple(PANDA_START[:2] + PANDA_START[3:])
    assert arm.task.moves[0].to_joints_deg == tuple(PANDA_THROUGH[:2] + PANDA_THROUGH[3:])
