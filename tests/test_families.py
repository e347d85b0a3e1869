"""Kinematic families recognised from the URDF chain (singplan.kinematics.families), whatever its conventions."""

from __future__ import annotations

import io
import json
import math
import xml.etree.ElementTree as ET
from pathlib import Path

import numpy as np
import pinocchio as pin
import pytest
import yaml

from singplan.cli import main
from singplan.kinematics.configuration import _frames, _signed_distances, classify, distances_batch
from singplan.kinematics.families import VERIFY_TOL_M, VERIFY_TOL_RAD, recognise
from singplan.kinematics.ik.solve import solve_all
from singplan.kinematics.robot import bundled_robots, default_tip, load_robot
from singplan.outputs.summary import summary
from singplan.planning.crossing import registry
from singplan.results.plan import plan
from singplan.task.load import parse_task

from .conftest import OPW_NAMES, erd_urdf
from .shared import run_checker

ROOT = Path(__file__).resolve().parents[1]
_AXIS_RPY = {0: "{d} 0 0", 1: "0 {d} 0", 2: "0 0 {d}"}  # a turn about the joint's own axis, as URDF rpy


def _wrapped(x: float) -> float:
    return math.atan2(math.sin(x), math.cos(x))


def _assert_fk_reproduced(urdf: Path, rng: np.random.Generator, tip: str | None = None) -> None:
    """The recognised closed form solves poses of random joints of the URDF, exactly (own check, not the module's)."""
    robot = load_robot(urdf, tip=tip)
    lo, hi = np.maximum(robot.lower_rad, -math.pi), np.minimum(robot.upper_rad, math.pi)
    for q in rng.uniform(lo, hi, size=(20, 6)):
        target = robot.fk(q)
        sols = solve_all(robot, target, seed=q)
        assert any(np.allclose(s, q, atol=1e-7) for s in sols.q)
        for s in sols.q:
            error = target.actInv(robot.fk(s))
            assert np.linalg.norm(error.translation) < 1e-9 and np.linalg.norm(pin.log3(error.rotation)) < 1e-9


@pytest.mark.parametrize("name", [*OPW_NAMES, "ur5", "panda"])
def test_bundled_arms_are_recognised_as_the_registry_says(name: str) -> None:
    entry = bundled_robots()[name]
    robot = load_robot(name)
    rec = robot.recognition
    assert rec.family == entry.family
    if rec.family in ("opw", "ur"):
        assert rec.residual_m <= VERIFY_TOL_M and rec.residual_rad <= VERIFY_TOL_RAD
    assert rec.opw == entry.opw  # the registry's published parameters: the same conventions, the same numbers


def test_a_ur_urdf_rounding_pi_over_2_to_9_decimals_is_ur_and_to_6_is_not(tmp_path: Path, rng) -> None:
    """example-robot-data's ur5_gripper.urdf writes pi/2 as 1.570796325: the closed form misses its FK by
    1.8e-9 m / 7.2e-9 rad, and it was refused at 1e-9. It is ur now, its branches reproduce random poses
    within the tolerance; the same file with pi/2 to 6 decimals (3.3e-7 rad short) is still refused."""
    urdf = Path(erd_urdf("ur5")).with_name("ur5_gripper.urdf")
    assert "1.570796325" in urdf.read_text()
    robot = load_robot(str(urdf))
    rec = robot.recognition
    assert rec.family == "ur", rec
    assert 1e-9 < rec.residual_rad <= VERIFY_TOL_RAD and rec.residual_m <= VERIFY_TOL_M
    for q in rng.uniform(-np.pi, np.pi, size=(10, 6)):
        target = robot.fk(q)
        sols = solve_all(robot, target, seed=q)
        assert any(np.allclose(s, q, atol=1e-6) for s in sols.q)
        for s in sols.q:
            error = target.actInv(robot.fk(s))
            assert np.linalg.norm(error.translation) <= VERIFY_TOL_M
            assert np.linalg.norm(pin.log3(error.rotation)) <= VERIFY_TOL_RAD
    coarse = tmp_path / "ur5_gripper_6_decimals.urdf"
    coarse.write_text(urdf.read_text().replace("1.570796325", "1.570796"))
    coarse_rec = load_robot(str(coarse)).recognition
    assert coarse_rec.family == "general6"
    assert dict(coarse_rec.rejected)["ur"].startswith("the closed form misses the URDF's FK"), coarse_rec.rejected


def test_recognition_is_cached_per_chain_and_costs_a_few_ms() -> None:
    import time

    robot = load_robot("abb_irb2400")
    model = robot.model.copy()
    start = time.perf_counter()
    first = recognise(model, robot.tip_frame_id)
    again = recognise(model, robot.tip_frame_id)
    assert first is again
    assert time.perf_counter() - start < 0.5  # generous: a fresh recognition measures ~3 ms here


# --- URDF variants: the same arm written with other conventions -----------------------------------

def _tree(name: str) -> ET.ElementTree:
    return ET.parse(load_robot(name).urdf_path)


def _joint(root: ET.Element, name: str) -> ET.Element:
    return next(j for j in root.iter("joint") if j.get("name") == name)


def _flip_axis(root: ET.Element, name: str) -> None:
    """The joint turns the other way: axis negated, limits mirrored (q_new = -q_old)."""
    joint = _joint(root, name)
    axis = joint.find("axis")
    assert axis is not None
    axis.set("xyz", " ".join(str(-float(v)) for v in axis.get("xyz", "").split()))
    limit = joint.find("limit")
    assert limit is not None
    lower, upper = float(limit.get("lower", "0")), float(limit.get("upper", "0"))
    limit.set("lower", str(-upper))
    limit.set("upper", str(-lower))


def _shift_zero(root: ET.Element, name: str, delta_rad: float) -> None:
    """The joint's zero moved by ``delta_rad`` about its axis (q_new = q_old - delta), limits with it."""
    joint = _joint(root, name)
    axis = [float(v) for v in joint.find("axis").get("xyz", "").split()]  # type: ignore[union-attr]
    k = int(np.argmax(np.abs(axis)))
    origin = joint.find("origin")
    assert origin is not None and all(float(v) == 0.0 for v in origin.get("rpy", "0 0 0").split())
    origin.set("rpy", _AXIS_RPY[k].format(d=delta_rad * math.copysign(1.0, axis[k])))
    limit = joint.find("limit")
    assert limit is not None
    for key in ("lower", "upper"):
        limit.set(key, str(float(limit.get(key, "0")) - delta_rad))


def _insert_fixed(root: ET.Element, name: str, xyz: tuple[float, float, float]) -> None:
    """A fixed joint and link inserted before the joint (its origin shortened to compensate)."""
    joint = _joint(root, name)
    parent = joint.find("parent")
    origin = joint.find("origin")
    assert parent is not None and origin is not None
    assert all(float(v) == 0.0 for v in origin.get("rpy", "0 0 0").split())
    extra = f"{name}_mount"
    ET.SubElement(root, "link", name=extra)
    fixed = ET.SubElement(root, "joint", name=f"{extra}_joint", type="fixed")
    ET.SubElement(fixed, "parent", link=parent.get("link", ""))
    ET.SubElement(fixed, "child", link=extra)
    ET.SubElement(fixed, "origin", xyz=" ".join(map(str, xyz)), rpy="0 0 0")
    parent.set("link", extra)
    old = [float(v) for v in origin.get("xyz", "0 0 0").split()]
    origin.set("xyz", " ".join(str(a - b) for a, b in zip(old, xyz, strict=True)))


def _rename_link(root: ET.Element, old: str, new: str) -> None:
    """Rename a link and the joint that makes it its child."""
    for link in root.iter("link"):
        if link.get("name") == old:
            link.set("name", new)
    for joint in root.iter("joint"):
        child = joint.find("child")
        if child is not None and child.get("link") == old:
            child.set("link", new)


def _write(tree: ET.ElementTree, path: Path) -> Path:
    tree.write(path)
    return path


def test_an_axis_flipped_arm_is_opw_with_that_sign_flipped(tmp_path: Path, rng) -> None:
    tree = _tree("fanuc_m10ia")
    _flip_axis(tree.getroot(), "joint_2")
    _flip_axis(tree.getroot(), "joint_6")
    variant = load_robot(_write(tree, tmp_path / "m10ia_flipped.urdf"))
    twin = bundled_robots()["fanuc_m10ia"].opw
    assert variant.family == "opw" and variant.opw is not None and twin is not None
    assert variant.opw.sign_corrections == tuple(s * (-1 if k in (1, 5) else 1)
                                                 for k, s in enumerate(twin.sign_corrections))
    assert variant.opw.offsets_rad == twin.offsets_rad
    assert (variant.opw.a1, variant.opw.a2, variant.opw.c2, variant.opw.c3, variant.opw.c4) == \
        (twin.a1, twin.a2, twin.c2, twin.c3, twin.c4)
    _assert_fk_reproduced(variant.urdf_path, rng)


@pytest.mark.parametrize(("name", "joint", "delta"), [("abb_irb2400", "joint_1", 0.4), ("abb_irb2400", "joint_3", -0.7),
                                                      ("kuka_kr6_r900_2", "joint_2", 0.25),
                                                      ("kuka_kr6_r900_2", "joint_5", 1.1)])
def test_another_zero_pose_is_opw_with_the_offset_moved(name: str, joint: str, delta: float, tmp_path: Path,
                                                        rng) -> None:
    tree = _tree(name)
    _shift_zero(tree.getroot(), joint, delta)
    variant = load_robot(_write(tree, tmp_path / f"{name}_zero.urdf"))
    twin = bundled_robots()[name].opw
    assert variant.family == "opw" and variant.opw is not None and twin is not None
    k = int(joint[-1]) - 1
    # q_old = q_new + delta and q_robot = (q_opw + offset) * sign: the offset moves by -sign * delta
    assert _wrapped(variant.opw.offsets_rad[k] - (twin.offsets_rad[k] - twin.sign_corrections[k] * delta)) == \
        pytest.approx(0.0, abs=1e-12)
    assert variant.opw.sign_corrections == twin.sign_corrections
    assert variant.opw.c2 == pytest.approx(twin.c2, abs=1e-12) and variant.opw.c4 == pytest.approx(twin.c4, abs=1e-12)
    _assert_fk_reproduced(variant.urdf_path, rng)


def test_extra_fixed_joints_and_a_new_base_link_keep_the_arm_opw(tmp_path: Path, rng) -> None:
    tree = _tree("kuka_kr120_r2500_pro")
    root = tree.getroot()
    _placed_base(root, (0.0, 0.0, 0.3), (0.0, 0.0, 0.6))
    _insert_fixed(root, "joint_3", (0.4, 0.0, 0.0))
    _insert_fixed(root, "joint_5", (0.2, 0.0, -0.041))
    variant = load_robot(_write(tree, tmp_path / "kr120_variant.urdf"))
    twin = bundled_robots()["kuka_kr120_r2500_pro"].opw
    assert variant.family == "opw" and variant.opw is not None and twin is not None
    assert variant.opw.c1 == pytest.approx(twin.c1 + 0.3, abs=1e-12)
    assert _wrapped(variant.opw.offsets_rad[0] - (twin.offsets_rad[0] - 0.6)) == pytest.approx(0.0, abs=1e-12)
    for key in ("a1", "a2", "b", "c2", "c3", "c4"):
        assert getattr(variant.opw, key) == pytest.approx(getattr(twin, key), abs=1e-12)
    _assert_fk_reproduced(variant.urdf_path, rng)


def test_every_convention_at_once_still_plans_the_twins_path(tmp_path: Path) -> None:
    """Flipped axes, moved zeros, a fixed joint and a raised base: the IK finds the twin's branches."""
    tree = _tree("abb_irb2400")
    root = tree.getroot()
    _flip_axis(root, "joint_4")
    _shift_zero(root, "joint_2", 0.3)
    _shift_zero(root, "joint_6", -1.0)
    _insert_fixed(root, "joint_5", (0.2, 0.0, 0.0))
    _placed_base(root, (0.0, 0.0, 0.5), (0.0, 0.0, 0.0))
    variant = load_robot(_write(tree, tmp_path / "irb2400_variant.urdf"))
    twin = load_robot("abb_irb2400")
    assert variant.family == "opw"
    q_twin = np.array([0.3, 0.2, 0.1, 0.5, 0.7, -0.4])
    q_variant = q_twin * np.array([1, 1, 1, -1, 1, 1]) - np.array([0, 0.3, 0, 0, 0, -1.0])
    T = twin.fk(q_twin)
    T_variant = pin.SE3(T.rotation, T.translation + np.array([0, 0, 0.5]))
    np.testing.assert_allclose(variant.fk(q_variant).homogeneous, T_variant.homogeneous, atol=1e-12)
    a, b = solve_all(twin, T), solve_all(variant, T_variant)
    assert sorted(a.labels) == sorted(b.labels) and len(a) == len(b) > 0


def test_a_variant_has_its_twins_labels_and_closed_form_distances(tmp_path: Path, rng) -> None:
    """Labels are geometry: a joint-1 zero, flipped wrist axes and a turned base change none of them."""
    tree = _tree("kuka_kr6_r900_2")
    root = tree.getroot()
    _shift_zero(root, "joint_1", -1.2)
    _flip_axis(root, "joint_1")
    _flip_axis(root, "joint_5")
    _shift_zero(root, "joint_4", 0.5)
    _placed_base(root, (0.0, 0.0, 0.1), (0.0, 0.0, 0.8))
    variant, twin = load_robot(_write(tree, tmp_path / "kr6_labels.urdf")), load_robot("kuka_kr6_r900_2")
    q_variant = rng.uniform(np.maximum(variant.lower_rad, -math.pi), np.minimum(variant.upper_rad, math.pi),
                            size=(200, 6))
    q_twin = q_variant.copy()
    q_twin[:, 0] = -q_variant[:, 0] - 1.2  # undo the flip, then the zero shift
    q_twin[:, 3] += 0.5
    q_twin[:, 4] = -q_variant[:, 4]
    closed = distances_batch(variant, q_variant)
    frames = np.array([_signed_distances(*_frames(variant, q)) for q in q_variant])
    np.testing.assert_allclose(closed, frames, rtol=0, atol=1e-12)
    np.testing.assert_allclose(closed, distances_batch(twin, q_twin), rtol=0, atol=1e-12)
    assert [classify(variant, q).label for q in q_variant] == [classify(twin, q).label for q in q_twin]


def test_a_wrist_offset_arm_is_general6_and_says_why(tmp_path: Path) -> None:
    tree = _tree("abb_irb2400")
    origin = _joint(tree.getroot(), "joint_6").find("origin")
    assert origin is not None
    origin.set("xyz", "0.085 0.01 0.0")  # axis 6 10 mm beside the wrist centre
    robot = load_robot(_write(tree, tmp_path / "offset_wrist.urdf"))
    assert robot.family == "general6" and robot.opw is None and robot.ur is None
    assert "axis 6 does not pass through the wrist centre" in robot.recognition.reason
    assert "not ur" in robot.recognition.reason


def test_ur5_with_an_extra_fixed_joint_and_a_raised_base_is_ur(tmp_path: Path, rng) -> None:
    tree = _tree("ur5")
    root = tree.getroot()
    _insert_fixed(root, "elbow_joint", (0.0, -0.05, 0.2))
    _placed_base(root, (0.0, 0.0, 0.25), (0.0, 0.0, 0.0))
    variant = load_robot(_write(tree, tmp_path / "ur5_variant.urdf"))
    twin = load_robot("ur5")
    assert variant.family == "ur" and variant.ur is not None and twin.ur is not None
    assert variant.ur.d1 == pytest.approx(twin.ur.d1 + 0.25, abs=1e-12)
    assert variant.ur.l2 == pytest.approx(twin.ur.l2, abs=1e-12)
    _assert_fk_reproduced(variant.urdf_path, rng)


def _placed_base(root: ET.Element, xyz: tuple[float, float, float], rpy: tuple[float, float, float]) -> None:
    """A new root link anywhere: the old root placed at ``xyz`` turned by ``rpy`` in it."""
    children = {c.get("link") for c in root.iter("child")}
    old_root = next(link.get("name") for link in root.iter("link") if link.get("name") not in children)
    ET.SubElement(root, "link", name="floor")
    fixed = ET.SubElement(root, "joint", name="floor_joint", type="fixed")
    ET.SubElement(fixed, "parent", link="floor")
    ET.SubElement(fixed, "child", link=str(old_root))
    ET.SubElement(fixed, "origin", xyz=" ".join(map(str, xyz)), rpy=" ".join(map(str, rpy)))


def _fixed_link(root: ET.Element, parent: str, name: str, xyz: tuple[float, float, float],
                rpy: tuple[float, float, float]) -> None:
    ET.SubElement(root, "link", name=name)
    fixed = ET.SubElement(root, "joint", name=f"{name}_joint", type="fixed")
    ET.SubElement(fixed, "parent", link=parent)
    ET.SubElement(fixed, "child", link=name)
    ET.SubElement(fixed, "origin", xyz=" ".join(map(str, xyz)), rpy=" ".join(map(str, rpy)))


def test_a_base_anywhere_and_a_tip_off_axis_6_are_folded_into_the_opw_closed_form(tmp_path: Path, rng) -> None:
    """The base link shifted and tilted away from axis 1, the tip turned and set off axis 6: still
    opw with the twin's lengths, the closed form solving the file's FK, the twin's labels."""
    tree = _tree("abb_irb2400")
    root = tree.getroot()
    _placed_base(root, (0.4, -0.2, 0.3), (0.3, -0.2, 0.7))
    _fixed_link(root, "tool0", "gripper_tcp", (0.05, 0.02, 0.1), (0.4, 0.5, 0.6))
    variant = load_robot(_write(tree, tmp_path / "irb2400_placed.urdf"), tip="gripper_tcp")
    twin = bundled_robots()["abb_irb2400"].opw
    assert variant.tip == "gripper_tcp" and variant.family == "opw" and variant.opw is not None and twin is not None
    for key in ("a1", "a2", "b", "c2", "c3"):  # c1 is counted from where the new base meets axis 1
        assert getattr(variant.opw, key) == pytest.approx(getattr(twin, key), abs=1e-12)
    assert variant.opw.c4 == pytest.approx(twin.c4 + 0.1, abs=1e-12)  # the flange at the TCP's foot on axis 6
    assert not np.allclose(variant.recognition.T_base_closed, np.eye(4))
    assert not np.allclose(variant.recognition.T_flange_tip, np.eye(4))
    _assert_fk_reproduced(variant.urdf_path, rng, tip="gripper_tcp")
    q = rng.uniform(np.maximum(variant.lower_rad, -math.pi), np.minimum(variant.upper_rad, math.pi), size=(100, 6))
    twin_robot = load_robot("abb_irb2400")
    np.testing.assert_allclose(distances_batch(variant, q), distances_batch(twin_robot, q), rtol=0, atol=1e-12)
    frames = np.array([_signed_distances(*_frames(variant, qk)) for qk in q])
    np.testing.assert_allclose(frames, distances_batch(variant, q), rtol=0, atol=1e-9)


def test_a_placed_base_and_an_off_axis_tcp_plan_the_twins_wrist_crossing(tmp_path: Path) -> None:
    """The IRB 2400 on a shifted, tilted base with its tip at a TCP off axis 6 plans a wrist near
    miss (wrist-joint: the arm re-solved for the position through the folded frames) with the
    joints and time of the bundled twin carrying the same tool."""
    xyz, rpy, tcp_xyz, tcp_rpy = (0.4, -0.2, 0.3), (0.3, -0.2, 0.7), (0.05, 0.02, 0.1), (0.4, 0.5, 0.6)
    tree = _tree("abb_irb2400")
    _placed_base(tree.getroot(), xyz, rpy)
    _fixed_link(tree.getroot(), "tool0", "gripper_tcp", tcp_xyz, tcp_rpy)
    urdf = _write(tree, tmp_path / "irb2400_placed.urdf")
    twin = load_robot("abb_irb2400", tool=pin.SE3(pin.rpy.rpyToMatrix(*tcp_rpy), np.array(tcp_xyz)))
    q_a, q_b = np.radians([10, 15, 5, 0, -10, 20]), np.radians([10, 25, 15, 0, 10, 20])
    T_b = twin.fk(q_b)
    T_b = pin.SE3(T_b.rotation @ pin.exp3(np.array([math.radians(0.5), 0.0, 0.0])), T_b.translation)  # a near miss
    base = pin.SE3(pin.rpy.rpyToMatrix(*rpy), np.array(xyz))

    def lin(T: pin.SE3) -> dict[str, object]:
        rpy_deg = np.degrees(pin.rpy.matrixToRpy(T.rotation)).tolist()
        return {"lin": {"to": {"xyz": T.translation.tolist(), "rpy_deg": rpy_deg}, "speed": 0.25}}

    common = {"start": {"joints_deg": np.degrees(q_a).tolist()},
              "singularity": {"method": "wrist-joint", "orientation_tolerance_deg": 1.5}}
    by_twin = plan(parse_task({**common, "robot": "abb_irb2400", "moves": [lin(T_b)],
                               "tool": {"xyz": list(tcp_xyz), "rpy_deg": np.degrees(tcp_rpy).tolist()}}))
    by_variant = plan(parse_task({**common, "robot": str(urdf), "tip": "gripper_tcp", "moves": [lin(base * T_b)]}))
    assert "wrist-joint" in [s.method for s in by_twin.segments]
    assert [s.method for s in by_variant.segments] == [s.method for s in by_twin.segments]
    assert by_variant.duration_s == pytest.approx(by_twin.duration_s, abs=1e-9)
    np.testing.assert_allclose(by_variant.q, by_twin.q, rtol=0, atol=1e-7)


def test_a_ros_industrial_style_ur5_base_plans_the_twins_motion(tmp_path: Path) -> None:
    """base_link turned 180 deg about z (ROS-Industrial's UR description): ur, and the UR5 example
    with its target expressed in that base plans the same joints in the same time."""
    tree = _tree("ur5")
    _placed_base(tree.getroot(), (0.0, 0.0, 0.0), (0.0, 0.0, math.pi))
    urdf = _write(tree, tmp_path / "ur5_ros_industrial.urdf")
    assert load_robot(urdf).family == "ur"
    doc = yaml.safe_load((ROOT / "examples" / "ur5_wrist_auto.yaml").read_text())
    target = doc["moves"][0]["lin"]["to"]
    turn = pin.SE3(pin.rpy.rpyToMatrix(0.0, 0.0, math.pi), np.zeros(3))
    T = turn * pin.SE3(pin.rpy.rpyToMatrix(*np.radians(target["rpy_deg"])), np.array(target["xyz"]))
    moved = {**doc, "robot": str(urdf), "moves": [{"lin": {**doc["moves"][0]["lin"], "to": {
        "xyz": T.translation.tolist(), "rpy_deg": np.degrees(pin.rpy.matrixToRpy(T.rotation)).tolist()}}}]}
    twin, variant = plan(parse_task(doc)), plan(parse_task(moved))
    assert variant.duration_s == pytest.approx(twin.duration_s, abs=1e-9)
    np.testing.assert_allclose(variant.q, twin.q, rtol=0, atol=1e-7)
    assert [s.method for s in variant.segments] == [s.method for s in twin.segments]


_UR5_DH_JOINTS = (  # name, parent, xyz, rpy: the DH-style layout of newer ur_description files (UR's published UR5 DH)
    ("shoulder_pan_joint", "base_link_inertia", "0 0 0.089159", "0 0 0"),
    ("shoulder_lift_joint", "shoulder_link", "0 0 0", "1.5707963267948966 0 0"),
    ("elbow_joint", "upper_arm_link", "-0.425 0 0", "0 0 0"),
    ("wrist_1_joint", "forearm_link", "-0.39225 0 0.10915", "0 0 0"),
    ("wrist_2_joint", "wrist_1_link", "0 -0.09465 0", "1.5707963267948966 0 0"),
    ("wrist_3_joint", "wrist_2_link", "0 0.0823 0", "1.5707963267948966 3.141592653589793 3.141592653589793"))


def _ur5_dh_urdf(path: Path) -> Path:
    """A UR5 written as newer ur_description writes it: every joint about its own z, base_link_inertia
    turned 180 deg under base_link, flange and tool0 frames; the bundled UR5's limits."""
    twin = load_robot("ur5")
    root = ET.Element("robot", name="ur5_dh")
    children = ["shoulder_link", "upper_arm_link", "forearm_link", "wrist_1_link", "wrist_2_link", "wrist_3_link"]
    for name in ("base_link", "base_link_inertia", *children, "flange", "tool0"):
        ET.SubElement(root, "link", name=name)
    fixed = [("base_link", "base_link_inertia", "0 0 0", "0 0 3.141592653589793"),
             ("wrist_3_link", "flange", "0 0 0", "0 -1.5707963267948966 -1.5707963267948966"),
             ("flange", "tool0", "0 0 0", "1.5707963267948966 0 1.5707963267948966")]
    for parent, child, xyz, rpy in fixed:
        joint = ET.SubElement(root, "joint", name=f"{parent}-{child}", type="fixed")
        ET.SubElement(joint, "parent", link=parent)
        ET.SubElement(joint, "child", link=child)
        ET.SubElement(joint, "origin", xyz=xyz, rpy=rpy)
    for k, (name, parent, xyz, rpy) in enumerate(_UR5_DH_JOINTS):
        joint = ET.SubElement(root, "joint", name=name, type="revolute")
        ET.SubElement(joint, "parent", link=parent)
        ET.SubElement(joint, "child", link=children[k])
        ET.SubElement(joint, "origin", xyz=xyz, rpy=rpy)
        ET.SubElement(joint, "axis", xyz="0 0 1")
        ET.SubElement(joint, "limit", lower=repr(float(twin.lower_rad[k])), upper=repr(float(twin.upper_rad[k])),
                      effort="150", velocity=repr(float(twin.velocity_rad_s[k])))
    ET.ElementTree(root).write(path)
    return path


def test_a_dh_layout_ur5_is_ur_and_plans_the_twins_motion(tmp_path: Path, rng) -> None:
    """Newer ur_description's layout (the same FK as the bundled UR5, other joint frames): ur by the
    geometric derivation, and the UR5 example (auto crosses with wrist-joint, whose position solve
    uses the closed form's joint-3 frame) plans the same joints in the same time."""
    urdf = _ur5_dh_urdf(tmp_path / "ur5_dh.urdf")
    robot, twin = load_robot(urdf), load_robot("ur5")
    for q in rng.uniform(-3.0, 3.0, size=(20, 6)):
        # 1e-10: the bundled file writes pi/2 as 1.57079632679
        np.testing.assert_allclose(robot.fk(q).homogeneous, twin.fk(q).homogeneous, rtol=0, atol=1e-10)
    assert robot.family == "ur" and robot.ur is not None and twin.ur is not None
    assert not np.allclose(robot.recognition.T_joint3_closed, np.eye(4))
    for key in ("d1", "lateral", "l2", "l3", "d5", "d6"):
        assert getattr(robot.ur, key) == pytest.approx(getattr(twin.ur, key), abs=1e-12)
    _assert_fk_reproduced(urdf, rng)
    q = rng.uniform(-3.0, 3.0, size=(100, 6))
    assert [classify(robot, qk).label for qk in q] == [classify(twin, qk).label for qk in q]
    frames = np.array([_signed_distances(*_frames(robot, qk)) for qk in q])
    np.testing.assert_allclose(frames, distances_batch(robot, q), rtol=0, atol=1e-9)
    doc = yaml.safe_load((ROOT / "examples" / "ur5_wrist_auto.yaml").read_text())
    by_twin, by_dh = plan(parse_task(doc)), plan(parse_task({**doc, "robot": str(urdf)}))
    assert [s.method for s in by_dh.segments] == [s.method for s in by_twin.segments]
    assert "wrist-joint" in [s.method for s in by_dh.segments]
    assert by_dh.duration_s == pytest.approx(by_twin.duration_s, abs=1e-9)
    np.testing.assert_allclose(by_dh.q, by_twin.q, rtol=0, atol=1e-7)


# --- the same URDF by name and by path ------------------------------------------------------------

@pytest.mark.parametrize("task_file", [ROOT / "singplan" / "demo_task.yaml", ROOT / "examples" / "ur5_wrist_auto.yaml"])
def test_the_same_urdf_plans_identically_by_name_and_by_path(task_file: Path) -> None:
    doc = yaml.safe_load(task_file.read_text())
    by_name = plan(parse_task(doc))
    by_path = plan(parse_task({**doc, "robot": str(load_robot(doc["robot"]).urdf_path)}))
    assert by_name.duration_s == by_path.duration_s
    assert by_name.tip == by_path.tip == "tool0"
    np.testing.assert_allclose(by_path.q, by_name.q, rtol=0, atol=1e-12)
    crossings = [s.method for s in by_name.segments if s.kind == "crossing"]
    assert crossings == [s.method for s in by_path.segments if s.kind == "crossing"]
    assert f"(tip {by_name.tip})" in summary(by_path, parse_task(doc))


# --- the tip default rule ---------------------------------------------------------------------------

def test_default_tip_prefers_tool0_then_flange_then_tcp_then_the_last_link(tmp_path: Path) -> None:
    tree = _tree("abb_irb2400")
    root = tree.getroot()
    assert default_tip(load_robot("abb_irb2400").model) == "tool0"
    path = _write(tree, tmp_path / "a.urdf")
    assert load_robot(path).tip == "tool0"
    _rename_link(root, "tool0", "gripper_tcp")
    ET.SubElement(root, "link", name="camera")  # a side link, not named as a tip
    camera = ET.SubElement(root, "joint", name="camera_joint", type="fixed")
    ET.SubElement(camera, "parent", link="link_6")
    ET.SubElement(camera, "child", link="camera")
    assert load_robot(_write(tree, tmp_path / "b.urdf")).tip == "gripper_tcp"
    _rename_link(root, "gripper_tcp", "plate")
    camera.find("parent").set("link", "plate")  # type: ignore[union-attr]
    assert load_robot(_write(tree, tmp_path / "c.urdf")).tip == "camera"  # the link farthest down the chain


def test_a_last_link_named_like_a_joint_is_passed_over_for_one_name_that_is_unique(tmp_path: Path) -> None:
    """The Unitree Z1 style: a fixed joint and its child link both named `plate`. A tip name that
    matches two frames cannot be looked up by other tools (the checker), so the default tip is
    the link above it; named explicitly, the ambiguous name is still the user's choice."""
    tree = _tree("abb_irb2400")
    root = tree.getroot()
    _rename_link(root, "tool0", "plate")
    for joint in root.iter("joint"):
        if joint.find("child").get("link") == "plate":  # type: ignore[union-attr]
            joint.set("name", "plate")
    robot = load_robot(_write(tree, tmp_path / "z1_like.urdf"))
    assert robot.tip == "link_6"
    assert [f.name for f in robot.model.frames].count(robot.tip) == 1


@pytest.mark.parametrize("name", ["so100", "so101", "z1", "panda", "ur5", "ur10", "xarm7"])
def test_a_default_tip_is_one_frame_of_its_urdf_where_the_robot_puts_it(name: str) -> None:
    """By path, the tip names exactly one frame of the whole URDF (as another tool loads it), and that
    frame is where the robot's own chain puts the tip. The SO-100's last link ``gripper`` shares its
    name with the jaw's joint: its tip is the joint frame ``wrist_roll`` at the same place."""
    robot = load_robot(erd_urdf(name))
    full = pin.buildModelFromUrdf(str(robot.urdf_path))
    assert [f.name for f in full.frames].count(robot.tip) == 1
    data = full.createData()
    rng = np.random.default_rng(2)
    for q in rng.uniform(np.maximum(robot.lower_rad, -3), np.minimum(robot.upper_rad, 3), (5, robot.n_joints)):
        q_full = pin.neutral(full)
        for value, joint in zip(q, robot.joint_names, strict=True):
            q_full[full.joints[full.getJointId(joint)].idx_q] = value
        pin.framesForwardKinematics(full, data, q_full)
        assert data.oMf[full.getFrameId(robot.tip)].isApprox(robot.fk_tip(q), 1e-12)
    if name == "so100":
        assert robot.tip == "wrist_roll" == load_robot("so100").tip


def test_the_so100_by_path_plans_and_the_checker_finds_its_tip(tmp_path: Path) -> None:
    """The example task with the URDF given by path: trajectory.json names a tip the checker can look up."""
    doc = yaml.safe_load((Path(__file__).resolve().parents[1] / "examples" / "so100_lin.yaml").read_text())
    doc["robot"] = erd_urdf("so100")
    task = tmp_path / "so100_by_path.yaml"
    task.write_text(yaml.safe_dump(doc))
    assert main(["plan", str(task), "-o", str(tmp_path / "out"), "--no-report", "--no-replay"],
                out=io.StringIO(), err=io.StringIO()) == 0
    assert json.loads((tmp_path / "out" / "trajectory.json").read_text())["tip"] == "wrist_roll"
    done = run_checker(task, tmp_path / "out")
    assert done.returncode == 0, done.stdout + done.stderr


def test_panda_by_path_ends_at_its_tcp_not_at_a_finger() -> None:
    panda = load_robot("panda")
    assert panda.tip == "panda_hand"  # the registry's default
    assert load_robot(panda.urdf_path).tip == "panda_hand_tcp"


# --- singplan info / robots -------------------------------------------------------------------------

def test_info_shows_family_parameters_tip_joints_and_methods() -> None:
    out = io.StringIO()
    assert main(["info", "fanuc_m10ia", "--json"], out=out) == 0
    info = json.loads(out.getvalue())
    assert info["family"] == "opw" and info["tip"] == "tool0"
    assert info["parameters"]["offsets_deg"] == [0.0, 0.0, -90.0, 0.0, 0.0, 180.0]
    assert info["verification"]["residual_m"] <= VERIFY_TOL_M
    assert [j["name"] for j in info["joints"]] == [f"joint_{k}" for k in range(1, 7)]
    assert info["joints"][0]["upper_deg"] == pytest.approx(179.9, abs=1e-9)
    assert all(m["applies"] for m in info["crossing_methods"])
    out = io.StringIO()
    assert main(["info", str(load_robot("panda").urdf_path)], out=out) == 0
    text = out.getvalue()
    assert "family: seven" in text and "tip: panda_hand_tcp" in text
    assert "wrist-joint  no  needs a closed form" in text


def test_info_of_an_unknown_robot_is_bad_input() -> None:
    err = io.StringIO()
    assert main(["info", "abb_irb9999"], out=io.StringIO(), err=err) == 2
    assert "abb_irb9999" in err.getvalue()


def test_robots_lists_the_recognised_family() -> None:
    out = io.StringIO()
    assert main(["robots", "--json"], out=out) == 0
    rows = {r["name"]: r for r in json.loads(out.getvalue())}
    assert rows["ur5"]["family"] == "ur" and rows["panda"]["family"] == "seven"
    assert all(rows[name]["family"] == "opw" for name in OPW_NAMES)


def test_a_user_urdf_named_like_a_bundled_arm_is_replayed_as_itself(tmp_path: Path) -> None:
    from types import SimpleNamespace

    from singplan.outputs.viewer import robot_of

    tree = _tree("abb_irb2400")
    _joint(tree.getroot(), "joint_6").find("origin").set("xyz", "0.2 0.0 0.0")  # type: ignore[union-attr]
    user = _write(tree, tmp_path / "abb_irb2400.urdf")
    joints = load_robot("abb_irb2400").joint_names  # robot_of checks them against the URDF's
    traj = SimpleNamespace(robot="abb_irb2400", urdf=str(user), tip="tool0", tool={"xyz": [0, 0, 0]},
                           joint_names=joints)
    assert robot_of(traj).urdf_path == user  # type: ignore[arg-type]
    bundled = SimpleNamespace(robot="abb_irb2400", urdf=str(load_robot("abb_irb2400").urdf_path), tip="tool0",
                              tool={"xyz": [0, 0, 0]}, joint_names=joints)
    assert robot_of(bundled).urdf_path == load_robot("abb_irb2400").urdf_path  # type: ignore[arg-type]


@pytest.mark.parametrize("name", ["abb_irb2400", "fanuc_m10ia"])
def test_a_variant_keeps_its_branch_at_the_closed_forms_boundaries(name: str, tmp_path: Path) -> None:
    """q = 0, the straightened elbow, q5 = 0 and |q5| = 1e-9 (OPW coordinates) on a re-conventioned arm."""
    tree = _tree(name)
    _flip_axis(tree.getroot(), "joint_5")
    _shift_zero(tree.getroot(), "joint_3", 0.2)
    robot = load_robot(_write(tree, tmp_path / f"{name}_boundary.urdf"))
    p = robot.opw
    assert p is not None
    straight = -math.atan2(p.a2, p.c3)  # OPW q3 where the elbow distance is 0
    mid_opw = (robot.lower_rad + robot.upper_rad) / 2 * p.signs - p.offsets + np.array([0.3, 0.1, 0.1, 0.4, 0.6, -0.2])
    opw_points = [np.where(np.arange(6) == k, value, mid_opw)
                  for k, value in ((2, straight), (4, 0.0), (4, 1e-9), (4, -1e-9))]
    points = [q for q in [np.zeros(6), *((np.array(v) + p.offsets) * p.signs for v in opw_points)]
              if robot.within_limits(q)]
    assert len(points) >= (5 if name == "fanuc_m10ia" else 4)  # the IRB 2400 cannot straighten its elbow
    for q in points:
        target = robot.fk(q)
        sols = solve_all(robot, target, seed=q)
        assert np.min(np.max(np.abs(sols.q - q), axis=1)) < 1e-6  # the seeded branch, not a jump
        for s in sols.q:
            error = target.actInv(robot.fk(s))
            assert np.linalg.norm(error.translation) < 1e-9 and np.linalg.norm(pin.log3(error.rotation)) < 1e-9


def test_methods_a_general6_arm_cannot_use_are_refused_or_listed_never_run_in_disguise(tmp_path: Path) -> None:
    """Axis 6 turned parallel to axis 5 (85 mm beside it): the arm has no wrist singularity, so
    wrist-joint cannot serve; alone it is refused at the (shoulder) zone, under auto listed infeasible,
    with the reason; axis and auto serve."""
    tree = _tree("abb_irb2400")
    _joint(tree.getroot(), "joint_6").find("axis").set("xyz", "0 1 0")  # type: ignore[union-attr]
    urdf = _write(tree, tmp_path / "parallel_56.urdf")
    robot = load_robot(urdf)
    assert robot.family == "general6"
    notes = registry.refusals(robot.recognition)
    assert "axis 6 is parallel to axis 5" in notes["wrist-joint"] and "axis" not in notes and "auto" not in notes
    out = io.StringIO()
    assert main(["info", str(urdf)], out=out) == 0
    assert "wrist-joint  no  needs a wrist singularity to cross, and axis 6 is parallel to axis 5" in out.getvalue()
    q_a, q_b = np.radians([0, -89, 61, 40, 30, 0]), np.radians([0, -83, 55, 40, 30, 0])  # across the shoulder
    outcomes = {}
    for method in ("wrist-joint", "auto"):
        task = {"robot": str(urdf), "start": {"joints_deg": np.degrees(q_a).tolist()},
                "singularity": {"method": method},
                "moves": [{"lin": {"to": {"xyz": robot.fk(q_b).translation.tolist()}, "speed": 0.1}}]}
        (tmp_path / "task.yaml").write_text(yaml.safe_dump(task))
        out, err = io.StringIO(), io.StringIO()
        code = main(["plan", str(tmp_path / "task.yaml"), "-o", str(tmp_path / method), "--quiet", "--no-report",
                     "--no-replay"], out=out, err=err)
        outcomes[method] = (code, err.getvalue())
    code, message = outcomes["wrist-joint"]
    assert code == 3 and "wrist-joint cannot cross the shoulder zone at s = " in message and "general6" in message
    assert "axis 6 is parallel to axis 5" in message
    assert outcomes["auto"][0] == 0, outcomes["auto"][1]
    segments = json.loads((tmp_path / "auto" / "trajectory.json").read_text())["segments"]
    alternatives = {a["method"]: a for a in next(s for s in segments if s["kind"] == "crossing")["alternatives"]}
    assert alternatives["exact"]["feasible"]
    assert not alternatives["wrist-joint"]["feasible"]
    assert "axis 6 is parallel to axis 5" in alternatives["wrist-joint"]["reason"]
