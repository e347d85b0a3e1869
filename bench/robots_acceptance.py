"""Acceptance on public URDFs: issue 11's "Done when", measured on arms from public sources.

    python bench/robots_acceptance.py [--quick] [--json OUT.json] [--keep DIR] [--seed N] [--markdown]
                                      [--urdf PATH[=TWIN] ...] [--only-urdf]

Arms:
- every bundled industrial arm three ways: by name, its URDF copied to a temporary path, and a
  variant of that copy with the ROS-Industrial conventions changed (an extra fixed root link, a
  ``flange`` link between the last link and ``tool0``, axis 4 flipped with its limits mirrored,
  joint 2's zero pose moved by 30 deg). The copies must be recognised in the same family and
  plan within 2 % of the twin by name;
- example-robot-data arms (``example_robot_data.load(name).urdf``): UR3/5/10, Unitree Z1,
  Kinova Jaco 2, Reach Bravo 7, Panda, xArm 7, SO-100. Each is loaded as the file is, with the
  default tip; where that fails or the default tip takes in a gripper joint, a documented
  adjustment (explicit arm tip, continuous joints given +-2 turn limits) is tried as a second row;
- any other URDF given with ``--urdf PATH`` (``PATH=TWIN`` to compare it with a bundled arm
  whose joint coordinates it shares, e.g. a vendor's own file), e.g. held-back test arms.

Tasks are generated for each arm, not written by hand: for a 6-axis arm, one LIN through a
wrist near miss and one through a shoulder near miss. A configuration at the singular surface
is found from seeded random joints (the singularity distances singplan itself reports,
:func:`singplan.kinematics.configuration.distances_batch`), moved off it by a small miss, and a LIN at
constant orientation is laid through its TCP along the direction in which that distance does
not change to first order, so that the path passes the singularity at the miss distance. Its
reachability is checked by following the path with damped Newton IK from the midpoint both
ways. For 5- and 7-axis arms a short LIN at constant orientation (7-axis: with joint 3 held)
checks that they plan at all.

Each task is planned with ``singplan plan`` (``singularity.method: auto``, in process through
``singplan.cli.main``) and judged by the independent checker
(``../shared/verify/verify_trajectory.py``, skipped when that folder is absent). Criteria
(issue 11, "Done when"): every 6-axis near miss crossed by a crossing method (a ``crossing``
segment whose method is not ``exact``), a copy within 2 % of its twin's duration, a held
joint held to 1e-9 rad, every plan passing the checker.
"""

from __future__ import annotations

import argparse
import contextlib
import io
import json
import logging
import math
import platform
import re
import shutil
import subprocess
import sys
import tempfile
import time
import xml.etree.ElementTree as ET
from dataclasses import asdict, dataclass, field
from pathlib import Path
from typing import Any

import numpy as np
import pinocchio as pin
import yaml

from singplan import __version__, cli
from singplan.errors import SingplanError
from singplan.kinematics.configuration import distances_batch
from singplan.kinematics.robot import Robot, bundled_robots, load_robot

CHECKER = Path(__file__).resolve().parents[2] / "shared" / "verify" / "verify_trajectory.py"
TWIN_TOL = 0.02  # a copy's duration may differ from its twin's by this fraction
TWIN_FK_TOL = 1e-6  # a twin's FK under the joint mapping [m, and rotation matrix entries]
HELD_TOL_RAD = 1e-9  # a 7-axis arm's held joint, issue 11 "Done when"
WRIST_MISS_RAD = math.radians(0.2)  # "a fraction of a degree", as the public near misses
SHOULDER_MISS_M = 0.001  # the public shoulder LINs pass 0.4 mm from axis 1
OTHER_CLEAR = {"wrist": math.radians(10.0), "shoulder": 0.06, "elbow": math.radians(10.0)}
LIN_SPEED_M_S = 0.25
NEWTON_STEP_M = 0.0005  # path step of the reachability check
MAX_JOINT_STEP_RAD = 0.05  # larger joint steps between path samples are halved (a branch jump otherwise)
FLIP_JOINT = 3  # variant: axis 4 flipped
ZERO_JOINT, ZERO_SHIFT_RAD = 1, math.radians(30.0)  # variant: joint 2's zero pose moved
ERD_ARMS = ("ur3", "ur5", "ur10", "z1", "kinova", "bravo7_no_ee", "panda", "xarm7", "so100")
QUICK_BUNDLED = ("fanuc_m10ia",)
QUICK_ERD = ("ur5", "panda", "so100")
# the arm's own last link where the default tip takes in a gripper joint (z1, so100)
ARM_TIPS = {"z1": "link06", "so100": "gripper", "kinova": "j2s6s200_end_effector"}
KINDS = {"wrist": 0, "shoulder": 1, "elbow": 2}
PHASE_JOINT = {"wrist": 3, "shoulder": 0}  # the joint that turns fast through the near miss
log = logging.getLogger("robots_acceptance")


@dataclass
class Arm:
    """One row of arms: how the robot is named in a task and what it is compared with."""

    label: str
    robot: str  # a bundled name or a URDF path
    source: str
    tip: str | None = None
    twin: str | None = None  # label of the arm whose tasks and duration this one reuses
    joint_sign: list[float] = field(default_factory=lambda: [1.0] * 6)
    joint_shift_rad: list[float] = field(default_factory=lambda: [0.0] * 6)  # q_here = sign*q_twin - shift
    note: str = ""


@dataclass
class Outcome:
    """One planned task, as measured here and by the checker."""

    arm: str
    task: str
    exit_code: int
    message: str = ""
    duration_s: float | None = None
    crossings: list[dict[str, Any]] = field(default_factory=list)
    crossed_by_method: bool | None = None
    twin_duration_s: float | None = None
    twin_ok: bool | None = None
    checker: str = "not run"
    checker_figures: dict[str, Any] = field(default_factory=dict)
    checker_failures: list[str] = field(default_factory=list)
    held_joint_dev_rad: float | None = None
    plan_s: float = 0.0


# ---------------------------------------------------------------- URDF variants


def _origin(elem: ET.Element) -> pin.SE3:
    o = elem.find("origin")
    xyz = [float(v) for v in (o.get("xyz", "0 0 0") if o is not None else "0 0 0").split()]
    rpy = [float(v) for v in (o.get("rpy", "0 0 0") if o is not None else "0 0 0").split()]
    return pin.SE3(pin.rpy.rpyToMatrix(*rpy), np.array(xyz))


def _set_origin(elem: ET.Element, T: pin.SE3) -> None:
    o = elem.find("origin")
    if o is None:
        o = ET.SubElement(elem, "origin")
    o.set("xyz", " ".join(repr(float(v)) for v in T.translation))
    o.set("rpy", " ".join(repr(float(v)) for v in pin.rpy.matrixToRpy(T.rotation)))


def _revolute_chain(root: ET.Element) -> list[ET.Element]:
    return [j for j in root.findall("joint") if j.get("type") in ("revolute", "continuous")]


def _flip_axis(joint: ET.Element) -> None:
    axis = joint.find("axis")
    assert axis is not None
    axis.set("xyz", " ".join(repr(-float(v)) for v in axis.get("xyz", "1 0 0").split()))
    lim = joint.find("limit")
    assert lim is not None
    lower, upper = float(lim.get("lower", "0")), float(lim.get("upper", "0"))
    lim.set("lower", repr(-upper))
    lim.set("upper", repr(-lower))


def _shift_zero(joint: ET.Element, shift_rad: float) -> None:
    """The joint's zero becomes the old ``shift_rad`` (the child link turns with it): q_new = q_old - shift_rad."""
    axis = np.array([float(v) for v in joint.find("axis").get("xyz").split()])  # type: ignore[union-attr]
    turn = pin.SE3(pin.exp3(axis / np.linalg.norm(axis) * shift_rad), np.zeros(3))
    _set_origin(joint, _origin(joint) * turn)
    lim = joint.find("limit")
    assert lim is not None
    lim.set("lower", repr(float(lim.get("lower", "0")) - shift_rad))
    lim.set("upper", repr(float(lim.get("upper", "0")) - shift_rad))


def _add_fixed(root: ET.Element, name: str, parent: str, child: str) -> None:
    joint = ET.SubElement(root, "joint", {"name": name, "type": "fixed"})
    ET.SubElement(joint, "parent", {"link": parent})
    ET.SubElement(joint, "child", {"link": child})
    ET.SubElement(joint, "origin", {"xyz": "0 0 0", "rpy": "0 0 0"})


def write_variant(src: Path, dst: Path) -> None:
    """The URDF with other conventions: extra root and flange links, axis 4 flipped, joint 2 re-zeroed."""
    tree = ET.parse(src)
    root = tree.getroot()
    children = {j.find("child").get("link") for j in root.findall("joint")}  # type: ignore[union-attr]
    base = next(lk.get("name") for lk in root.findall("link") if lk.get("name") not in children)
    ET.SubElement(root, "link", {"name": "acceptance_world"})
    _add_fixed(root, "acceptance_world-base", "acceptance_world", str(base))
    tool_joint = next(j for j in root.findall("joint") if j.find("child").get("link") == "tool0")  # type: ignore[union-attr]
    last_link = str(tool_joint.find("parent").get("link"))  # type: ignore[union-attr]
    ET.SubElement(root, "link", {"name": "flange"})
    _add_fixed(root, "acceptance_flange", last_link, "flange")
    tool_joint.find("parent").set("link", "flange")  # type: ignore[union-attr]
    chain = _revolute_chain(root)
    _flip_axis(chain[FLIP_JOINT])
    _shift_zero(chain[ZERO_JOINT], ZERO_SHIFT_RAD)
    tree.write(dst)


def write_with_limits(src: Path, dst: Path) -> None:
    """Continuous joints made revolute with +-2 turn limits (singplan needs position limits)."""
    tree = ET.parse(src)
    for joint in tree.getroot().findall("joint"):
        if joint.get("type") == "continuous":
            joint.set("type", "revolute")
            lim = joint.find("limit")
            if lim is None:
                lim = ET.SubElement(joint, "limit", {"effort": "100", "velocity": "1.0"})
            lim.set("lower", repr(-2 * math.pi))
            lim.set("upper", repr(2 * math.pi))
    tree.write(dst)


def write_joints_renamed(src: Path, dst: Path) -> bool:
    """Joints that share a link's name get a ``_joint`` suffix (False when none does)."""
    tree = ET.parse(src)
    links = {lk.get("name") for lk in tree.getroot().findall("link")}
    clashes = [j for j in tree.getroot().findall("joint") if j.get("name") in links]
    for joint in clashes:
        joint.set("name", f"{joint.get('name')}_joint")
    tree.write(dst)
    return bool(clashes)


# ---------------------------------------------------------------- arms


def bundled_arms(names: list[str], tmp: Path) -> list[Arm]:
    arms = []
    registry = bundled_robots()
    for name in names:
        src = registry[name].urdf_path()
        copy = tmp / "copies" / name / src.name
        copy.parent.mkdir(parents=True, exist_ok=True)
        shutil.copyfile(src, copy)
        variant = tmp / "variants" / name / src.name
        variant.parent.mkdir(parents=True, exist_ok=True)
        write_variant(src, variant)
        sign, shift = [1.0] * 6, [0.0] * 6
        sign[FLIP_JOINT] = -1.0
        shift[ZERO_JOINT] = ZERO_SHIFT_RAD
        arms += [Arm(name, name, "bundled"),
                 Arm(f"{name}@path", str(copy), "bundled, copied", twin=name),
                 Arm(f"{name}@variant", str(variant), "bundled, conventions changed", twin=name,
                     joint_sign=sign, joint_shift_rad=shift,
                     note="root+flange links, axis 4 flipped, joint 2 zero +30 deg")]
    return arms


def _erd_urdf(name: str) -> tuple[str, str]:
    import example_robot_data as erd  # only this part needs it

    with contextlib.redirect_stdout(io.StringIO()):
        urdf = str(Path(erd.load(name).urdf).resolve())
    note = ""
    if name.removesuffix("_no_ee") not in Path(urdf).stem:
        note = f"example_robot_data.load({name!r}) gives {Path(urdf).name}"
    return urdf, note


def erd_arms(names: list[str], tmp: Path, present: set[str]) -> list[Arm]:
    """The example-robot-data arms (labels ``erd:NAME``), each after its bundled twin by name if it has one."""
    arms = []
    bundled = bundled_robots()
    for name in names:
        urdf, note = _erd_urdf(name)
        twin = None
        if name in bundled and Path(urdf).read_bytes() == bundled[name].urdf_path().read_bytes():
            twin = name
            if name not in present:
                arms.append(Arm(name, name, "bundled"))
        arms.append(Arm(f"erd:{name}", urdf, "example-robot-data", twin=twin, note=note))
        own_file = Path(urdf).with_name(f"{name}_robot.urdf")
        if note and own_file.is_file():
            arms.append(Arm(f"erd:{own_file.stem}", str(own_file), "example-robot-data file",
                            note=f"{own_file.name} of the same package (load({name!r}) gives another file)"))
        if 'type="continuous"' in Path(urdf).read_text():
            limited = tmp / "limited" / Path(urdf).name
            limited.parent.mkdir(parents=True, exist_ok=True)
            write_with_limits(Path(urdf), limited)
            arms.append(Arm(f"erd:{name}+limits", str(limited), "example-robot-data, continuous -> +-2 turns",
                            tip=ARM_TIPS.get(name), note="continuous joints given +-2 turn limits"))
        elif name in ARM_TIPS:
            arms.append(Arm(f"erd:{name}+tip", urdf, "example-robot-data", tip=ARM_TIPS[name],
                            note=f"tip {ARM_TIPS[name]} (the default takes in the gripper joint)"))
            renamed = tmp / "renamed" / Path(urdf).name
            renamed.parent.mkdir(parents=True, exist_ok=True)
            if write_joints_renamed(Path(urdf), renamed):
                arms.append(Arm(f"erd:{name}+tip+renamed", str(renamed), "example-robot-data, joints renamed",
                                tip=ARM_TIPS[name], note="joints named like links renamed *_joint"))
    return arms


def recognise(arm: Arm) -> dict[str, Any]:
    """Load as singplan does: family, joints, tip, or the exit code and message of the refusal."""
    try:
        robot = load_robot(arm.robot, tip=arm.tip)
    except SingplanError as exc:
        return {"arm": arm.label, "exit_code": exc.exit_code, "message": str(exc)}
    except Exception as exc:  # a crash is a finding to report, not a reason to stop
        return {"arm": arm.label, "exit_code": 1, "message": f"internal error: {type(exc).__name__}: {exc}"}
    return {"arm": arm.label, "exit_code": 0, "family": robot.family, "joints": robot.n_joints,
            "tip": robot.tip, "rejected": robot.recognition.reason}


# ---------------------------------------------------------------- task generation


def _pose(robot: Robot, q: np.ndarray) -> dict[str, list[float]]:
    T = robot.fk(q)
    return {"xyz": [float(v) for v in T.translation],
            "rpy_deg": [math.degrees(float(v)) for v in pin.rpy.matrixToRpy(T.rotation)]}


def _newton(robot: Robot, q: np.ndarray, target: pin.SE3, lo: np.ndarray, hi: np.ndarray) -> np.ndarray | None:
    """Damped Newton on the TCP pose from ``q``; None when it does not converge inside the limits."""
    for _ in range(30):
        T = robot.fk(q)
        err = np.concatenate([target.translation - T.translation, pin.log3(target.rotation @ T.rotation.T)])
        if np.linalg.norm(err[:3]) < 1e-10 and np.linalg.norm(err[3:]) < 1e-10:
            return q if np.all(q >= lo) and np.all(q <= hi) else None
        J = robot.jacobian(q)
        q = q + J.T @ np.linalg.solve(J @ J.T + 1e-12 * np.eye(6), err)
    return None


def _follow(robot: Robot, q_mid: np.ndarray, direction: np.ndarray, half_m: float) -> list[np.ndarray] | None:
    """Joint samples of the constant-orientation LIN through q_mid's TCP, from -half to +half."""
    T_mid = robot.fk(q_mid)
    steps = math.ceil(half_m / NEWTON_STEP_M)
    sides = []
    for sign in (-1.0, 1.0):
        q, side = q_mid.copy(), []
        for k in range(1, steps + 1):
            q_next = _step(robot, q, T_mid, sign * direction * half_m, (k - 1) / steps, k / steps)
            if q_next is None:
                return None
            q = q_next
            side.append(q)
        sides.append(side)
    return sides[0][::-1] + [q_mid] + sides[1]


def _step(robot: Robot, q: np.ndarray, T_mid: pin.SE3, offset: np.ndarray, u0: float, u1: float,
          depth: int = 0) -> np.ndarray | None:
    """Newton from u0 to u1 along the offset, halving the step where the joints jump (near a singularity)."""
    lo, hi = robot.model.lowerPositionLimit, robot.model.upperPositionLimit
    q_next = _newton(robot, q, pin.SE3(T_mid.rotation, T_mid.translation + u1 * offset), lo, hi)
    if q_next is not None and np.max(np.abs(q_next - q)) <= MAX_JOINT_STEP_RAD:
        return q_next
    if depth >= 12:
        return None
    half = _step(robot, q, T_mid, offset, u0, 0.5 * (u0 + u1), depth + 1)
    return None if half is None else _step(robot, half, T_mid, offset, 0.5 * (u0 + u1), u1, depth + 1)


def _at_distance(robot: Robot, q: np.ndarray, kind: str, target: float, joint: int) -> np.ndarray | None:
    """q with ``joint`` moved so the signed ``kind`` distance equals ``target`` (None if it cannot)."""
    lo, hi = robot.model.lowerPositionLimit[joint], robot.model.upperPositionLimit[joint]
    grid = np.linspace(lo, hi, 721)
    qs = np.repeat(q[None], grid.size, axis=0)
    qs[:, joint] = grid
    f = distances_batch(robot, qs)[:, KINDS[kind]] - target
    roots = np.nonzero((np.sign(f[:-1]) != np.sign(f[1:])) & (np.abs(f[:-1] - f[1:]) < 0.5))[0]
    if roots.size == 0:
        return None
    a, b = grid[roots[0]], grid[roots[0] + 1]
    for _ in range(60):
        m = 0.5 * (a + b)
        qm = q.copy()
        qm[joint] = m
        fm = distances_batch(robot, qm[None])[0, KINDS[kind]] - target
        a, b = (m, b) if np.sign(fm) == np.sign(f[roots[0]]) else (a, m)
    out = q.copy()
    out[joint] = 0.5 * (a + b)
    return out


def _miss_direction(robot: Robot, q: np.ndarray, kind: str) -> np.ndarray | None:
    """Unit TCP direction along which the ``kind`` distance is stationary and the phase joint turns fastest."""
    J = robot.jacobian(q)
    if np.linalg.svd(J, compute_uv=False)[-1] < 1e-6:
        return None
    jinv_xyz = np.linalg.inv(J)[:, :3]  # joint rates of a unit TCP velocity at fixed orientation
    h = 1e-6
    qs = np.repeat(q[None], 12, axis=0)
    for j in range(6):
        qs[2 * j, j] += h
        qs[2 * j + 1, j] -= h
    d = distances_batch(robot, qs)[:, KINDS[kind]]
    grad_q = (d[0::2] - d[1::2]) / (2 * h)
    g = grad_q @ jinv_xyz
    v = jinv_xyz[PHASE_JOINT[kind]]
    g_unit = g / (np.linalg.norm(g) + 1e-300)
    dirn = v - (v @ g_unit) * g_unit
    norm = float(np.linalg.norm(dirn))
    return dirn / norm if norm > 1e-9 else None


def near_miss_task(robot: Robot, kind: str, rng: np.random.Generator, length_m: float,
                   tries: int = 200) -> tuple[dict[str, Any], dict[str, float]] | None:
    """A LIN whose path passes the ``kind`` singularity at the miss distance, or None."""
    lo, hi = robot.model.lowerPositionLimit, robot.model.upperPositionLimit
    margin = 0.1 * (hi - lo)
    miss = WRIST_MISS_RAD if kind == "wrist" else SHOULDER_MISS_M
    tune = 4 if kind == "wrist" else 1
    for attempt in range(tries):
        q = rng.uniform(lo + margin, hi - margin)
        if kind == "shoulder":
            q[2] = rng.uniform(lo[2] + margin[2], hi[2] - margin[2])
        q_mid = _at_distance(robot, q, kind, miss * rng.choice([-1.0, 1.0]), tune)
        if q_mid is None:
            continue
        direction = _miss_direction(robot, q_mid, kind)
        if direction is None:
            continue
        path = _follow(robot, q_mid, direction, 0.5 * length_m)
        if path is None:
            continue
        dists = distances_batch(robot, np.array(path))
        others = [k for k in KINDS if k != kind]
        if any(np.min(np.abs(dists[:, KINDS[k]])) < OTHER_CLEAR[k] for k in others):
            continue
        closest = float(np.min(np.abs(dists[:, KINDS[kind]])))
        task = _lin_task(robot, path[0], path[-1])
        return task, {"closest_along_path": closest, "tries": attempt + 1}
    return None


def _lin_task(robot: Robot, q_start: np.ndarray, q_end: np.ndarray,
              extra: dict[str, Any] | None = None) -> dict[str, Any]:
    task: dict[str, Any] = {
        "robot": str(robot.urdf_path) if robot.entry is None else robot.name,
        "start": {"joints_deg": [math.degrees(float(v)) for v in q_start]},
        "moves": [{"lin": {"to": _pose(robot, q_end), "speed": LIN_SPEED_M_S}}],
        "singularity": {"method": "auto"},
        "limits": {"velocity_scale": 1.0, "acceleration": 10.0},
        "output": {"period": 0.004},
    }
    if robot.tip != (robot.entry.tip if robot.entry is not None else None):
        task["tip"] = robot.tip
    task.update(extra or {})
    return task


def reduced_task(robot: Robot, rng: np.random.Generator, length_m: float, tries: int = 200) -> dict[str, Any] | None:
    """A short LIN at constant orientation for a 5- or 7-axis arm (7-axis: joint 3 held)."""
    lo, hi = robot.model.lowerPositionLimit, robot.model.upperPositionLimit
    margin = 0.15 * (hi - lo)
    names = [robot.model.names[j] for j in range(1, robot.model.njoints)]
    for _ in range(tries):
        q = rng.uniform(lo + margin, hi - margin)
        J = robot.jacobian(q)
        if np.linalg.svd(J[:3], compute_uv=False)[-1] < 0.05:
            continue
        direction = rng.normal(size=3)
        direction /= np.linalg.norm(direction)
        if robot.n_joints == 7:  # move with joint 3 held: a pseudo-inverse of the other six columns
            keep = [j for j in range(7) if j != 2]
            dq = np.zeros(7)
            dq[keep] = np.linalg.lstsq(J[:, keep], np.concatenate([direction, np.zeros(3)]), rcond=None)[0]
        else:  # 5 axes: a joint motion that keeps the tool axis still to first order (its rate
            # rows are the angular velocity across z), so the LIN's direction is one the arm can hold
            z = robot.fk(q).rotation[:, 2]
            across = np.linalg.svd(np.eye(3) - np.outer(z, z))[0][:, :2]  # (3, 2) unit vectors normal to z
            free = np.linalg.svd(across.T @ J[3:])[2][2:].T  # (5, 3) null space of the tool-axis rates
            dq = free @ rng.normal(size=free.shape[1])
        q_end = q + dq * length_m / max(1e-9, float(np.linalg.norm(J[:3] @ dq)))
        if not (np.all(q_end >= lo) and np.all(q_end <= hi)):
            continue
        extra = {}
        if robot.n_joints == 7:
            extra["redundancy"] = {"joint": names[2], "value_deg": math.degrees(float(q[2]))}
        return _lin_task(robot, q, q_end, extra)
    return None


def for_twin(task: dict[str, Any], arm: Arm, twin_tip: str) -> dict[str, Any]:
    """The twin's task on this arm: its robot, and the start joints in this URDF's coordinates."""
    out = json.loads(json.dumps(task))
    if not out:
        return out
    out["robot"] = arm.robot
    q = np.radians(task["start"]["joints_deg"])
    n = q.size
    q_here = np.resize(np.array(arm.joint_sign), n) * q - np.resize(np.array(arm.joint_shift_rad), n)
    out["start"]["joints_deg"] = [math.degrees(float(v)) for v in q_here]
    out["tip"] = arm.tip or twin_tip  # the twin's tip: the comparison is of planning, not of tip rules
    return out


# ---------------------------------------------------------------- planning and checking


def plan_and_check(arm: Arm, name: str, task: dict[str, Any], work: Path) -> Outcome:
    task_file = work / f"{arm.label}__{name}.yaml".replace("/", "_")
    out_dir = work / f"{arm.label}__{name}".replace("/", "_")
    task_file.write_text(yaml.safe_dump(task, sort_keys=False))
    err = io.StringIO()
    t0 = time.perf_counter()
    with contextlib.redirect_stderr(err), contextlib.redirect_stdout(io.StringIO()):
        code = cli.main(["plan", str(task_file), "-o", str(out_dir), "--no-report", "--no-replay"])
    outcome = Outcome(arm.label, name, code, message=err.getvalue().strip()[-400:],
                      plan_s=round(time.perf_counter() - t0, 2))
    if code != 0:
        return outcome
    traj = json.loads((out_dir / "trajectory.json").read_text())
    outcome.duration_s = float(traj["t"][-1])
    outcome.crossings = [{"singularity": s.get("singularity"), "method": s.get("method"),
                          "min_distance": s.get("min_distance"), "time_lost_s": s.get("time_lost_s"),
                          "alternatives": s.get("alternatives", [])}
                         for s in traj["segments"] if s["kind"] == "crossing"]
    if "redundancy" in task:
        held = [n == task["redundancy"]["joint"] for n in traj["joint_names"]].index(True)
        dev = np.abs(np.array(traj["q"])[:, held] - math.radians(task["redundancy"]["value_deg"]))
        outcome.held_joint_dev_rad = float(np.max(dev))
    _check(outcome, task_file, out_dir)
    return outcome


def _check(outcome: Outcome, task_file: Path, out_dir: Path) -> None:
    if not CHECKER.is_file():
        outcome.checker = "absent"
        return
    run = subprocess.run([sys.executable, str(CHECKER), str(task_file), str(out_dir), "--json"],
                         capture_output=True, text=True, timeout=600)
    outcome.checker = {0: "pass", 1: "FAIL"}.get(run.returncode, f"error {run.returncode}")
    try:
        result = json.loads(run.stdout[:run.stdout.rindex("}") + 1])
    except ValueError:
        outcome.checker_failures = [run.stdout.strip()[-300:] + run.stderr.strip()[-300:]]
        return
    outcome.checker_figures = {k: v for k, v in result.get("metrics", {}).items() if isinstance(v, (int, float))}
    outcome.checker_failures = [str(f) for f in result.get("failures", [])]


def _crossed(outcome: Outcome, kind: str) -> bool:
    return any(c["singularity"] == kind and c["method"] not in (None, "exact") for c in outcome.crossings)


def user_arms(specs: list[str], present: set[str]) -> list[Arm]:
    """``PATH`` or ``PATH=TWIN`` (a bundled name with the same joint coordinates) from the command line."""
    arms = []
    for spec in specs:
        path, _, twin = spec.partition("=")
        if twin and twin not in present:
            arms.append(Arm(twin, twin, "bundled"))
            present.add(twin)
        arms.append(Arm(f"file:{Path(path).stem}", str(Path(path).resolve()), "--urdf", twin=twin or None))
    return arms


def _confirm_twin(arm: Arm, twin_tip: str) -> None:
    """Drop a twin whose FK under the joint mapping differs (another joint convention, another arm)."""
    here, twin = load_robot(arm.robot, tip=arm.tip or twin_tip), load_robot(str(arm.twin))
    if here.n_joints != twin.n_joints:
        arm.note, arm.twin = f"not a twin of {arm.twin}: {here.n_joints} joints", None
        return
    rng = np.random.default_rng(0)
    n = twin.n_joints
    sign, shift = np.resize(np.array(arm.joint_sign), n), np.resize(np.array(arm.joint_shift_rad), n)
    worst = max(float(np.max(np.abs(here.fk(sign * q - shift).homogeneous - twin.fk(q).homogeneous)))
                for q in rng.uniform(twin.model.lowerPositionLimit, twin.model.upperPositionLimit, (20, n)))
    if worst > TWIN_FK_TOL:
        arm.note, arm.twin = f"not a twin of {arm.twin}: FK differs by {worst:.3g} (other joint coordinates)", None


def run(quick: bool, seed: int, work_root: Path, extra_urdfs: list[str] | None = None,
        only_extra: bool = False) -> dict[str, Any]:
    """Every arm's recognition, generated tasks, plans and checks; task files and plans go to ``work_root``."""
    work_root.mkdir(parents=True, exist_ok=True)
    arms: list[Arm] = []
    if not only_extra:
        names = list(QUICK_BUNDLED) if quick else [n for n in sorted(bundled_robots())
                                                   if load_robot(n).n_joints == 6]
        arms = bundled_arms(names, work_root)
        arms += erd_arms(list(QUICK_ERD if quick else ERD_ARMS), work_root, {a.label for a in arms})
    arms += user_arms(extra_urdfs or [], {a.label for a in arms})
    recognitions = {arm.label: recognise(arm) for arm in arms}
    for arm in arms:
        if arm.twin is not None and recognitions[arm.label]["exit_code"] == 0:
            _confirm_twin(arm, recognitions[arm.twin]["tip"])
    outcomes: list[Outcome] = []
    tasks: dict[str, dict[str, dict[str, Any]]] = {}
    generation: dict[str, dict[str, Any]] = {}
    by_label = {a.label: a for a in arms}
    for arm in arms:
        rec = recognitions[arm.label]
        if rec["exit_code"] != 0:
            continue
        if arm.twin is not None and arm.twin in tasks:
            own = {name: for_twin(t, arm, recognitions[arm.twin]["tip"]) for name, t in tasks[arm.twin].items()}
        else:
            own, generation[arm.label] = _generate(load_robot(arm.robot, tip=arm.tip), seed)
            tasks[arm.label] = own
        for name, task in own.items():
            if not task:
                outcomes.append(Outcome(arm.label, name, -1, message="not generated: no LIN within the limits"))
                continue
            outcome = plan_and_check(arm, name, task, work_root)
            _judge(outcome, name, outcomes, by_label)
            outcomes.append(outcome)
            log.info("%s %s: exit %d %s %s", arm.label, name, outcome.exit_code, outcome.duration_s, outcome.checker)
    return {"arms": [asdict(a) | {"recognition": recognitions[a.label], "generation": generation.get(a.label)}
                     for a in arms],
            "outcomes": [asdict(o) for o in outcomes], "work_dir": str(work_root)}


def _generate(robot: Robot, seed: int) -> tuple[dict[str, dict[str, Any]], dict[str, Any]]:
    rng = np.random.default_rng(seed)
    lo, hi = robot.model.lowerPositionLimit, robot.model.upperPositionLimit
    reach = float(max(np.linalg.norm(robot.fk(q).translation) for q in rng.uniform(lo, hi, (64, robot.n_joints))))
    length_m = min(0.2, 0.3 * reach)
    tasks: dict[str, dict[str, Any]] = {}
    notes: dict[str, Any] = {"length_m": length_m}
    if robot.n_joints == 6:
        for kind in ("wrist", "shoulder"):
            found = near_miss_task(robot, kind, rng, length_m)
            if found is None:
                notes[kind] = "no near-miss LIN found within the limits"
                tasks[f"{kind}_near_miss"] = {}
                continue
            tasks[f"{kind}_near_miss"], notes[kind] = found
    else:
        task = reduced_task(robot, rng, 0.5 * length_m)
        if task is None:
            notes["lin"] = "no LIN found"
        elif "redundancy" in task:  # both ways a 7-axis arm is planned: joint 3 held, and minimum norm
            tasks["lin_held"] = task
            tasks["lin"] = {k: v for k, v in task.items() if k != "redundancy"}
        else:
            tasks["lin"] = task
    return tasks, notes


def _judge(outcome: Outcome, name: str, done: list[Outcome], arms: dict[str, Arm]) -> None:
    if name.endswith("_near_miss") and outcome.exit_code == 0:
        outcome.crossed_by_method = _crossed(outcome, name.removesuffix("_near_miss"))
    twin = arms[outcome.arm].twin
    ref = next((o for o in done if o.arm == twin and o.task == name), None)
    if ref is not None and ref.duration_s and outcome.duration_s is not None:
        outcome.twin_duration_s = ref.duration_s
        outcome.twin_ok = abs(outcome.duration_s / ref.duration_s - 1.0) <= TWIN_TOL


# ---------------------------------------------------------------- report


def _yes(v: bool | None) -> str:
    return "-" if v is None else ("yes" if v else "NO")


def table(result: dict[str, Any]) -> str:
    lines = ["| arm | source | family (tip) | task | exit | duration [s] | crossings | crossed by method | "
             "twin [s] | within 2% | checker |", "|" + "---|" * 11]
    by_arm: dict[str, list[dict[str, Any]]] = {}
    for o in result["outcomes"]:
        by_arm.setdefault(o["arm"], []).append(o)
    for arm in result["arms"]:
        rec = arm["recognition"]
        fam = (f"{rec['family']} {rec['joints']}R ({rec['tip']})" if rec["exit_code"] == 0
               else f"exit {rec['exit_code']}")
        rows = by_arm.get(arm["label"], [])
        if not rows:
            why = rec.get("message") or "; ".join(f"{k}: {v}" for k, v in (arm["generation"] or {}).items()
                                                   if isinstance(v, str)) or "no task"
            lines.append(f"| {arm['label']} | {arm['source']} | {fam} | - | - | - | {_short(why)} | - | - | - | - |")
        for o in rows:
            cross = ", ".join(f"{c['singularity']}:{c['method']}" for c in o["crossings"]) or "none"
            if o["exit_code"] != 0:
                cross = _short(o["message"])
            code = "-" if o["exit_code"] == -1 else str(o["exit_code"])
            dur = "-" if o["duration_s"] is None else f"{o['duration_s']:.3f}"
            twin = "-" if o["twin_duration_s"] is None else f"{o['twin_duration_s']:.3f}"
            lines.append(f"| {arm['label']} | {arm['source']} | {fam} | {o['task']} | {code} | {dur} | "
                         f"{cross} | {_yes(o['crossed_by_method'])} | {twin} | {_yes(o['twin_ok'])} | {o['checker']} |")
    return "\n".join(lines)


def _cell(o: dict[str, Any] | None) -> str:
    if o is None:
        return "-"
    if o["exit_code"] == -1:
        return "not generated"
    if o["exit_code"] != 0:
        return f"exit {o['exit_code']}"
    methods = ",".join(sorted({c["method"] for c in o["crossings"]})) or "no zone"
    held = "" if o["held_joint_dev_rad"] is None else f", held to {o['held_joint_dev_rad']:.1e} rad"
    return f"{methods} {o['duration_s']:.3f} s{held}, checker {o['checker']}"


def _twin_cells(tasks: dict[str, dict[str, Any]]) -> str:
    def verdict(o: dict[str, Any]) -> str:
        return _cell(o) if o["twin_ok"] is None else ("yes" if o["twin_ok"] else "NO")

    return ", ".join(f"{name.removesuffix('_near_miss')} {verdict(o)}" for name, o in tasks.items())


def condensed_table(result: dict[str, Any]) -> str:
    """One row per arm as loaded (its copies folded into the last column), for docs/robots.md."""
    outs: dict[str, dict[str, dict[str, Any]]] = {}
    for o in result["outcomes"]:
        outs.setdefault(o["arm"], {})[o["task"]] = o
    lines = ["| arm | family (tip) | wrist near miss / LIN | shoulder near miss / LIN, joint 3 held | "
             "same duration (2 %) by path, variant, twin |", "|---|---|---|---|---|"]
    for arm in result["arms"]:
        label, rec = arm["label"], arm["recognition"]
        if "@" in label:
            continue
        fam = f"{rec['family']} ({rec['tip']})" if rec["exit_code"] == 0 else f"exit {rec['exit_code']}"
        tasks = outs.get(label, {})
        first, second = ((tasks.get("lin"), tasks.get("lin_held")) if "lin" in tasks
                         else (tasks.get("wrist_near_miss"), tasks.get("shoulder_near_miss")))
        twins = [f"{kind}: {_twin_cells(outs[label + '@' + kind])}" for kind in ("path", "variant")
                 if label + "@" + kind in outs]
        if arm["twin"]:
            twins.append(f"vs {arm['twin']}: {_twin_cells(tasks)}")
        lines.append(f"| {label} | {fam} | {_cell(first)} | {_cell(second)} | {'; '.join(twins) or '-'} |")
    return "\n".join(lines)


def _short(text: str, n: int = 110) -> str:
    text = re.sub(r"\s+", " ", text.replace("|", "/"))
    return text if len(text) <= n else text[:n - 3] + "..."


def summary_counts(result: dict[str, Any]) -> dict[str, str]:
    outs = [o for o in result["outcomes"] if o["exit_code"] != -1]
    near = [o for o in outs if o["task"].endswith("_near_miss")]
    twins = [o for o in outs if o["twin_ok"] is not None]
    checked = [o for o in outs if o["checker"] not in ("not run", "absent")]
    crossed = sum(bool(o["crossed_by_method"]) for o in near)
    held = [o for o in outs if o["held_joint_dev_rad"] is not None]
    missing = len(result["outcomes"]) - len(outs)
    copies = {a["label"] for a in result["arms"] if a["twin"]}
    own = [o for o in near if o["arm"] not in copies]
    return {"near misses crossed by a crossing method": f"{crossed}/{len(near)}",
            "the same, copies left out": f"{sum(bool(o['crossed_by_method']) for o in own)}/{len(own)}",
            "near misses not generated (no LIN found)": str(missing),
            "copies within 2% of their twin": f"{sum(o['twin_ok'] for o in twins)}/{len(twins)}",
            "held joints within 1e-9 rad": f"{sum(o['held_joint_dev_rad'] <= HELD_TOL_RAD for o in held)}/"
                                           f"{sum(1 for o in outs if o['task'] == 'lin_held')}",
            "plans passing the checker": f"{sum(o['checker'] == 'pass' for o in checked)}/{len(checked)}",
            "tasks planned (exit 0)": f"{sum(o['exit_code'] == 0 for o in outs)}/{len(outs)}"}


def environment() -> dict[str, str]:
    from importlib import metadata

    def version(dist: str) -> str:
        try:
            return metadata.version(dist)
        except metadata.PackageNotFoundError:
            return "absent"

    return {"date": time.strftime("%Y-%m-%d %H:%M UTC", time.gmtime()), "python": platform.python_version(),
            "singplan": __version__, "pinocchio": pin.__version__, "numpy": np.__version__,
            "toppra": version("toppra"), "example-robot-data": version("example-robot-data"),
            "machine": f"{platform.machine()}, 2 cores"}


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--quick", action="store_true",
                    help="one bundled arm (three ways) and UR5, Panda, SO-100 from example-robot-data")
    ap.add_argument("--json", type=Path, help="write the full result here")
    ap.add_argument("--keep", type=Path, help="keep tasks and plans in this folder")
    ap.add_argument("--seed", type=int, default=11)
    ap.add_argument("--markdown", action="store_true", help="also print one row per arm (docs/robots.md)")
    ap.add_argument("--urdf", action="append", default=[], metavar="PATH[=TWIN]",
                    help="another URDF (repeatable); =TWIN compares it with that bundled arm")
    ap.add_argument("--only-urdf", action="store_true", help="only the --urdf files (and their twins)")
    args = ap.parse_args(argv)
    logging.basicConfig(level=logging.INFO, format="%(message)s", stream=sys.stderr)
    t0 = time.perf_counter()
    with tempfile.TemporaryDirectory(prefix="robots_acceptance_") as scratch:
        result = run(args.quick, args.seed, args.keep or Path(scratch), args.urdf, args.only_urdf)
    result["environment"] = environment() | {"seed": str(args.seed), "wall_s": f"{time.perf_counter() - t0:.0f}"}
    result["summary"] = summary_counts(result)
    print(table(result))
    if args.markdown:
        print()
        print(condensed_table(result))
    for key, value in result["summary"].items():
        print(f"{key}: {value}")
    for arm in result["arms"]:
        if arm["note"]:
            print(f"{arm['label']}: {arm['note']}")
    if args.json:
        args.json.write_text(json.dumps(result, indent=1, default=str))
    return 0


if __name__ == "__main__":
    sys.exit(main())
