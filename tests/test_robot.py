"""Robot loading, the bundled URDFs against the registry, FK and the Jacobian."""

from __future__ import annotations

import io
import math
import re
from pathlib import Path

import numpy as np
import pinocchio as pin
import pytest
import yaml

from singplan.cli import main
from singplan.errors import RobotModelError, UnknownNameError
from singplan.kinematics.robot import MAX_URDF_BYTES, SUPPORTED_JOINT_COUNTS, bundled_robots, load_robot, robots_dir

from .conftest import OPW_NAMES, erd_urdf, random_q


def test_registry_lists_every_bundled_arm_and_the_two_example_robots() -> None:
    names = set(bundled_robots())
    assert set(OPW_NAMES) <= names
    assert len(OPW_NAMES) == 10
    assert {"ur5", "panda"} <= names


@pytest.mark.parametrize("name", OPW_NAMES)
def test_bundled_urdf_has_the_registry_chain_and_limits(name: str) -> None:
    spec = yaml.safe_load((robots_dir() / "robots.yaml").read_text())["robots"][name]
    robot = load_robot(name)
    assert robot.joint_names == tuple(f"joint_{i}" for i in range(1, 7))
    assert robot.tip == "tool0"
    for i, joint in enumerate(spec["chain"], start=1):
        np.testing.assert_allclose(robot.model.jointPlacements[i].translation, joint["xyz"], atol=0)
        np.testing.assert_allclose(robot.model.jointPlacements[i].rotation, np.eye(3), atol=0)
    np.testing.assert_allclose(np.degrees(robot.lower_rad), [lo for lo, _ in spec["position_deg"]], atol=1e-9)
    np.testing.assert_allclose(np.degrees(robot.upper_rad), [hi for _, hi in spec["position_deg"]], atol=1e-9)
    np.testing.assert_allclose(np.degrees(robot.velocity_rad_s), spec["velocity_deg_s"], atol=1e-9)
    assert np.all(robot.model.inertias[1].mass > 0)


def test_generated_urdfs_are_up_to_date() -> None:
    import importlib.util

    script = robots_dir().parent / "generate_urdfs.py"
    if not script.exists():
        pytest.skip("generator script not shipped in an installed wheel")
    spec = importlib.util.spec_from_file_location("generate_urdfs", script)
    assert spec is not None and spec.loader is not None
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    assert module.main(["--check"]) == 0


def test_example_robot_data_arms_load_as_chains() -> None:
    ur5 = load_robot("ur5")
    assert ur5.n_joints == 6 and ur5.tip == "tool0" and ur5.urdf_path.is_file()
    panda = load_robot("panda")
    assert panda.n_joints == 7  # fingers locked away: only the arm chain remains
    assert panda.tip == "panda_hand"


def test_erd_urdf_is_the_path_example_robot_data_loads() -> None:
    import example_robot_data

    for name in ("xarm7", "bravo7_no_ee"):  # two whose load() is quick
        assert erd_urdf(name) == example_robot_data.load(name).urdf


def test_unknown_robot_lists_valid_names() -> None:
    with pytest.raises(UnknownNameError) as info:
        load_robot("abb_irb9999")
    assert "abb_irb2400" in str(info.value) and "ur5" in str(info.value)
    assert info.value.exit_code == 2


def test_missing_and_unreadable_urdf_name_the_file(tmp_path) -> None:
    with pytest.raises(RobotModelError, match="no such URDF"):
        load_robot(tmp_path / "missing.urdf")
    broken = tmp_path / "broken.urdf"
    broken.write_text("<robot name='x'><link name='a'/><joint name='j' type='revolute'>")
    with pytest.raises(RobotModelError, match=r"broken\.urdf"):
        load_robot(broken)


def test_unknown_tip_frame_names_file_and_frame() -> None:
    with pytest.raises(UnknownNameError) as info:
        load_robot("abb_irb2400", tip="flange_x")
    assert "flange_x" in str(info.value) and "abb_irb2400.urdf" in str(info.value) and "tool0" in str(info.value)


def test_urdf_by_path_takes_the_default_tip_rule(robots) -> None:
    robot = load_robot(robots["abb_irb2400"].urdf_path)
    assert robot.name == "abb_irb2400" and robot.tip == "tool0"


@pytest.mark.parametrize("name", ["abb_irb2400", "staubli_tx2_60", "ur5", "panda"])
def test_batched_tcp_frames_and_jacobians_match_pinocchio(name: str, rng) -> None:
    """The chunked numpy chain (one walk for both) against a Pinocchio call per sample, with a tool."""
    tool = pin.SE3(pin.rpy.rpyToMatrix(0.3, -0.2, 0.5), np.array([0.02, -0.03, 0.15]))
    robot = load_robot(name).with_tool(tool)
    q = random_q(robot, rng, 50)
    positions, jacobians = robot.tcp_positions(q), robot.tcp_jacobians(q)
    frames, full = robot.tcp_frames(q), robot.tcp_kinematics(q)[2]
    np.testing.assert_array_equal(frames[0], positions)
    np.testing.assert_array_equal(full[:, :3], jacobians)
    for k in range(len(q)):
        T = robot.fk(q[k])
        np.testing.assert_allclose(positions[k], T.translation, atol=1e-12)
        np.testing.assert_allclose(frames[1][k], T.rotation, atol=1e-12)
        np.testing.assert_allclose(full[k], robot.jacobian(q[k]), atol=1e-12)


@pytest.mark.parametrize("name", ["abb_irb2400", "kuka_kr6_r900_2", "fanuc_lrmate200id", "staubli_tx2_60", "ur5"])
def test_jacobian_matches_finite_differences(name: str, robots, rng) -> None:
    """Columns of the TCP Jacobian against central differences of FK (position and rotation)."""
    tool = pin.SE3(pin.rpy.rpyToMatrix(0.3, -0.2, 0.5), np.array([0.02, -0.03, 0.15]))
    robot = robots[name].with_tool(tool)
    h = 1e-6
    for q in random_q(robot, rng, 20):
        J = robot.jacobian(q)
        T0 = robot.fk(q)
        for j in range(robot.n_joints):
            dq = np.zeros(robot.n_joints)
            dq[j] = h
            Tp, Tm = robot.fk(q + dq), robot.fk(q - dq)
            lin = (Tp.translation - Tm.translation) / (2 * h)
            ang = (pin.log3(T0.rotation.T @ Tp.rotation) - pin.log3(T0.rotation.T @ Tm.rotation)) / (2 * h)
            np.testing.assert_allclose(J[:3, j], lin, atol=1e-7)
            np.testing.assert_allclose(J[3:, j], T0.rotation @ ang, atol=1e-7)


def test_wrist_center_is_on_axes_4_5_6_for_opw_arms(robots, rng) -> None:
    for name in OPW_NAMES:
        robot = robots[name]
        q = random_q(robot, rng, 1)[0]
        wc = robot.wrist_center(q)
        flange = robot.fk_tip(q)
        # the flange sits c4 along its z axis from the wrist centre
        c4 = robot.opw.c4 if robot.opw else math.nan
        np.testing.assert_allclose(flange.translation - c4 * flange.rotation[:, 2], wc, atol=1e-12)


URDF_TEXT = (robots_dir() / "abb_irb2400.urdf").read_text()
JOINT_5_LIMIT = 'velocity="6.283185307179586" lower="-2.0943951023931953" upper="2.0943951023931953"'


def _urdf(tmp_path, old: str, new: str):
    assert old in URDF_TEXT
    path = tmp_path / "arm.urdf"
    path.write_text(URDF_TEXT.replace(old, new, 1))
    return path


@pytest.mark.parametrize(("old", "new", "words"), [
    (JOINT_5_LIMIT, JOINT_5_LIMIT.replace("6.283185307179586", "0"), "joint 'joint_5' has no velocity limit"),
    (JOINT_5_LIMIT, JOINT_5_LIMIT.replace("6.283185307179586", "1e-300"), "joint 'joint_5' has velocity limit 1e-300"),
    (JOINT_5_LIMIT, JOINT_5_LIMIT.replace("6.283185307179586", "nan"), "joint [joint_5]: velocity value (nan)"),
    (JOINT_5_LIMIT, 'velocity="6" lower="1" upper="1"', "joint 'joint_5' has position limits [1, 1] rad"),
    (JOINT_5_LIMIT, 'velocity="6" lower="-30" upper="30"', "4 turns"),
    ('<joint name="joint_2" type="revolute">', '<joint name="joint_2" type="prismatic">', "'joint_2' is prismatic"),
    ('<joint name="joint_4" type="revolute">', '<joint name="joint_4" type="planar">', "'joint_4' is a Planar joint"),
    ('<origin xyz="0.497 0.0 0.0"', '<origin xyz="nan 0.0 0.0"', "[nan]"),
    ('<origin xyz="0.497 0.0 0.0"', '<origin xyz="1e308 1e308 0.0"', "forward kinematics"),
    ('<origin xyz="0.497 0.0 0.0"', '<origin xyz="1497 0.0 0.0"', "units in mm"),
    ("<robot", "robot", "cannot be read as URDF"),
])
def test_urdf_without_what_planning_needs_names_file_and_joint(tmp_path, capfd, old: str, new: str,
                                                                words: str) -> None:
    path = _urdf(tmp_path, old, new)
    with pytest.raises(RobotModelError) as info:
        load_robot(path)
    assert words in str(info.value) and str(path) in str(info.value)
    assert info.value.exit_code == 2
    captured = capfd.readouterr()
    assert captured.err == "" and captured.out == ""  # urdfdom's own lines go into the message, not the terminal


def _six_axis_urdf(tmp_path: Path, kinds: dict[str, str]) -> Path:
    """A small 6R arm ending in ``tool0`` (a user's file, as in the bug report); ``kinds`` retypes joints."""
    axes = ["0 0 1", "0 1 0", "0 1 0", "1 0 0", "0 1 0", "1 0 0"]
    origins = ["0 0 0.4", "0.15 0 0", "0 0 0.5", "0.2 0 0.08", "0.25 0 0", "0.08 0 0"]
    links = ["base_link", *(f"link_{i}" for i in range(1, 7)), "tool0"]
    joints = [f'<joint name="j{i}" type="{kinds.get(f"j{i}", "revolute")}"><parent link="{links[i - 1]}"/>'
              f'<child link="{links[i]}"/><origin xyz="{origins[i - 1]}"/><axis xyz="{axes[i - 1]}"/>'
              '<limit lower="-2" upper="2" velocity="3" effort="50"/></joint>' for i in range(1, 7)]
    joints.append('<joint name="j6-tool0" type="fixed"><parent link="link_6"/><child link="tool0"/></joint>')
    path = tmp_path / "myarm.urdf"
    path.write_text('<robot name="myarm">' + "".join(f'<link name="{k}"/>' for k in links)
                    + "".join(joints) + "</robot>")
    return path


def test_the_six_axis_test_urdf_loads_with_its_default_tip(tmp_path: Path) -> None:
    robot = load_robot(_six_axis_urdf(tmp_path, {}))
    assert robot.tip == "tool0" and robot.joint_names == tuple(f"j{i}" for i in range(1, 7))


@pytest.mark.parametrize(("joint", "kind", "words"), [
    ("j6", "prismatic", "joint 'j6' is prismatic"),
    ("j3", "prismatic", "joint 'j3' is prismatic"),
])
def test_an_unsupported_joint_on_the_default_chain_is_refused_not_skipped(tmp_path: Path, joint: str, kind: str,
                                                                           words: str) -> None:
    """Regression: the default tip once ended the chain at the deepest *revolute* joint, so another kind
    of j6 was left off and the arm loaded as a 5-axis one (tip link_5); the joint must be named, exit 2.
    (A continuous j6 is planned: tests/test_continuous.py.)"""
    urdf = _six_axis_urdf(tmp_path, {joint: kind})
    with pytest.raises(RobotModelError, match=re.escape(words)):
        load_robot(urdf)
    err = io.StringIO()
    assert main(["info", str(urdf)], out=io.StringIO(), err=err) == 2
    assert words in err.getvalue()
    task = tmp_path / "task.yaml"  # no tip: the default one
    task.write_text("robot: myarm.urdf\nstart: {joints_deg: [0, 10, 20, 0, 30, 0]}\n"
                    "moves: [ptp: {to: {joints_deg: [0, 0, 0, 0, 45, 0]}}]\n")
    err = io.StringIO()
    assert main(["plan", str(task), "-o", str(tmp_path / "out")], out=io.StringIO(), err=err) == 2
    assert words in err.getvalue() and "expected 5 joint values" not in err.getvalue()
    assert not (tmp_path / "out").exists()


def test_supported_joint_counts_is_the_one_place(tmp_path, monkeypatch) -> None:
    import singplan.kinematics.robot as robot_module

    five = _urdf(tmp_path, '<joint name="joint_6" type="revolute">', '<joint name="joint_6" type="fixed">')
    assert load_robot(five).n_joints == 5
    monkeypatch.setattr(robot_module, "SUPPORTED_JOINT_COUNTS", (6, 7))
    with pytest.raises(RobotModelError, match="5 revolute joints from base_link to tool0; singplan plans arms with "
                                              "6 or 7"):
        load_robot(five)


def test_urdf_files_that_are_not_usable(tmp_path) -> None:
    (tmp_path / "folder.urdf").mkdir()
    with pytest.raises(RobotModelError, match="is a directory"):
        load_robot(tmp_path / "folder.urdf")
    big = tmp_path / "big.urdf"
    big.write_text(URDF_TEXT.replace("</robot>", "<!--" + "x" * MAX_URDF_BYTES + "--></robot>"))
    cap = rf"big\.urdf: \d+ bytes is over the {MAX_URDF_BYTES}-byte cap for a URDF"
    with pytest.raises(RobotModelError, match=cap):
        load_robot(big)
    with pytest.raises(RobotModelError, match="No link"):
        load_robot(_urdf(tmp_path, URDF_TEXT, '<robot name="x"></robot>'))
    with pytest.raises(UnknownNameError, match=r"unknown robot '.*arm\.xml'; valid: abb_irb2400, ") as info:
        load_robot(tmp_path / "arm.xml")
    assert info.value.what == "robot"


def test_every_bundled_arm_passes_the_checks() -> None:
    for name in bundled_robots():
        robot = load_robot(name)
        assert robot.n_joints in SUPPORTED_JOINT_COUNTS
        assert np.all(robot.velocity_rad_s > 0) and np.all(robot.lower_rad < robot.upper_rad)


def test_a_tip_before_a_tools_joint_plans_the_arm_without_it(tmp_path: Path) -> None:
    """The refusal's advice holds: a prismatic last joint (a slide, say) is left out by a tip
    before it, and the arm before it loads with the joints up to that tip."""
    urdf = _six_axis_urdf(tmp_path, {"j6": "prismatic"})
    with pytest.raises(RobotModelError, match="give the task a `tip` before it; the tip now is tool0"):
        load_robot(urdf)
    robot = load_robot(urdf, tip="link_5")
    assert robot.tip == "link_5" and robot.joint_names == tuple(f"j{i}" for i in range(1, 6))
