"""Exports checked against each format's rules: a JSON schema of the ROS 2 message, a URScript
parser check, the degree CSV's header and values; the output-folder rules of DESIGN.md."""

from __future__ import annotations

import io
import json
import math
import re
from dataclasses import replace
from pathlib import Path
from typing import Any

import jsonschema
import numpy as np
import pytest
import yaml

from singplan.cli import main
from singplan.kinematics.vendor_config import convention_for
from singplan.outputs import exports
from singplan.outputs.choices import PROGRAM_FORMATS
from singplan.outputs.timeline import robot_of
from singplan.results.plan import plan
from singplan.results.trajectory import Trajectory, load, save
from singplan.task.load import load_task
from tests.conftest import SCENARIOS

# Written from the message definitions (ROS 2 common_interfaces / rcl_interfaces):
# trajectory_msgs/msg/JointTrajectory: std_msgs/Header header, string[] joint_names, JointTrajectoryPoint[] points
# trajectory_msgs/msg/JointTrajectoryPoint: float64[] positions, velocities, accelerations, effort;
#   builtin_interfaces/Duration time_from_start
# std_msgs/msg/Header: builtin_interfaces/Time stamp, string frame_id
# builtin_interfaces Time and Duration: int32 sec, uint32 nanosec (nanosec < 1e9: the rest below a second)
_INT32 = {"type": "integer", "minimum": -2**31, "maximum": 2**31 - 1}
_NANOSEC = {"type": "integer", "minimum": 0, "maximum": 999_999_999}
_TIME = {"type": "object", "properties": {"sec": _INT32, "nanosec": _NANOSEC}, "required": ["sec", "nanosec"],
         "additionalProperties": False}
_FLOAT64S = {"type": "array", "items": {"type": "number"}}
JOINT_TRAJECTORY_SCHEMA: dict[str, Any] = {
    "type": "object",
    "properties": {
        "header": {"type": "object", "properties": {"stamp": _TIME, "frame_id": {"type": "string"}},
                   "additionalProperties": False},
        "joint_names": {"type": "array", "items": {"type": "string"}},
        "points": {"type": "array", "items": {
            "type": "object",
            "properties": {"positions": _FLOAT64S, "velocities": _FLOAT64S, "accelerations": _FLOAT64S,
                           "effort": _FLOAT64S, "time_from_start": _TIME},
            "required": ["positions", "time_from_start"], "additionalProperties": False}},
    },
    "required": ["joint_names", "points"],
    "additionalProperties": False,
}


def check_joint_trajectory(msg: Any, traj: Trajectory) -> None:
    """The schema, plus what a schema cannot say: array lengths, increasing times, the values."""
    jsonschema.validate(msg, JOINT_TRAJECTORY_SCHEMA)
    n = len(msg["joint_names"])
    assert msg["joint_names"] == list(traj.joint_names)
    assert len(msg["points"]) == len(traj.t)
    times = []
    for p in msg["points"]:
        for key in ("positions", "velocities", "accelerations"):
            assert len(p[key]) == n, key
        assert len(p["effort"]) in (0, n)
        times.append(p["time_from_start"]["sec"] + p["time_from_start"]["nanosec"] * 1e-9)
    assert np.all(np.diff(times) > 0)
    np.testing.assert_allclose(times, traj.t, atol=1e-9, rtol=0)
    np.testing.assert_array_equal([p["positions"] for p in msg["points"]], traj.q)  # repr floats round-trip
    np.testing.assert_array_equal([p["velocities"] for p in msg["points"]], traj.qd)
    np.testing.assert_array_equal([p["accelerations"] for p in msg["points"]], traj.qdd)


_NUMBER = r"-?\d+(?:\.\d+)?"  # URScript literals as written: fixed point, no exponent
_SERVOJ = re.compile(rf"  servoj\(\[([^\]]*)\], 0, 0, t=({_NUMBER}), lookahead_time=({_NUMBER}), gain=({_NUMBER})\)")
_MOVEJ = re.compile(rf"  movej\(\[([^\]]*)\], a=({_NUMBER}), v=({_NUMBER})\)")


def _six(text: str) -> list[float]:
    values = [float(v) for v in text.split(",")]
    assert len(values) == 6 and all(math.isfinite(v) for v in values), text
    return values


def parse_urscript(text: str, step_s: float = 0.002) -> tuple[list[float], np.ndarray, float]:
    """Check the program's structure; return the movej target, the servoj targets (M, 6) and the servoj t."""
    lines = text.splitlines()
    opened = sum(1 for line in lines if re.match(r"\s*def \w+\(\):$", line))
    closed = sum(1 for line in lines if line.strip() == "end")
    assert lines[0] == "def singplan_move():" and lines[-1] == "end" and opened == closed == 1
    body = [line for line in lines[1:-1] if not line.strip().startswith("#")]
    movej = _MOVEJ.fullmatch(body[0])
    assert movej is not None, body[0]
    assert body[-1] == "  stopj(2.0)"
    targets, periods = [], set()
    for line in body[1:-1]:
        m = _SERVOJ.fullmatch(line)
        assert m is not None, line
        targets.append(_six(m.group(1)))
        periods.add(float(m.group(2)))
        assert 0.03 <= float(m.group(3)) <= 0.2 and 100 <= float(m.group(4)) <= 2000
    assert len(periods) == 1
    period = periods.pop()
    assert abs(period / step_s - round(period / step_s)) < 1e-9 and round(period / step_s) >= 1
    return _six(movej.group(1)), np.array(targets), period


def check_csv_deg(text: str, traj: Trajectory) -> None:
    lines = text.splitlines()
    names = traj.joint_names
    assert lines[0].split(",") == ["t [s]", *(f"{n} [deg]" for n in names), *(f"{n} [deg/s]" for n in names)]
    rows = np.array([[float(v) for v in line.split(",")] for line in lines[1:]])
    assert rows.shape == (len(traj.t), 1 + 2 * len(names))
    np.testing.assert_allclose(rows[:, 0], traj.t, atol=1e-12)
    np.testing.assert_allclose(rows[:, 1:1 + len(names)], np.degrees(traj.q), atol=1e-9)
    np.testing.assert_allclose(rows[:, 1 + len(names):], np.degrees(traj.qd), atol=1e-9)


def check_all_formats(folder: Path) -> None:
    """Every format writes; a controller program only for the robot's own vendor (tests/test_programs.py
    reads those back), exit 2 for the others."""
    traj = load(folder)
    convention = convention_for(robot_of(traj))
    own = {"kuka": "krl", "abb": "rapid", "fanuc": "fanuc-ls"}.get(convention.vendor if convention else "")
    for fmt in exports.FORMATS:
        expected = (0 if fmt == own else 2) if fmt in PROGRAM_FORMATS else 0
        assert main(["export", str(folder), "--format", fmt]) == expected, fmt
    text = {fmt: (folder / exports.DEFAULT_FILE_NAMES[fmt]).read_text() for fmt in exports.FORMATS
            if fmt not in PROGRAM_FORMATS}
    check_joint_trajectory(yaml.safe_load(text["ros2"]), traj)
    check_joint_trajectory(json.loads(text["ros2-json"]), traj)
    movej, servoj, period = parse_urscript(text["urscript"])
    step = exports.servo_period(traj.period, 0.002)
    assert period == pytest.approx(step, abs=1e-12)
    expected = traj.q if step == traj.period else exports.resample(traj, step)[0]
    np.testing.assert_allclose(servoj, expected, atol=1e-12, rtol=0)  # 12 decimals written
    np.testing.assert_allclose(movej, traj.q[0], atol=1e-12, rtol=0)
    check_csv_deg(text["csv-deg"], traj)


def test_all_formats_of_a_planned_folder(planned_kuka: Path) -> None:
    check_all_formats(planned_kuka)


def _planning_scenarios() -> list[str]:
    if SCENARIOS is None:
        return []
    expect = yaml.safe_load((SCENARIOS / "expect.yaml").read_text())
    return sorted(name for name, spec in expect.items() if isinstance(spec, dict) and spec.get("exit") == 0)


_FAST = {"ur5__wrist_near_lin", "fanuc_lrmate200id__wrist_near_lin"}
_SLOW = {"abb_irb2400__program"}  # a 4.6 s program: seconds to plan and write in every format


def _export_mark(name: str) -> tuple[pytest.MarkDecorator, ...]:
    return () if name in _FAST else (pytest.mark.slow,) if name in _SLOW else (pytest.mark.soak,)


@pytest.mark.parametrize("name", [pytest.param(n, marks=_export_mark(n)) for n in _planning_scenarios()])
def test_every_public_scenario_exports(name: str, tmp_path: Path) -> None:
    assert SCENARIOS is not None
    folder = save(plan(load_task(SCENARIOS / f"{name}.yaml")), tmp_path / name)
    check_all_formats(folder)


def test_yaml_floats_stay_floats(rng: np.random.Generator) -> None:
    for x in (1e-05, -3e-300, 1e22, 0.0, -0.0, 123.5, 5e-324, -1e16, 2.5e-07):
        text = exports._yaml_float(x)
        parsed = yaml.safe_load(text)
        assert isinstance(parsed, float) and parsed == x, text
    row = (rng.standard_normal(600) * 10.0 ** rng.integers(-320, 300, 600)).tolist()
    parsed_row = yaml.safe_load(exports._yaml_list(row))
    assert all(isinstance(v, float) for v in parsed_row) and parsed_row == row
    assert json.loads(exports._json_list(row)) == row


def test_durations_split_into_sec_and_nanosec() -> None:
    assert exports._duration(0.0) == (0, 0)
    assert exports._duration(1.999999999999) == (2, 0)  # rounding never yields nanosec == 1e9
    assert exports._duration(12.004) == (12, 4_000_000)


def test_servo_period_and_resampling(planned_kuka: Path) -> None:
    traj = load(planned_kuka)
    assert exports.servo_period(0.004, 0.002) == 0.004
    assert exports.servo_period(0.004, 0.008) == 0.008
    assert exports.servo_period(0.003, 0.002) == pytest.approx(0.004)  # 1.5 steps -> 2
    assert exports.servo_period(0.0005, 0.002) == 0.002  # at least one step
    q_same, _t_same = exports.resample(traj, traj.period)
    np.testing.assert_allclose(q_same, traj.q, atol=1e-12)  # Hermite through the samples themselves
    q8, t8 = exports.resample(traj, 0.008)
    assert t8[-1] == pytest.approx(traj.t[-1]) and np.all(np.diff(t8) <= 0.008 + 1e-12)
    np.testing.assert_allclose(q8[-1], traj.q[-1], atol=1e-12)
    np.testing.assert_allclose(q8, np.array([np.interp(t8, traj.t, traj.q[:, j]) for j in range(6)]).T, atol=1e-4)


def test_cb3_program_is_resampled(planned_kuka: Path) -> None:
    traj = load(planned_kuka)
    text = exports.to_urscript(traj, exports.UrScriptOptions(controller="cb3"))
    _, servoj, period = parse_urscript(text, step_s=0.008)
    assert period == pytest.approx(0.008) and "resampled from the planned period 0.004 s" in text
    assert len(servoj) == len(exports.resample(traj, 0.008)[0])


@pytest.mark.parametrize(("option", "value", "field"), [
    ("--lookahead-time", "0.01", "--lookahead-time: expected"),
    ("--lookahead-time", "0.5", "--lookahead-time: expected"),
    ("--gain", "50", "--gain: expected"), ("--gain", "3000", "--gain: expected")])
def test_servoj_parameters_out_of_range(planned_kuka: Path, option: str, value: str, field: str) -> None:
    err = io.StringIO()
    assert main(["export", str(planned_kuka), "--format", "urscript", option, value,
                 "-o", str(planned_kuka / "x.script")], err=err) == 2
    assert field in err.getvalue() and not (planned_kuka / "x.script").exists()


def test_non_ur_robot_gets_a_warning(planned_kuka: Path) -> None:
    err = io.StringIO()
    assert main(["export", str(planned_kuka), "--format", "urscript", "-o", str(planned_kuka / "k.script")],
                err=err) == 0
    assert "not a Universal Robots arm" in err.getvalue()
    assert "# WARNING: kuka_kr6_r900_2 is not a Universal Robots arm" in (planned_kuka / "k.script").read_text()


def test_unknown_format_lists_the_valid_ones(planned_kuka: Path) -> None:
    err = io.StringIO()
    assert main(["export", str(planned_kuka), "--format", "kuka-krl"], err=err) == 2
    assert "ros2, ros2-json, urscript, csv-deg, krl, rapid, fanuc-ls" in err.getvalue()


def test_output_path_rules(planned_kuka: Path, tmp_path: Path) -> None:
    blocker = tmp_path / "a_file"
    blocker.write_text("keep")
    err = io.StringIO()
    assert main(["export", str(planned_kuka), "--format", "ros2", "-o", str(blocker / "x.yaml")], err=err) == 2
    assert str(blocker) in err.getvalue() and blocker.read_text() == "keep"
    (tmp_path / "dir.yaml").mkdir()
    assert main(["export", str(planned_kuka), "--format", "ros2", "-o", str(tmp_path / "dir.yaml")]) == 2
    before = {p.name: p.stat().st_mtime_ns for p in planned_kuka.iterdir()}
    assert main(["export", str(planned_kuka), "--format", "ros2-json"]) == 0
    after = {p.name: p.stat().st_mtime_ns for p in planned_kuka.iterdir()}
    assert set(after) - set(before) <= {"trajectory.ros2.json"}
    assert all(after[k] == v for k, v in before.items() if k != "trajectory.ros2.json")
    assert not [p for p in planned_kuka.iterdir() if p.name.endswith(".singplan-tmp")]


def _broken_copy(src: Path, dst: Path, edit: Any) -> Path:
    doc = json.loads((src / "trajectory.json").read_text())
    edit(doc)
    dst.mkdir()
    (dst / "trajectory.json").write_text(json.dumps(doc))
    return dst


@pytest.mark.parametrize(("edit", "field"), [
    (lambda d: d["q"][3].__setitem__(2, float("nan")), "q[3][2]"),
    (lambda d: d["qd"].pop(), "qd: expected"),
    (lambda d: d.__setitem__("period", -1), "period"),
    (lambda d: d.__setitem__("joint_names", ["a", "a", "b", "c", "d", "e"]), "joint_names"),
    (lambda d: d.__setitem__("t", d["t"][::-1]), "t[1]")])
def test_bad_trajectory_is_bad_input(planned_kuka: Path, tmp_path: Path, edit: Any, field: str) -> None:
    folder = _broken_copy(planned_kuka, tmp_path / "broken", edit)
    for fmt in exports.FORMATS:
        err = io.StringIO()
        assert main(["export", str(folder), "--format", fmt], err=err) == 2, fmt
        assert field in err.getvalue(), err.getvalue()
    assert sorted(p.name for p in folder.iterdir()) == ["trajectory.json"]  # nothing written


def test_urscript_needs_uniform_samples(planned_kuka: Path, tmp_path: Path) -> None:
    folder = _broken_copy(planned_kuka, tmp_path / "gap", lambda d: d.__setitem__("t", [*d["t"][:5], *[
        v + 0.001 for v in d["t"][5:]]]))
    err = io.StringIO()
    assert main(["export", str(folder), "--format", "urscript"], err=err) == 2
    assert "t[5]: servoj streams samples uniform" in err.getvalue()
    assert main(["export", str(folder), "--format", "ros2"]) == 0  # a message carries any increasing times


def test_export_of_a_trajectory_file_goes_next_to_it(planned_kuka: Path) -> None:
    assert main(["export", str(planned_kuka / "trajectory.json"), "--format", "csv-deg"]) == 0
    assert (planned_kuka / "trajectory_deg.csv").is_file()


def test_missing_folder_is_bad_input(tmp_path: Path) -> None:
    err = io.StringIO()
    assert main(["export", str(tmp_path / "nope"), "--format", "csv-deg"], err=err) == 2
    assert "nope" in err.getvalue()


def test_python_functions_equal_the_files(planned_kuka: Path) -> None:
    traj = load(planned_kuka)
    out = planned_kuka / "py.yaml"
    exports.export(traj, "ros2", out)
    assert out.read_text() == exports.to_ros2_yaml(traj)
    assert json.loads(exports.to_ros2_json(traj)) == yaml.safe_load(exports.to_ros2_yaml(traj))
    short = replace(traj, t=traj.t[:1], q=traj.q[:1], qd=traj.qd[:1], qdd=traj.qdd[:1])
    _, servoj, _ = parse_urscript(exports.to_urscript(short))
    assert len(servoj) == 1


def test_the_format_checks_catch_broken_output(planned_kuka: Path) -> None:
    """The checks above can fail: each mutation of a good export is caught."""
    traj = load(planned_kuka)
    good = json.loads(exports.to_ros2_json(traj))
    mutations = [lambda m: m["points"][1]["time_from_start"].__setitem__("nanosec", 10**9),
                 lambda m: m["points"][1]["time_from_start"].__setitem__("sec", 2**31),
                 lambda m: m["points"][2].__setitem__("positions", m["points"][2]["positions"][:5]),
                 lambda m: m["points"][2]["velocities"].__setitem__(0, "0.1"),
                 lambda m: m["points"][3].__setitem__("time_from_start", m["points"][2]["time_from_start"]),
                 lambda m: m.__setitem__("extra", 1)]
    for mutate in mutations:
        msg = json.loads(json.dumps(good))
        mutate(msg)
        with pytest.raises((AssertionError, jsonschema.ValidationError)):
            check_joint_trajectory(msg, traj)
    script = exports.to_urscript(traj)
    first_servoj = script.index("  servoj(")
    broken = [script.replace("\nend\n", "\n"), script.replace("servoj([", "servoj([0.1, ", 1),
              script[:first_servoj] + script[first_servoj:].replace("0, 0, t=", "0, 0, t=nan", 1),
              script.replace("gain=300", "gain=3000", 1), script.replace("  stopj(2.0)\n", "")]
    for text in broken:
        with pytest.raises((AssertionError, ValueError)):
            parse_urscript(text)


def test_a_urdf_whose_joints_changed_since_the_plan_is_refused_by_every_output(planned_kuka: Path,
                                                                                tmp_path: Path) -> None:
    """One check (``robot_of``) for the exports, the replay and the programs, one message naming the
    field, the URDF and both joint lists."""
    from singplan.errors import InputError
    from singplan.outputs.programs import build_program
    from singplan.outputs.viewer import replay

    traj = load(planned_kuka)
    renamed = replace(traj, joint_names=tuple(f"old_{n}" for n in traj.joint_names))
    wording = (rf"joint_names: the trajectory's joints \['old_{traj.joint_names[0]}', .*\] are not those of "
               rf".*\.urdf to {traj.tip} \['{traj.joint_names[0]}', .*\]; the URDF changed since the plan\?")
    for output in (lambda: robot_of(renamed), lambda: exports.to_csv_deg(renamed, vendor_config=True),
                   lambda: build_program(renamed, "krl"), lambda: replay(renamed, html=tmp_path / "r.html")):
        with pytest.raises(InputError, match=wording):
            output()
    assert not (tmp_path / "r.html").exists()


def test_a_urdf_edited_after_its_robot_was_loaded_is_named_by_the_replay_scene(tmp_path: Path) -> None:
    """The replay scene reads the URDF again for its visuals: a joint renamed in the file since the robot
    was loaded is named, not an index error."""
    from singplan.errors import InputError
    from singplan.kinematics.robot import bundled_robots, load_robot
    from singplan.outputs.scene import RobotScene

    urdf = tmp_path / "arm.urdf"
    urdf.write_text(bundled_robots()["kuka_kr6_r900_2"].urdf_path().read_text())
    robot = load_robot(str(urdf))
    text = urdf.read_text()
    urdf.write_text(text.replace(f'"{robot.joint_names[2]}"', '"renamed_joint"'))
    with pytest.raises(InputError, match=rf"joint_names: '{robot.joint_names[2]}' is not a joint of .*arm\.urdf "
                                         r"\(the URDF changed since the plan\?\)"):
        RobotScene.of(robot)


def test_vendor_config_csv_of_a_bundled_arm_whose_urdf_is_gone(planned_kuka: Path) -> None:
    """The degree CSV's vendor configuration reads the robot as every output does (``robot_of``): a
    bundled arm planned from a URDF that is not on this machine is the bundled arm."""
    traj = load(planned_kuka)
    moved = replace(traj, urdf=str(planned_kuka / "gone" / "kuka_kr6_r900_2.urdf"))
    assert exports.to_csv_deg(moved, vendor_config=True) == exports.to_csv_deg(traj, vendor_config=True)
    assert exports.to_csv_deg(moved, vendor_config=True).splitlines()[1].endswith(",S 6 T 50")  # KUKA Status/Turn
