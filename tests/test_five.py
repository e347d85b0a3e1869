"""Five-axis arms (SEEDS 002, reduced order): loading, reduced IK, planning, exit codes.

The plans (numeric IK at every path sample, most judged by the independent checker) and the
brute-force IK references take seconds each: they are marked slow (CI: ``python -m pytest -q -m slow``).
"""

from __future__ import annotations

import io
import json
import shutil
from pathlib import Path

import numpy as np
import pinocchio as pin
import pytest

from singplan.cli import main
from singplan.errors import RobotModelError
from singplan.kinematics.configuration import classify
from singplan.kinematics.ik.numeric import solve_lm
from singplan.kinematics.ik.solve import solve_all
from singplan.kinematics.reduced import free_joints, z_angles
from singplan.kinematics.robot import load_robot, robots_dir
from singplan.planning.crossing.registry import refusals

from .conftest import erd_urdf
from .shared import run_checker

DATA = Path(__file__).parent / "data"
SCORBOT = DATA / "five_scorbot_er4u.urdf"
Z_TOL_RAD = np.radians(0.01)


def test_scorbot_loads_as_five_with_the_roll_free() -> None:
    robot = load_robot(str(SCORBOT))
    assert robot.family == "five" and robot.n_joints == 5 and robot.tip == "tcp"
    assert free_joints(robot) == (4,)  # the roll turns about the tool axis through the TCP
    assert robot.recognition.capabilities == frozenset()  # no closed form, no spherical wrist, tool axis only
    assert refusals(robot.recognition)["wrist-joint"] and "exact" not in refusals(robot.recognition)


@pytest.mark.parametrize("name", ["so100", "so101"])
def test_so_arms_leave_the_gripper_joint_out_of_the_chain(name: str) -> None:
    pytest.importorskip("example_robot_data")
    robot = load_robot(erd_urdf(name))
    assert robot.family == "five" and "gripper" not in robot.joint_names
    tip = {"so100": "wrist_roll", "so101": "gripper_frame_link"}[name]  # SO-100: `gripper` is two frames' name
    assert robot.tip == tip  # the default rule for a URDF by path
    assert load_robot(name).tip == tip  # by name


def test_ik_keeps_position_and_tool_axis_and_holds_the_roll_at_the_seed() -> None:
    robot = load_robot(str(SCORBOT))
    q = np.radians([20.0, 60.0, -40.0, -20.0, 10.0])
    T = robot.fk(q)
    turned = pin.SE3(T.rotation @ pin.rpy.rpyToMatrix(0.0, 0.0, 0.7), T.translation)  # another roll: ignored
    sols = solve_all(robot, turned, seed=q)
    assert sorted(sols.labels) == ["F D N", "F U N"]
    for qk in sols.q:
        got = robot.fk(qk)
        assert np.linalg.norm(got.translation - T.translation) < 1e-9
        assert z_angles(got.rotation[None], T.rotation[None])[0] < 1e-9
        assert qk[4] == pytest.approx(q[4], abs=1e-12)
    assert classify(robot, q).label == "F U N"


def _plan(task: Path, out: Path) -> dict:
    assert main(["plan", str(task), "-o", str(out), "--no-report", "--no-replay"]) == 0
    return json.loads((out / "trajectory.json").read_text())


@pytest.mark.parametrize("task", ["five_scorbot_moves.yaml", "five_scorbot_stretched.yaml"])
@pytest.mark.slow
def test_scorbot_tasks_plan_and_pass_the_checker(task: str, tmp_path: Path) -> None:
    shutil.copy(SCORBOT, tmp_path / SCORBOT.name)
    path = tmp_path / task
    shutil.copy(DATA / task, path)
    traj = _plan(path, tmp_path / "out")
    assert traj["metrics"]["max_orientation_error_deg"] < 0.01
    _checked(path, tmp_path / "out")


def _checked(path: Path, out: Path) -> None:
    done = run_checker(path, out)
    assert done.returncode == 0, done.stdout[-2000:]


def _so_task(task: str, tmp_path: Path) -> Path:
    pytest.importorskip("example_robot_data")
    path = tmp_path / "task.yaml"
    shutil.copy(DATA / task, path)
    return path


@pytest.mark.slow
def test_so100_passes_near_the_shoulder_singularity(tmp_path: Path) -> None:
    path = _so_task("five_so100_shoulder.yaml", tmp_path)
    traj = _plan(path, tmp_path / "out")
    _checked(path, tmp_path / "out")
    (zone,) = [s for s in traj["segments"] if s["kind"] == "crossing"]
    assert zone["singularity"] == "shoulder" and zone["min_distance"] == pytest.approx(0.015, abs=1e-4)
    assert traj["q"][-1][4] == traj["q"][0][4]  # the free roll does not move while axis 1 swings


@pytest.mark.parametrize("name", ["so100", "so101"])
@pytest.mark.slow
def test_so_arm_tasks_plan_ignore_the_roll_and_pass_the_checker(name: str, tmp_path: Path) -> None:
    path = _so_task(f"five_{name}_moves.yaml", tmp_path)
    traj = _plan(path, tmp_path / "out")
    _checked(path, tmp_path / "out")
    robot = load_robot(name)
    tool = traj["tool"]
    robot = robot.with_tool(pin.SE3(pin.rpy.rpyToMatrix(*np.radians(tool["rpy_deg"])), np.array(tool["xyz"])))
    got = robot.fk(np.array(traj["q"][-1]))
    target = traj["task"]["moves"][-1]["lin"]["to"]
    wanted = pin.rpy.rpyToMatrix(*np.radians(target["rpy_deg"]))
    assert np.linalg.norm(got.translation - np.array(target["xyz"])) < 1e-8
    assert z_angles(got.rotation[None], wanted[None])[0] < Z_TOL_RAD
    # the 45 deg turn about the tool axis is not made (the start's own roll differs by a few degrees)
    assert np.degrees(np.linalg.norm(pin.log3(got.rotation.T @ wanted))) > 30.0
    if free_joints(robot):  # a free roll stays where it started
        assert traj["q"][-1][4] == pytest.approx(traj["q"][0][4], abs=1e-12)


@pytest.mark.slow
def test_stretched_task_reports_the_elbow_zone(tmp_path: Path) -> None:
    shutil.copy(SCORBOT, tmp_path / SCORBOT.name)
    path = tmp_path / "task.yaml"
    shutil.copy(DATA / "five_scorbot_stretched.yaml", path)
    traj = _plan(path, tmp_path / "out")
    kinds = {s["singularity"] for s in traj["segments"] if s["kind"] == "crossing"}
    assert kinds == {"elbow"}


def _task(tmp_path: Path, body: str) -> Path:
    shutil.copy(SCORBOT, tmp_path / SCORBOT.name)
    path = tmp_path / "task.yaml"
    path.write_text(f"robot: {SCORBOT.name}\n" + body)
    return path


@pytest.mark.slow  # the numeric all-branch IK searches every sample up to the edge of reach (~8 s)
def test_unreachable_target_exits_3(tmp_path: Path) -> None:
    path = _task(tmp_path, "start: {pose: {xyz: [0.40, 0.0, 0.15], rpy_deg: [180, 0, 0]}}\n"
                           "moves:\n  - lin: {to: {xyz: [0.90, 0.0, 0.15]}, speed: 0.1}\n")
    assert main(["plan", str(path), "-o", str(tmp_path / "out")]) == 3
    assert not (tmp_path / "out").exists()


def test_malformed_task_exits_2(tmp_path: Path) -> None:
    path = _task(tmp_path, "start: {joints_deg: [0, 10, 20, 0, 0, 0]}\n"  # six values for five joints
                           "moves:\n  - lin: {to: {xyz: [0.40, 0.0, 0.15]}, speed: 0.1}\n")
    assert main(["plan", str(path), "-o", str(tmp_path / "out")]) == 2


def test_a_four_joint_chain_is_refused_naming_the_counts(tmp_path: Path) -> None:
    text = (robots_dir() / "abb_irb2400.urdf").read_text()
    for joint in ("joint_5", "joint_6"):
        text = text.replace(f'<joint name="{joint}" type="revolute">', f'<joint name="{joint}" type="fixed">', 1)
    path = tmp_path / "arm4.urdf"
    path.write_text(text)
    with pytest.raises(RobotModelError, match="4 revolute joints from base_link to tool0; singplan plans arms with "
                                              "5, 6 or 7"):
        load_robot(str(path))


def test_a_five_joint_cut_of_a_six_axis_urdf_loads_as_five(tmp_path: Path) -> None:
    text = (robots_dir() / "abb_irb2400.urdf").read_text()
    path = tmp_path / "arm5.urdf"
    path.write_text(text.replace('<joint name="joint_6" type="revolute">', '<joint name="joint_6" type="fixed">', 1))
    assert load_robot(str(path)).family == "five"


def test_cli_ik_lists_both_elbows_and_info_names_the_family() -> None:
    out, err = io.StringIO(), io.StringIO()
    # the pose of joints (20, 60, -40, -20, 10) deg to six digits: its axis is a few 1e-8 rad out of reach
    argv = ["ik", str(SCORBOT), "--xyz", "0.450368", "0.163921", "0.615978", "--rpy-deg", "90", "80", "110"]
    assert main(argv, out, err) == 0
    text = out.getvalue()
    assert "2 solution(s)" in text and "F U N" in text and "F D N" in text
    out = io.StringIO()
    assert main(["info", str(SCORBOT)], out, err) == 0
    assert "family: five" in out.getvalue() and "wrist-joint" in out.getvalue()


def test_ptp_to_a_pose_in_the_asked_elbow_configuration(tmp_path: Path) -> None:
    robot = load_robot(str(SCORBOT))
    T = robot.fk(np.radians([20.0, 60.0, -40.0, -20.0, 10.0]))
    xyz = [float(v) for v in T.translation]
    rpy = [float(v) for v in np.degrees(pin.rpy.matrixToRpy(T.rotation))]
    # 3 cm in along the arm's own direction: the horizontal tool axis stays in the arm plane
    azimuth = np.radians(20.0)
    radial_in = [float(v) for v in T.translation - 0.03 * np.array([np.cos(azimuth), np.sin(azimuth), 0.0])]
    path = _task(tmp_path, "start: {joints_deg: [0, 60, -40, -20, 0]}\n"
                           f"moves:\n  - ptp: {{to: {{xyz: {xyz}, rpy_deg: {rpy}}}, config: F D N}}\n"
                           f"  - lin: {{to: {{xyz: {radial_in}}}, speed: 0.1, config: keep}}\n")
    traj = _plan(path, tmp_path / "out")
    _checked(path, tmp_path / "out")
    ends = {seg["move"]: seg for seg in traj["segments"]}  # each move's last segment
    assert [ends[i]["config_after"] for i in (0, 1)] == ["F D N", "F D N"]
    q_ptp_end = np.degrees(traj["q"][round(ends[0]["t1"] / traj["period"])])
    assert np.allclose(q_ptp_end, [20.0, 20.0, 40.0, -60.0, 0.0], atol=1e-6)  # elbow down; the roll stays at 0


def _same(a: np.ndarray, b: np.ndarray, skip: tuple[int, ...]) -> bool:
    keep = [j for j in range(len(a)) if j not in skip]
    return bool(np.all(np.abs(np.angle(np.exp(1j * (a[keep] - b[keep])))) < 1e-6))


@pytest.mark.parametrize("name", ["scorbot", "so101"])
@pytest.mark.slow  # a brute-force reference search
def test_ik_finds_every_branch_a_brute_force_search_finds(name: str) -> None:
    robot = load_robot(str(SCORBOT)) if name == "scorbot" else load_robot(name)
    free = free_joints(robot)
    rng = np.random.default_rng(5)
    lower, upper = np.maximum(robot.lower_rad, -np.pi), np.minimum(robot.upper_rad, np.pi)
    for q in rng.uniform(lower, upper, size=(3, 5)):
        T = robot.fk(q)
        found = solve_all(robot, T).q
        assert any(_same(q, row, free) for row in found)
        for seed in rng.uniform(lower, upper, size=(100, 5)):  # brute force: more seeds than the search's quiet stop
            brute = solve_lm(robot, T, seed)
            if brute is not None and robot.within_limits(brute):
                assert any(_same(brute, row, free) for row in found), np.degrees(brute)
