"""Planning edge cases users hit: pose starts with a configuration, PTP to poses, URDF paths,
reorientations, and the exit codes of the CLI for each kind of failure."""

from __future__ import annotations

import io
from pathlib import Path

import numpy as np
import pinocchio as pin
import pytest

from singplan.cli import main
from singplan.errors import TaskError, UnreachableError
from singplan.kinematics.robot import load_robot
from singplan.results.plan import plan
from singplan.task.load import parse_task

BASE = {"robot": "kuka_kr6_r900_2", "tool": {"xyz": [0, 0, 0.1]},
        "start": {"joints_deg": [0, -80, 100, 0, 40, 0]}}
_START_XYZ = load_robot("kuka_kr6_r900_2", tool=pin.SE3(np.eye(3), np.array([0, 0, 0.1]))).fk(
    np.radians([0, -80, 100, 0, 40, 0])).translation


def _floats(values: np.ndarray) -> list[float]:
    return [float(v) for v in values]


def task(**changes: object) -> dict:
    return {**BASE, **changes}


def test_pose_start_with_a_configuration_and_ptp_to_a_pose_with_a_configuration() -> None:
    robot = load_robot("kuka_kr6_r900_2")
    q = np.radians([10, -70, 95, 20, 35, 10])
    T = robot.fk(q)
    rpy = list(np.degrees(pin.rpy.matrixToRpy(T.rotation)))
    doc = {"robot": "kuka_kr6_r900_2", "start": {"pose": {"xyz": list(T.translation), "rpy_deg": rpy},
                                                 "config": "F U N"},
           "moves": [{"ptp": {"to": {"xyz": _floats(T.translation + np.array([0.05, 0, 0])), "rpy_deg": rpy},
                              "config": "F U F"}}]}
    traj = plan(parse_task(doc))
    assert traj.segments[0].config_before == "F U N" and traj.segments[-1].config_after == "F U F"
    assert np.linalg.norm(robot.fk(traj.q[-1]).translation - (T.translation + np.array([0.05, 0, 0]))) < 1e-9


def test_start_pose_in_a_configuration_the_pose_does_not_have_is_no_plan() -> None:
    doc = task(start={"pose": {"xyz": [0.5, 0.0, 0.6], "rpy_deg": [0, 90, 0]}, "config": "B D N"},
               moves=[{"ptp": {"to": {"joints_deg": [0, -80, 100, 0, 40, 0]}}}])
    with pytest.raises(UnreachableError, match=r"start\.pose"):
        plan(parse_task(doc))


def test_pure_reorientation_lin_turns_on_the_spot() -> None:
    robot = load_robot("kuka_kr6_r900_2", tool=None)
    q0 = np.radians([0, -80, 100, 0, 40, 0])
    T = robot.fk(q0)
    rpy = np.degrees(pin.rpy.matrixToRpy(T.rotation)) + np.array([0, 0, 20])
    traj = plan(parse_task({"robot": "kuka_kr6_r900_2", "start": {"joints_deg": list(np.degrees(q0))},
                            "moves": [{"lin": {"to": {"xyz": list(T.translation), "rpy_deg": list(rpy)}}}]}))
    p = np.array([robot.fk(q).translation for q in traj.q])
    assert np.max(np.linalg.norm(p - T.translation, axis=1)) < 1e-9
    assert traj.metrics.max_orientation_error_deg < 1e-6


def test_a_urdf_given_by_path_plans(tmp_path: Path) -> None:
    urdf = load_robot("ur5").urdf_path
    doc = {"robot": str(urdf), "tip": "tool0", "start": {"joints_deg": [10, -70, 90, -30, 40, 20]},
           "moves": [{"ptp": {"to": {"joints_deg": [20, -60, 80, -20, 50, 30]}, "velocity_scale": 0.5}}]}
    traj = plan(parse_task(doc))
    assert traj.robot == urdf.stem and traj.urdf == str(urdf)
    np.testing.assert_allclose(traj.q[-1], np.radians([20, -60, 80, -20, 50, 30]), atol=1e-12)


@pytest.mark.parametrize(("doc", "code", "words"), [
    (task(moves=[{"lin": {"to": {"xyz": [0.5, 0.0, 0.5], "rpy_deg": [0, 90, 0]}}},
                 {"lin": {"to": {"xyz": [0.5, 0.1, 0.5], "rpy_deg": [180, -90, 0]}}}]), 2, "ambiguous"),
    (task(moves=[{"circ": {"via": {"xyz": _floats(_START_XYZ + np.array([0, 0.05, 0]))},
                           "to": {"xyz": _floats(_START_XYZ + np.array([0, 0.1, 0]))}}}]), 2, "collinear"),
    (task(moves=[{"ptp": {"to": {"joints_deg": [0, -80, 100, 0, 40]}}}]), 2, "expected 6 joint values"),
    (task(moves=[{"ptp": {"to": {"joints_deg": [0, -80, 100, 0, 140, 0]}}}]), 2, "outside its limits"),
    (task(moves=[{"ptp": {"to": {"xyz": [3.0, 0.0, 0.5]}}}]), 3, "no IK solution"),
    (task(moves=[{"lin": {"to": {"xyz": [0.2, 0.0, 0.5]}}}], tip="flange_x"), 2, "unknown tip frame"),
    (task(moves=[{"ptp": {"to": {"joints_deg": [0, -80, 100, 0, 40, 0]}}}],
          limits={"acceleration": [1, 2, 3]}), 2, "limits.acceleration"),
])
def test_cli_exit_codes_name_the_problem(tmp_path: Path, doc: dict, code: int, words: str) -> None:
    import yaml

    path = tmp_path / "task.yaml"
    path.write_text(yaml.safe_dump(doc))
    err = io.StringIO()
    assert main(["plan", str(path), "-o", str(tmp_path / "out")], out=io.StringIO(), err=err) == code
    assert words in err.getvalue() and "Traceback" not in err.getvalue()
    assert not (tmp_path / "out").exists()


def test_output_sample_cap_is_bad_input() -> None:
    doc = task(moves=[{"ptp": {"to": {"joints_deg": [160, -80, 100, 0, 40, 0]}, "velocity_scale": 1e-3}}],
               limits={"velocity_scale": 1e-3}, output={"period": 0.0001})  # the smallest scales: 1e-6 in all
    with pytest.raises(TaskError, match="over the cap"):
        plan(parse_task(doc))


@pytest.mark.parametrize(("command", "given", "words"), [
    ("plan", "bogus", "--method: unknown value 'bogus'; valid: auto, wrist-joint, axis, null-space, exact"),
    ("plan", "exatc", "--method: unknown value 'exatc' (did you mean 'exact'?); valid: auto, "),
    ("batch", "exatc", "--method: unknown value 'exatc' (did you mean 'exact'?); valid: auto, "),
])
def test_an_unknown_method_option_names_the_option(tmp_path: Path, command: str, given: str, words: str) -> None:
    import yaml

    path = tmp_path / "task.yaml"
    path.write_text(yaml.safe_dump(task(moves=[{"ptp": {"to": {"joints_deg": [0, -80, 100, 0, 40, 0]}}}])))
    err = io.StringIO()
    assert main([command, str(path), "-o", str(tmp_path / "out"), "--method", given], out=io.StringIO(), err=err) == 2
    assert words in err.getvalue() and "singularity.method" not in err.getvalue()
    assert "Traceback" not in err.getvalue() and not (tmp_path / "out").exists()


def test_an_unknown_method_argument_names_the_argument() -> None:
    doc = task(moves=[{"ptp": {"to": {"joints_deg": [0, -80, 100, 0, 40, 0]}}}])
    with pytest.raises(TaskError, match=r"^method: unknown value 'exatc' \(did you mean 'exact'\?\)") as info:
        plan(parse_task(doc), method="exatc")
    assert info.value.field == "method" and info.value.exit_code == 2
