"""A fast slice of bench/robots_acceptance.py: public URDFs planned like the bundled arms.

One bundled arm by name against its URDF copied to another path and against a variant with
other conventions (same family, same duration); the UR5 of example-robot-data recognised as
``ur`` and planning a generated near miss as the bundled UR5 does; a generated wrist near
miss on an OPW arm crossed by a crossing method and passed by the independent checker in
../shared/verify (skipped when that folder is absent, as in a user's clone, except under
CI=true where it must run). About 8 s on 2 cores: it runs with the default suite.
"""

from __future__ import annotations

import json
import math
import shutil
from pathlib import Path
from typing import Any

import numpy as np
import pinocchio as pin
import pytest
import yaml

from singplan.cli import main
from singplan.kinematics.configuration import distances_batch
from singplan.kinematics.robot import bundled_robots, load_robot

from .shared import bench_module, run_checker

ARM = "fanuc_m10ia"
TWIN_TOL = 0.02
FK_TOL_M = 1e-12


ra = bench_module("robots_acceptance")


def _plan(task: dict[str, Any], tmp_path: Path, name: str) -> tuple[int, Path, Path]:
    task_file = tmp_path / f"{name}.yaml"
    task_file.write_text(yaml.safe_dump(task))
    out = tmp_path / name
    return main(["plan", str(task_file), "-o", str(out), "--no-report", "--no-replay", "--quiet"]), task_file, out


def _duration(out: Path) -> float:
    return float(json.loads((out / "trajectory.json").read_text())["t"][-1])


@pytest.fixture(scope="module")
def wrist_task() -> dict[str, Any]:
    found = ra.near_miss_task(load_robot(ARM), "wrist", np.random.default_rng(11), 0.2)
    assert found is not None, f"no wrist near miss found on {ARM} with seed 11"
    return found[0]


def test_the_generated_near_miss_passes_the_wrist_at_the_miss_distance(wrist_task: dict[str, Any]) -> None:
    robot = load_robot(ARM)
    q = np.radians(wrist_task["start"]["joints_deg"])
    start = robot.fk(q)
    end = np.array(wrist_task["moves"][0]["lin"]["to"]["xyz"])
    lo, hi = robot.model.lowerPositionLimit, robot.model.upperPositionLimit
    samples = []
    for u in np.linspace(0.0, 1.0, 401):  # the LIN keeps the start orientation: only the position moves
        q = ra._newton(robot, q, pin.SE3(start.rotation, start.translation + u * (end - start.translation)), lo, hi)
        assert q is not None, f"the generated LIN is not reachable at u = {u:.4f}"
        samples.append(q)
    closest = float(np.min(np.abs(distances_batch(robot, np.array(samples))[:, 0])))
    assert closest == pytest.approx(ra.WRIST_MISS_RAD, rel=0.05)


def test_a_bundled_arm_by_path_and_with_other_conventions_plans_like_by_name(
        tmp_path: Path, wrist_task: dict[str, Any]) -> None:
    src = bundled_robots()[ARM].urdf_path()
    copy = tmp_path / "copy" / src.name
    copy.parent.mkdir()
    shutil.copyfile(src, copy)
    variant = tmp_path / "variant" / src.name
    variant.parent.mkdir()
    ra.write_variant(src, variant)
    by_name, by_path, other = load_robot(ARM), load_robot(copy), load_robot(variant)
    assert by_name.family == by_path.family == other.family == "opw"
    q = np.radians(wrist_task["start"]["joints_deg"])
    arm = ra.Arm("variant", str(variant), "", joint_sign=[1.0, 1.0, 1.0, -1.0, 1.0, 1.0],
                 joint_shift_rad=[0.0, ra.ZERO_SHIFT_RAD, 0.0, 0.0, 0.0, 0.0])
    q_other = np.array(arm.joint_sign) * q - np.array(arm.joint_shift_rad)
    assert np.max(np.abs(other.fk(q_other).translation - by_name.fk(q).translation)) < FK_TOL_M
    code, _, out = _plan(wrist_task, tmp_path, "by_name")
    assert code == 0
    reference = _duration(out)
    for label, arm_here in (("by_path", ra.Arm("by_path", str(copy), "")), ("variant", arm)):
        task = ra.for_twin(wrist_task, arm_here, "tool0")
        assert task["robot"] == (str(copy) if label == "by_path" else str(variant))
        code, _, out = _plan(task, tmp_path, label)
        assert code == 0, label
        assert abs(_duration(out) / reference - 1.0) <= TWIN_TOL, (label, _duration(out), reference)


def test_the_example_robot_data_ur5_is_ur_and_plans_like_the_bundled_ur5(tmp_path: Path) -> None:
    pytest.importorskip("example_robot_data")
    urdf, _ = ra._erd_urdf("ur5")
    robot = load_robot(urdf)
    assert (robot.family, robot.n_joints, robot.tip) == ("ur", 6, "tool0")
    found = ra.near_miss_task(load_robot("ur5"), "wrist", np.random.default_rng(11), 0.2)
    assert found is not None
    code, _, out = _plan(found[0], tmp_path, "ur5_by_name")
    assert code == 0
    reference = _duration(out)
    code, _, out = _plan(ra.for_twin(found[0], ra.Arm("erd", urdf, ""), "tool0"), tmp_path, "ur5_by_path")
    assert code == 0
    assert abs(_duration(out) / reference - 1.0) <= TWIN_TOL, (_duration(out), reference)


def test_the_wrist_near_miss_is_crossed_by_a_crossing_method_and_passes_the_checker(
        tmp_path: Path, wrist_task: dict[str, Any]) -> None:
    code, task_file, out = _plan(wrist_task, tmp_path, "near")
    assert code == 0
    segments = json.loads((out / "trajectory.json").read_text())["segments"]
    crossings = [s for s in segments if s["kind"] == "crossing"]
    assert [s["singularity"] for s in crossings] == ["wrist"]
    assert crossings[0]["method"] not in (None, "exact"), crossings[0]["alternatives"]
    assert crossings[0]["min_distance"] == pytest.approx(ra.WRIST_MISS_RAD, abs=math.radians(0.05))
    run = run_checker(task_file, out)
    assert run.returncode == 0, run.stdout[-2000:]
