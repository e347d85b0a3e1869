"""General 6R arms (no closed form): crossing methods, zones and the all-branch numeric IK.

Test arms: the bundled ABB IRB 2400 with axis 6 moved 10 mm along axis 5 (a wrist offset, no
closed form), and real public URDFs from example-robot-data: the Reach Bravo 7 (its continuous
joints declared revolute over +-2 turns, as docs/robots.md tells users) and the Unitree Z1.
Each plan is written by the CLI and judged by the independent checker. The four crossing tests
plan each task with four methods on arms without a closed form (the numeric all-branch IK at
every path sample: 5-30 s a test), so they are marked slow (CI runs them: ``-m slow``).
"""

from __future__ import annotations

import io
import json
import math
import subprocess
import xml.etree.ElementTree as ET
from pathlib import Path
from typing import Any

import numpy as np
import pinocchio as pin
import pytest
import yaml

from singplan.cli import main
from singplan.kinematics.ik import numeric as ik_numeric
from singplan.kinematics.robot import Robot, load_robot
from singplan.planning.crossing import registry

from .conftest import erd_urdf
from .shared import run_checker

pytest.importorskip("example_robot_data")


def _checker(folder: Path) -> subprocess.CompletedProcess[str]:
    return run_checker(folder / "task.yaml", folder / "out", "--quiet")


@pytest.fixture(scope="module")
def offset_wrist(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """The IRB 2400 with axis 6 10 mm beside the wrist centre (along axis 5)."""
    tree = ET.parse(load_robot("abb_irb2400").urdf_path)
    joint = next(j for j in tree.getroot().iter("joint") if j.get("name") == "joint_6")
    joint.find("origin").set("xyz", "0.085 0.01 0.0")  # type: ignore[union-attr]
    path = tmp_path_factory.mktemp("arms") / "irb2400_offset_wrist.urdf"
    tree.write(path)
    return path


@pytest.fixture(scope="module")
def bravo7(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """example-robot-data's Bravo 7 with its continuous joints declared revolute over +-1 turn."""
    tree = ET.parse(erd_urdf("bravo7_no_ee"))
    for joint in tree.getroot().iter("joint"):
        if joint.get("type") == "continuous":
            joint.set("type", "revolute")
            limit = joint.find("limit")
            if limit is None:  # the file gives none: 1 rad/s, as its revolute wrist joints
                limit = ET.SubElement(joint, "limit", effort="100", velocity="1")
            limit.set("lower", "-6.2832")
            limit.set("upper", "6.2832")
    path = tmp_path_factory.mktemp("arms") / "bravo7_revolute.urdf"
    tree.write(path)
    return path


def _near_miss(urdf: Path | str, q_mid_deg: list[float], dq_deg: list[float], miss_deg: float,
               speed: float, tip: str | None = None, **singularity: float) -> dict[str, Any]:
    """A LIN from FK(q_mid - dq) to FK(q_mid + dq), the end orientation tilted by ``miss_deg`` about x:
    its path passes close to the singularity at q_mid."""
    robot = load_robot(urdf, tip=tip)
    q_mid, dq = np.radians(q_mid_deg), np.radians(dq_deg)
    T_b = robot.fk(q_mid + dq)
    R = T_b.rotation @ pin.exp3(np.array([math.radians(miss_deg), 0.0, 0.0]))
    task: dict[str, Any] = {
        "robot": str(urdf), "start": {"joints_deg": np.degrees(q_mid - dq).round(9).tolist()},
        "moves": [{"lin": {"to": {"xyz": T_b.translation.round(9).tolist(),
                                  "rpy_deg": np.degrees(pin.rpy.matrixToRpy(R)).round(9).tolist()},
                           "speed": speed}}],
        "singularity": {"orientation_tolerance_deg": 1.5, **singularity}}
    if tip is not None:
        task["tip"] = tip
    return task


def _plan(task: dict[str, Any], method: str, folder: Path) -> tuple[int, str, dict[str, Any] | None]:
    """Plan through the CLI; exit code, stdout + stderr and the trajectory (None when not planned)."""
    folder.mkdir(parents=True, exist_ok=True)
    (folder / "task.yaml").write_text(yaml.safe_dump({**task, "singularity": {**task["singularity"],
                                                                              "method": method}}))
    out, err = io.StringIO(), io.StringIO()
    code = main(["plan", str(folder / "task.yaml"), "-o", str(folder / "out"), "--no-report", "--no-replay"],
                out=out, err=err)
    traj = json.loads((folder / "out" / "trajectory.json").read_text()) if code == 0 else None
    return code, out.getvalue() + err.getvalue(), traj


def _crossings(traj: dict[str, Any]) -> list[dict[str, Any]]:
    return [s for s in traj["segments"] if s["kind"] == "crossing"]


def _assert_runner_up_is_not_refused(summary_text: str, traj: dict[str, Any]) -> None:
    """The summary's table of what auto compared lists the methods that planned the move and those
    that could not beat the chosen one (not timed, ``feasible`` null) first, and every refused one
    after them, saying so: the row after the chosen one is never a refused method."""
    for segment in _crossings(traj):
        feasible = {a["method"] for a in segment.get("alternatives") or [] if a["feasible"] is not False}
        rows = [line.split() for line in summary_text.splitlines()
                if line.startswith("          ") and line.split()[0] != "method"]
        refused = ["infeasible:" in row for row in rows]
        assert refused == sorted(refused), summary_text  # the refused ones last
        assert all(row[0] in feasible for row, r in zip(rows, refused, strict=True) if not r), summary_text


def _plan_all(task: dict[str, Any], tmp_path: Path, planned: tuple[str, ...]) -> dict[str, dict[str, Any]]:
    """exact, auto, wrist-joint, axis; those in ``planned`` must plan and pass the checker, the
    others exit 3 (their message under the key "refused:METHOD")."""
    out: dict[str, Any] = {}
    for method in ("exact", "auto", "wrist-joint", "axis"):
        code, text, traj = _plan(task, method, tmp_path / method)
        if method not in planned:
            assert code == 3, text  # a clear refusal, not a crash
            out[f"refused:{method}"] = text
            continue
        assert code == 0 and traj is not None, text
        check = _checker(tmp_path / method)
        assert check.returncode == 0, check.stdout + check.stderr
        if method == "auto":
            _assert_runner_up_is_not_refused(text, traj)
        out[method] = traj
    return out


@pytest.mark.slow
def test_offset_wrist_near_miss_is_crossed_faster_than_exact(offset_wrist: Path, tmp_path: Path) -> None:
    robot = load_robot(offset_wrist)
    assert robot.family == "general6" and not registry.refusals(robot.recognition)
    task = _near_miss(offset_wrist, [10, 20, 10, 0, 0, 20], [0, 5, 5, 0, 10, 0], 0.5, speed=0.25)
    plans = _plan_all(task, tmp_path, ("exact", "auto", "wrist-joint", "axis"))
    for method in ("wrist-joint", "axis"):
        (crossing,) = _crossings(plans[method])
        assert crossing["singularity"] == "wrist" and crossing["method"] == method
    (chosen,) = _crossings(plans["auto"])
    assert chosen["method"] in ("wrist-joint", "axis")  # a crossing method, not exact ...
    assert plans["auto"]["metrics"]["duration_s"] < 0.9 * plans["exact"]["metrics"]["duration_s"]  # ... as faster
    assert min(plans[m]["metrics"]["duration_s"] for m in ("wrist-joint", "axis")) == \
        plans["auto"]["metrics"]["duration_s"]


@pytest.mark.slow
def test_offset_wrist_shoulder_near_miss_is_crossed_by_axis(offset_wrist: Path, tmp_path: Path) -> None:
    """Past the shoulder the offset wrist's branch folds back (the seeded solve stops): the tracker
    goes on in the nearest other branch, exact and wrist-joint refuse that jump (exit 3) and axis
    crosses the zone within 3 mm of the path."""
    task = _near_miss(offset_wrist, [0, -40, -12, 40, 30, 0], [0, 3, -3, 0, 0, 0], 0.0, speed=0.1,
                      position_tolerance_mm=3.0)
    task["moves"][0]["lin"]["to"]["xyz"][1] += 0.002
    plans = _plan_all(task, tmp_path, ("auto", "axis"))
    (chosen,) = _crossings(plans["auto"])
    assert chosen["method"] == "axis" and chosen["singularity"] == "shoulder"
    assert "no continuous joint motion follows the path at s = " in plans["refused:exact"]


@pytest.mark.slow
def test_bravo7_wrist_near_miss_is_crossed_by_axis(bravo7: Path, tmp_path: Path) -> None:
    """A non-spherical wrist: wrist-joint's orientation deviation (3.8 deg) is over the 1.5 deg
    tolerance, so it is infeasible (exit 3 alone); axis keeps it under and auto takes it."""
    robot = load_robot(bravo7)
    assert robot.family == "general6"
    out = io.StringIO()
    assert main(["info", str(bravo7)], out=out) == 0
    assert "wrist-joint  yes joints 1-3 by Newton" in out.getvalue() and "axis         yes" in out.getvalue()
    q_mid = np.radians([20, 60, 60, 30, 180, 20])  # axes 4, 5, 6 coplanar
    assert np.linalg.svd(robot.jacobian(q_mid), compute_uv=False)[-1] < 1e-5  # and singular there
    task = _near_miss(bravo7, [20, 60, 60, 30, 180, 20], [0, 5, 5, 0, 10, 0], 0.5, speed=0.1)
    plans = _plan_all(task, tmp_path, ("exact", "auto", "axis"))
    (chosen,) = _crossings(plans["auto"])
    assert chosen["method"] == "axis" and chosen["singularity"] == "wrist"
    assert plans["auto"]["metrics"]["duration_s"] < 0.9 * plans["exact"]["metrics"]["duration_s"]
    reasons = {a["method"]: a for a in chosen["alternatives"]}
    assert not reasons["wrist-joint"]["feasible"] and "over the tolerance" in reasons["wrist-joint"]["reason"]


@pytest.mark.slow
def test_z1_shoulder_near_miss_is_crossed_by_axis(tmp_path: Path) -> None:
    """The Unitree Z1 (axes 2-4 parallel, 70 mm between axes 4 and 5: no closed form here) passing
    1 mm beside its shoulder singularity; exact would swing joint 4 past its limit."""
    urdf = erd_urdf("z1")
    robot = load_robot(urdf, tip="link06")
    assert robot.family == "general6"
    task = _near_miss(urdf, [10, 55, -90, 0, 30, 20], [0, 4, 4, 0, 0, 0], 0.0, speed=0.1, tip="link06",
                      position_tolerance_mm=3.0)
    task["moves"][0]["lin"]["to"]["xyz"][1] += 0.002
    plans = _plan_all(task, tmp_path, ("auto", "axis"))
    (chosen,) = _crossings(plans["auto"])
    assert chosen["method"] == "axis" and chosen["singularity"] == "shoulder"
    assert chosen["min_distance"] < 2e-3 and chosen["min_distance_unit"] == "m"


@pytest.mark.parametrize("tip", [None, "j2s6s200_end_effector"])
def test_kinova_with_revolute_joints_is_opw_whatever_its_tip(tip: str | None, tmp_path: Path) -> None:
    """The Kinova j2s6s200 (spherical wrist) once its continuous joints are declared revolute: its
    default tip (a finger tip, off axis 6) and its end effector (turned about axis 6) are folded
    into the OPW closed form, which reproduces the file's FK."""
    tree = ET.parse(erd_urdf("kinova"))
    for joint in tree.getroot().iter("joint"):
        if joint.get("type") == "continuous":
            joint.set("type", "revolute")
            limit = joint.find("limit")
            assert limit is not None
            limit.set("lower", "-6.2832")
            limit.set("upper", "6.2832")
    tree.write(tmp_path / "kinova_revolute.urdf")
    robot = load_robot(tmp_path / "kinova_revolute.urdf", tip=tip)
    assert robot.family == "opw", robot.recognition.reason
    assert robot.recognition.residual_m < 1e-9 and robot.recognition.residual_rad < 1e-9


def test_continuous_joints_without_a_speed_limit_are_bad_input_naming_the_joint() -> None:
    """The Bravo 7's continuous joints give no <limit>: their speed limit is unknown, and singplan
    invents none (the Kinova's continuous joints, which give one, plan: tests/test_continuous.py)."""
    err = io.StringIO()
    assert main(["info", erd_urdf("bravo7_no_ee")], out=io.StringIO(), err=err) == 2
    assert "joint 'joint1' has no velocity limit (<limit velocity=...> missing or 0)" in err.getvalue()


def _brute_force(robot: Robot, T: pin.SE3, count: int, seed: int) -> list[np.ndarray]:
    """Distinct solutions of Levenberg-Marquardt from ``count`` uniform random seeds."""
    rng = np.random.default_rng(seed)
    lower, upper = np.maximum(robot.lower_rad, -math.pi), np.minimum(robot.upper_rad, math.pi)
    found = ik_numeric._Found(key=None, seed=None, rows=[], origins=[], keys=[])
    for start in rng.uniform(lower, upper, size=(count, robot.n_joints)):
        q = ik_numeric.solve_lm(robot, T, start)
        if q is not None:
            found.add(q, 0)
    return found.rows


def _same_branches(a: list[np.ndarray], b: list[np.ndarray]) -> bool:
    def key(rows: list[np.ndarray]) -> list[tuple[float, ...]]:
        return sorted(tuple(np.round(np.angle(np.exp(1j * q)), 4)) for q in rows)

    return len(a) == len(b) and np.allclose(key(a), key(b), atol=1e-3)


@pytest.mark.parametrize(("arm", "count"), [("offset", 5), ("z1", 3), ("bravo", 3)])
@pytest.mark.slow  # Levenberg-Marquardt from 300 seeds per pose
def test_numeric_ik_finds_the_branches_a_brute_force_search_finds(arm: str, count: int, offset_wrist: Path,
                                                                 bravo7: Path) -> None:
    """Seeded random poses (and one 0.3 deg from the offset wrist's singularity, one with two Z1
    branches): the all-branch
    search gives exactly the branches of Levenberg-Marquardt from 300 uniform random seeds."""
    robot = {"offset": lambda: load_robot(offset_wrist), "z1": lambda: load_robot(erd_urdf("z1"), tip="link06"),
             "bravo": lambda: load_robot(bravo7)}[arm]()
    rng = np.random.default_rng(3)
    q_all = rng.uniform(np.maximum(robot.lower_rad, -math.pi), np.minimum(robot.upper_rad, math.pi),
                        size=(count, robot.n_joints))
    if arm == "offset":
        q_all[-1] = np.radians([10, 25, 15, 30, 0.3, 20])
    if arm == "z1":  # its joint ranges leave most poses one branch; this one has two
        q_all[-1] = np.radians([105, 67, -86, -62, 31, -67])
    counts = []
    for q in q_all:
        T = robot.fk(q)
        rows, _ = ik_numeric.all_branches(robot, T)
        reference = _brute_force(robot, T, 300, seed=7)
        assert any(np.allclose(np.angle(np.exp(1j * (r - q))), 0.0, atol=1e-6) for r in rows)  # its own branch
        assert _same_branches(rows, reference), (np.degrees(q).round(1).tolist(), len(rows), len(reference))
        counts.append(len(rows))
    assert max(counts) >= (4 if arm == "offset" else 2)  # poses with several branches, not only one
