"""Continuous joints: planned as unlimited revolute joints, one angle each (singplan.kinematics.continuous).

References: Pinocchio's own model of the original URDF (continuous joints as (cos, sin) pairs) for
the kinematics, the independent checker (../shared/verify) for the plans, the replay page built
from the saved folder, and the exports read back for the turns.
"""

from __future__ import annotations

import io
import json
import math
import re
import shutil
import xml.etree.ElementTree as ET
from pathlib import Path
from typing import Any

import numpy as np
import pinocchio as pin
import pytest
import yaml

from singplan.cli import main
from singplan.errors import RobotModelError
from singplan.kinematics.continuous import UNLIMITED_LIMIT_RAD, as_revolute
from singplan.kinematics.ik.solve import solve_all
from singplan.kinematics.robot import Robot, load_robot, robots_dir
from singplan.results.trajectory import URDF_FILE, load, robot_files

from .conftest import erd_urdf
from .shared import run_checker

KINOVA_TIP = "j2s6s200_end_effector"


def _continuous_abb(tmp_path: Path) -> Path:
    """The bundled ABB IRB 2400 with its wrist roll joints 4 and 6 declared continuous."""
    tree = ET.parse(robots_dir() / "abb_irb2400.urdf")
    for joint in tree.getroot().iter("joint"):
        if joint.get("name") in ("joint_4", "joint_6"):
            joint.set("type", "continuous")
            limit = joint.find("limit")
            assert limit is not None
            del limit.attrib["lower"], limit.attrib["upper"]
    path = tmp_path / "irb2400_continuous.urdf"
    tree.write(path)
    return path


def _continuous_ur5(tmp_path: Path) -> Path:
    """example-robot-data's UR5 with continuous wrists, as older ur_description files declare them;
    its ``package://example-robot-data/...`` meshes found beside it (a link to that package), and its
    SRDF beside it under the URDF's stem (the pairs MoveIt never checks: its links overlap by design)."""
    original = Path(erd_urdf("ur5"))
    package = tmp_path / "example-robot-data"
    if not package.exists():
        package.symlink_to(original.resolve().parents[3], target_is_directory=True)
    tree = ET.parse(original)
    for joint in tree.getroot().iter("joint"):
        if joint.get("name") in ("wrist_1_joint", "wrist_2_joint", "wrist_3_joint"):
            joint.set("type", "continuous")
    path = tmp_path / "ur5_continuous_wrists.urdf"
    tree.write(path)
    shutil.copyfile(original.resolve().parents[1] / "srdf" / "ur5.srdf", path.with_suffix(".srdf"))
    return path


def _full_q(model: pin.Model, robot: Robot, q: np.ndarray) -> np.ndarray:
    """Pinocchio's configuration of the original model for one angle per chain joint."""
    out = pin.neutral(model)
    for value, name in zip(q, robot.joint_names, strict=True):
        joint = model.joints[model.getJointId(name)]
        if joint.nq == 2:
            out[joint.idx_q:joint.idx_q + 2] = math.cos(value), math.sin(value)
        else:
            out[joint.idx_q] = value
    return out


@pytest.mark.parametrize("which", ["kinova", "abb", "ur5"])
def test_one_angle_per_joint_gives_pinocchio_s_own_kinematics(which: str, tmp_path: Path) -> None:
    """FK of the unlimited robot at any angle (whole turns beyond +-180 deg included) equals the
    original model's, continuous joints as (cos, sin); those joints have no limits, the others theirs."""
    path = {"kinova": lambda: Path(erd_urdf("kinova")), "abb": lambda: _continuous_abb(tmp_path),
            "ur5": lambda: _continuous_ur5(tmp_path)}[which]()
    robot = load_robot(path, tip=KINOVA_TIP if which == "kinova" else None)
    original = pin.buildModelFromUrdf(str(path))
    continuous = [original.joints[original.getJointId(n)].nq == 2 for n in robot.joint_names]
    assert any(continuous) and robot.unlimited.tolist() == continuous
    assert np.all(np.isinf(robot.lower_rad[robot.unlimited])) and np.all(np.isfinite(robot.lower_rad[~robot.unlimited]))
    data = original.createData()
    frame = original.getFrameId(robot.tip)
    rng = np.random.default_rng(4)
    lo = np.where(robot.unlimited, -4 * np.pi, robot.lower_rad)
    hi = np.where(robot.unlimited, 4 * np.pi, robot.upper_rad)
    for q in rng.uniform(lo, hi, (20, robot.n_joints)):
        pin.framesForwardKinematics(original, data, _full_q(original, robot, q))
        assert data.oMf[frame].isApprox(robot.fk_tip(q), 1e-12)


def test_the_ik_takes_the_shortest_turn_of_an_unlimited_joint(tmp_path: Path) -> None:
    robot = load_robot(_continuous_abb(tmp_path))
    q = np.radians([10.0, 20.0, 10.0, 400.0, 40.0, -530.0])  # joints 4 and 6 past a turn
    T = robot.fk(q)
    seeded = solve_all(robot, T, seed=q)
    assert np.min(np.max(np.abs(seeded.q - q), axis=1)) < 1e-9  # q itself, at its own turn
    unseeded = solve_all(robot, T)
    assert np.all(np.abs(unseeded.q[:, [3, 5]]) <= np.pi + 1e-12)  # one turn each, no endless variants
    assert len(unseeded) == len(solve_all(robot, T, seed=np.zeros(6)))


def _pose(T: pin.SE3) -> dict[str, list[float]]:
    return {"xyz": [float(v) for v in T.translation],
            "rpy_deg": [float(v) for v in np.degrees(pin.rpy.matrixToRpy(T.rotation))]}


def _winding_task(robot: Robot, urdf: Path, q0_deg: list[float], ptp_deg: list[float], **extra: Any) -> dict[str, Any]:
    """Two LINs turning the tool 170 deg each about the last joint's axis (joint 6 past a turn), a PTP
    to joints far past a turn, and a PTP back to the start pose (the shortest turn)."""
    q0 = np.radians(q0_deg)
    T = robot.fk(q0)
    axis = T.rotation.T @ robot.jacobian(q0)[3:, -1]  # the last joint's axis in the TCP frame
    Ta = T * pin.SE3(pin.exp3(axis * math.radians(170)), np.array([0.03, 0.0, 0.0]))
    Tb = Ta * pin.SE3(pin.exp3(axis * math.radians(170)), np.array([0.0, 0.03, 0.0]))
    return {"robot": str(urdf), "start": {"joints_deg": q0_deg},
            "moves": [{"lin": {"to": _pose(Ta), "speed": 0.1}}, {"lin": {"to": _pose(Tb), "speed": 0.1}},
                      {"ptp": {"to": {"joints_deg": ptp_deg}}}, {"ptp": {"to": _pose(T)}}],
            "limits": {"acceleration": 5.0}, **extra}


def _plan_and_check(task: dict[str, Any], tmp_path: Path) -> Path:
    path = tmp_path / "task.yaml"
    path.write_text(yaml.safe_dump(task))
    out = tmp_path / "out"
    err = io.StringIO()
    assert main(["plan", str(path), "-o", str(out), "--no-report", "--no-replay"], out=io.StringIO(), err=err) == 0, \
        err.getvalue()
    done = run_checker(path, out)
    assert done.returncode == 0, done.stdout + done.stderr
    return out


def _turns_kept(q: np.ndarray, joint: int, beyond_deg: float) -> None:
    """Joint values (N, n) [rad] run past ``beyond_deg`` without a jump (a wrap would jump by 360 deg;
    the fastest joint here moves at most 1.8 deg a 4 ms sample)."""
    assert np.max(np.abs(np.degrees(q[:, joint]))) > beyond_deg
    assert np.max(np.abs(np.diff(np.degrees(q), axis=0))) < 2.0


@pytest.mark.parametrize("which", ["kinova", "abb", "ur5"])
def test_a_program_winding_continuous_joints_plans_passes_the_checker_and_replays(which: str, tmp_path: Path) -> None:
    """example-robot-data's Kinova j2s6s200, the bundled ABB and the UR5 with continuous wrists: joint 6
    winds past 360 deg through LINs and PTPs; the plan passes the independent checker (which reads
    trajectory.urdf: one coordinate per joint), and the saved folder replays."""
    if which == "kinova":
        urdf = Path(erd_urdf("kinova"))
        q0, ptp = [2.13, 234.06, 94.6, 80.76, 134.84, -13.8], [20, 180, 90, 20, 120, 420]  # its joints are slow
        robot = load_robot(urdf, tip=KINOVA_TIP)
        task = _winding_task(robot, urdf, q0, ptp, tip=KINOVA_TIP)
    else:
        urdf = _continuous_abb(tmp_path) if which == "abb" else _continuous_ur5(tmp_path)
        q0, ptp = ([10.0, 20.0, 10.0, 30.0, 50.0, 20.0], [40, 10, 20, -400, 60, 600]) if which == "abb" else \
                  ([10.0, -100.0, 80.0, -60.0, 60.0, 20.0], [40, -90, 70, -400, 60, 600])
        robot = load_robot(urdf)
        task = _winding_task(robot, urdf, q0, ptp)
    out = _plan_and_check(task, tmp_path)
    doc = json.loads((out / "trajectory.json").read_text())
    assert doc["urdf"] == str(out / URDF_FILE) and doc["urdf_source"] == str(urdf.resolve())
    copy = pin.buildModelFromUrdf(doc["urdf"])
    assert all(copy.joints[copy.getJointId(n)].nq == 1 for n in doc["joint_names"])
    traj = load(out)
    assert traj.urdf == str(urdf.resolve())  # singplan reads the URDF it planned
    _turns_kept(traj.q, 5, 400.0)
    err = io.StringIO()
    assert main(["replay", str(out), "--html", str(tmp_path / "replay.html")], out=io.StringIO(), err=err) == 0, \
        err.getvalue()
    page = (tmp_path / "replay.html").read_text()
    assert "warning" not in err.getvalue() and len(page) > 1_000_000  # the meshes are on the page


def test_every_export_keeps_the_turns(tmp_path: Path) -> None:
    urdf = _continuous_abb(tmp_path)
    out = _plan_and_check(_winding_task(load_robot(urdf), urdf, [10.0, 20.0, 10.0, 30.0, 50.0, 20.0],
                                        [40, 10, 20, -400, 60, 600]), tmp_path)
    csv = np.loadtxt(out / "trajectory.csv", delimiter=",", skiprows=1)[:, 1:]
    _turns_kept(csv, 5, 590.0)
    _turns_kept(np.asarray(json.loads((out / "trajectory.json").read_text())["q"]), 3, 390.0)
    for fmt in ("ros2", "ros2-json", "urscript", "csv-deg"):
        target = tmp_path / f"export.{fmt}"
        assert main(["export", str(out), "--format", fmt, "-o", str(target)], out=io.StringIO()) == 0
        text = target.read_text()
        if fmt == "ros2":
            q = np.array([p["positions"] for p in yaml.safe_load(text)["points"]])
        elif fmt == "ros2-json":
            q = np.array([p["positions"] for p in json.loads(text)["points"]])
        elif fmt == "urscript":
            q = np.array([[float(v) for v in row.split(",")] for row in re.findall(r"servoj\(\[([^\]]*)\]", text)])
        else:
            q = np.radians(np.loadtxt(io.StringIO(text), delimiter=",", skiprows=1)[:, 1:7])
        _turns_kept(q, 5, 590.0)
        np.testing.assert_allclose(q[-1], csv[-1], atol=1e-6)


def test_the_copy_beside_the_trajectory_loads_as_the_same_robot(tmp_path: Path) -> None:
    """trajectory.urdf (continuous joints as revolute with +-1e9 rad limits) reads back as the same
    unlimited joints; its meshes are named by absolute path, so it works from the output folder."""
    urdf = _continuous_ur5(tmp_path)
    robot = load_robot(urdf)
    text = as_revolute(urdf.read_text(), str(urdf))
    assert f'upper="{UNLIMITED_LIMIT_RAD!r}"' in text and 'type="continuous"' not in text
    traj_urdf = tmp_path / "copy" / "robot.urdf"
    traj_urdf.parent.mkdir()
    from singplan.kinematics.continuous import portable_urdf

    traj_urdf.write_text(portable_urdf(urdf.read_text(), urdf))
    again = load_robot(traj_urdf)
    assert again.unlimited.tolist() == robot.unlimited.tolist() and again.joint_names == robot.joint_names
    q = np.radians([10, -100, 80, 700, 60, -900])
    assert again.fk(q).isApprox(robot.fk(q), 1e-12)
    meshes = [m.get("filename", "") for m in ET.parse(traj_urdf).getroot().iter("mesh")]
    assert meshes and all(Path(m).is_absolute() and Path(m).is_file() for m in meshes)


def test_no_copy_for_a_urdf_without_continuous_joints(planned_kuka: Path) -> None:
    traj = load(planned_kuka)
    assert robot_files(traj) == {} and not (planned_kuka / URDF_FILE).exists()
    assert "urdf_source" not in json.loads((planned_kuka / "trajectory.json").read_text())


def test_info_shows_unlimited_joints() -> None:
    out = io.StringIO()
    assert main(["info", erd_urdf("kinova"), "--json"], out=out) == 0
    joints = json.loads(out.getvalue())["joints"]
    assert [j["lower_deg"] is None for j in joints] == [True, False, False, True, False, True]
    out = io.StringIO()
    assert main(["info", erd_urdf("kinova")], out=out) == 0
    assert out.getvalue().count("unlimited (continuous)") == 3


def test_a_start_far_past_a_turn_is_valid_and_a_joint_without_a_speed_limit_is_named(tmp_path: Path) -> None:
    urdf = _continuous_abb(tmp_path)
    task = {"robot": str(urdf), "start": {"joints_deg": [0, 10, 10, 3000, 40, -3000]},
            "moves": [{"ptp": {"to": {"joints_deg": [0, 10, 10, 3010, 40, -2990]}}}]}
    (tmp_path / "far").mkdir()
    assert _plan_and_check(task, tmp_path / "far").is_dir()
    text = urdf.read_text()
    limitless = re.sub(r'(<joint name="joint_6" type="continuous">.*?)<limit[^>]*/>', r"\1", text, flags=re.S)
    assert limitless != text
    bare = tmp_path / "bare.urdf"
    bare.write_text(limitless)
    with pytest.raises(RobotModelError, match="joint 'joint_6' has no velocity limit"):
        load_robot(bare)
