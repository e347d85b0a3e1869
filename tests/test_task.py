"""Task YAML v1 validation: every error names its field; exit code 2."""

from __future__ import annotations

import io
import math
import textwrap
from dataclasses import replace
from pathlib import Path

import pytest

from singplan.cli import main
from singplan.entry import load_task, parse_task
from singplan.errors import TaskError
from singplan.kinematics.robot import VELOCITY_LIMIT_RAD_S
from singplan.task.schema import (
    ACCELERATION_RAD_S2,
    JOINT_DEG,
    MAX_FILE_BYTES,
    MAX_MOVES,
    PERIOD_S,
    SPEED_M_S,
    VELOCITY_SCALE,
)

MINIMAL_TASK = {"robot": "abb_irb2400", "start": {"joints_deg": [0, 10, 20, 0, 30, 0]},
                "moves": [{"lin": {"to": {"xyz": [1.0, 0.2, 0.8]}}}]}
GOOD = (Path(__file__).parent / "data" / "good_task.yaml").read_text()  # every field set


def write(tmp_path: Path, text: str) -> Path:
    p = tmp_path / "task.yaml"
    p.write_text(textwrap.dedent(text))
    return p


def test_good_task_round_trips_through_its_mapping(tmp_path: Path) -> None:
    task = load_task(write(tmp_path, GOOD))
    assert task.robot == "abb_irb2400" and len(task.moves) == 3
    assert task.moves[1].kind == "circ" and task.moves[1].to.rpy_deg is None  # orientation held
    assert task.moves[2].velocity_scale == 0.5 and task.period_s == 0.002
    assert task.limits.acceleration_rad_s2 == (5, 5, 5, 10, 10, 10)
    assert task.singularity.zone.shoulder_mm == 10
    assert parse_task(task.to_mapping()) == task


@pytest.mark.parametrize(("snippet", "replacement", "field", "words"), [
    ("xyz: [1.0, 0.0, 1.0]", "xyz: [1.0, 0.0]", "moves[0].lin.to.xyz", "expected 3 numbers, got 2"),
    ("speed: 0.25", "sped: 0.25", "moves[0].lin.sped", "did you mean 'speed'"),
    ("speed: 0.25", "speed: -1", "moves[0].lin.speed", "must be positive"),
    ("speed: 0.25", "speed: .nan", "moves[0].lin.speed", "finite"),
    ("method: exact", "method: teleport", "singularity.method", "valid: auto"),
    ("period: 0.002", "period: 0", "output.period", "positive"),
    ("velocity_scale: 0.8", "velocity_scale: 1.5", "limits.velocity_scale", "at most 1"),
    ("config: auto", "config: X Y Z", "moves[0].lin.config", "F U N"),
    ("start: {joints_deg: [0, 10, 20, 0, 30, 0]}", "start: {}", "start", "exactly one"),
    ("start: {joints_deg: [0, 10, 20, 0, 30, 0]}",
     "start: {joints_deg: [0, 10, 20, 0, 30, 0], pose: {xyz: [1, 0, 1], rpy_deg: [0, 0, 0]}}", "start", "both"),
    ("via: {xyz: [1.1, 0.1, 1.0]}, ", "", "moves[1].circ.via", "missing"),
    ("- ptp: {to: {joints_deg: [0, 0, 0, 0, 30, 0]}, velocity_scale: 0.5}", "- spline: {to: {xyz: [1, 1, 1]}}",
     "moves[2] kind", "valid: lin, circ, ptp"),
    ("robot: abb_irb2400", "robot: missing_arm.urdf", "robot", "does not exist"),
    ("robot: abb_irb2400", "robot: [1, 2]", "robot", "non-empty string"),
])
def test_bad_field_is_named(tmp_path: Path, snippet: str, replacement: str, field: str, words: str) -> None:
    assert snippet in GOOD
    with pytest.raises(TaskError) as info:
        load_task(write(tmp_path, GOOD.replace(snippet, replacement, 1)))
    assert info.value.field == field
    assert words in str(info.value)
    assert info.value.exit_code == 2


def test_a_missing_urdf_is_named_as_written_and_by_the_absolute_path_looked_at(tmp_path: Path) -> None:
    """A relative path is taken from the task file's folder, not the working directory: say where."""
    with pytest.raises(TaskError) as info:
        load_task(write(tmp_path, GOOD.replace("robot: abb_irb2400", "robot: robots/nope.urdf", 1)))
    assert info.value.field == "robot" and info.value.exit_code == 2
    looked_at = tmp_path / "robots" / "nope.urdf"
    assert f"URDF file robots/nope.urdf does not exist (looked for {looked_at})" in str(info.value)
    with pytest.raises(TaskError) as info:  # given absolutely: named once
        load_task(write(tmp_path, GOOD.replace("robot: abb_irb2400", f"robot: {looked_at}", 1)))
    assert str(info.value).endswith(f"URDF file {looked_at} does not exist")


@pytest.mark.parametrize(("text", "words"), [
    ("", "the task file is empty; it needs at least robot, start and moves"),
    ("- just\n- a list\n", r"the task must be a mapping of keys \(robot, start, moves, \.\.\.\), got list"),
    ("robot: abb_irb2400\nmoves: [lin: {to: {xyz: [1, 2, 3]}\n", r"not valid YAML \(line 3, column 1\)"),
    ("a: &x [1, 2]\nb: *x\n", r"b: YAML aliases are not allowed in a task \(line 2\)"),
])
def test_unusable_documents(tmp_path: Path, text: str, words: str) -> None:
    with pytest.raises(TaskError, match=words):
        load_task(write(tmp_path, text))


@pytest.mark.parametrize(("text", "field", "words"), [
    ("robot: abb_irb2400\nstart: {joints_deg: [0, 10, 20, 0, 30, 0]}\nmoves:\n", "moves",
     "moves: empty (null); give a list of moves"),
    ("robot: abb_irb2400\nstart:\nmoves: [ptp: {to: {joints_deg: [0, 0, 0, 0, 30, 0]}}]\n", "start",
     "start: empty (null); give a mapping with joints_deg or pose"),
    ("robot:\nstart: {joints_deg: [0, 10, 20, 0, 30, 0]}\nmoves: [ptp: {to: {joints_deg: [0, 0, 0, 0, 30, 0]}}]\n",
     "robot", "robot: empty (null); give a bundled robot name"),
    ("robot: abb_irb2400\nstart: {joints_deg: [0, 10, 20, 0, 30, 0]}\nmoves: [lin: {to: }]\n", "moves[0].lin.to",
     "moves[0].lin.to: empty (null); give the target mapping"),
    ("robot: abb_irb2400\nstart: {joints_deg: [0, 10, 20, 0, 30, 0]}\n", "moves", "moves: missing (required)"),
])
def test_a_required_key_given_empty_is_not_called_missing(tmp_path: Path, text: str, field: str, words: str) -> None:
    with pytest.raises(TaskError) as info:
        load_task(write(tmp_path, text))
    assert info.value.field == field and str(info.value).startswith(words) and info.value.exit_code == 2


def test_empty_moves_from_the_command_line_is_bad_input(tmp_path: Path) -> None:
    err = io.StringIO()
    path = write(tmp_path, "robot: abb_irb2400\nstart: {joints_deg: [0, 10, 20, 0, 30, 0]}\nmoves:\n")
    assert main(["plan", str(path), "-o", str(tmp_path / "out")], out=io.StringIO(), err=err) == 2
    assert err.getvalue() == "singplan: error: moves: empty (null); give a list of moves\n"


def test_billion_laughs_is_refused_fast(tmp_path: Path) -> None:
    lines = ['a0: &a0 ["lol", "lol", "lol", "lol", "lol", "lol", "lol", "lol", "lol"]']
    lines += [f"a{i}: &a{i} [{', '.join(['*a' + str(i - 1)] * 9)}]" for i in range(1, 9)]
    with pytest.raises(TaskError, match=r"a1\[0\]: YAML aliases are not allowed in a task \(line 2\)") as info:
        load_task(write(tmp_path, "\n".join(lines) + "\n"))
    assert info.value.field == "a1[0]"


def test_too_many_moves_is_bad_input() -> None:
    # the mapping a YAML file of 10 001 PTPs parses to, built directly: the cap is the schema's, and
    # parsing that file took seconds (the file size and YAML node caps are tested on their own)
    move = {"ptp": {"to": {"joints_deg": [0, 0, 0, 0, 30, 0]}}}
    doc = {"robot": "abb_irb2400", "start": {"joints_deg": [0, 0, 0, 0, 30, 0]}, "moves": [move] * (MAX_MOVES + 1)}
    with pytest.raises(TaskError, match=f"{MAX_MOVES + 1} moves is over the cap of {MAX_MOVES}") as info:
        parse_task(doc)
    assert info.value.field == "moves"
    assert len(parse_task({**doc, "moves": [move] * MAX_MOVES}).moves) == MAX_MOVES  # the cap itself is allowed


def test_missing_file_and_binary_file(tmp_path: Path) -> None:
    with pytest.raises(TaskError, match="no such task file"):
        load_task(tmp_path / "nope.yaml")
    bad = tmp_path / "bin.yaml"
    bad.write_bytes(b"\xff\xfe\x00robot")
    with pytest.raises(TaskError):
        load_task(bad)


def test_a_key_given_twice_is_bad_input_naming_the_key_and_lines(tmp_path: Path) -> None:
    """The last value used to win silently: speed 0.25 then 9.5 planned at 9.5 m/s."""
    text = GOOD.replace("speed: 0.25,", "speed: 0.25, speed: 9.5,")
    with pytest.raises(TaskError) as info:
        load_task(write(tmp_path, text))
    assert info.value.field == "moves[0].lin.speed"
    assert "twice" in str(info.value) and "lines 5 and 5" in str(info.value)  # the LIN is line 5 of the file


@pytest.mark.parametrize("style", ["flow", "block", "mapping"])
def test_nesting_is_refused_before_pyyaml_recurses(tmp_path: Path, style: str) -> None:
    depth = 20_000
    if style == "flow":
        text = "robot: " + "[" * depth + "]" * depth
    elif style == "block":
        text = "robot:\n" + "".join(" " * (i + 1) + "- \n" for i in range(3000))
    else:
        text = "robot: " + "{a: " * depth + "1" + "}" * depth
    with pytest.raises(TaskError, match="deeper than 64") as info:
        load_task(write(tmp_path, text))
    assert info.value.field.startswith("robot[0]" if style != "mapping" else "robot.a.a")


def test_64_levels_are_allowed(tmp_path: Path) -> None:
    """The cap counts levels from the document's top mapping: 64 read, 65 refused."""
    inner = "[" * 61 + "]" * 61  # top mapping + limits mapping + 62 lists = 64 levels
    with pytest.raises(TaskError, match=r"limits.acceleration\[0\]: expected a number"):
        load_task(write(tmp_path, GOOD.replace("acceleration: [5, 5, 5, 10, 10, 10]", f"acceleration: [{inner}]")))
    with pytest.raises(TaskError, match="deeper than 64"):
        load_task(write(tmp_path, GOOD.replace("acceleration: [5, 5, 5, 10, 10, 10]", f"acceleration: [[{inner}]]")))


def test_exponent_floats_are_numbers(tmp_path: Path) -> None:
    """YAML 1.1 reads 1e-3 as a string; a task means the number (as YAML 1.2 and JSON do)."""
    text = GOOD.replace("speed: 0.25", "speed: 2.5e-1").replace("period: 0.002", "period: 2E-3")
    task = load_task(write(tmp_path, text))
    assert task.moves[0].speed_m_s == 0.25 and task.period_s == 0.002


@pytest.mark.parametrize(("snippet", "replacement", "field", "words"), [
    ("speed: 0.25", "speed: " + "9" * 400, "moves[0].lin.speed", "number too large"),
    ("speed: 0.25", "speed: 1" + "0" * 330, "moves[0].lin.speed", "number too large"),
    ("speed: 0.25", "speed: 1e-300", "moves[0].lin.speed", "at least 0.0001 m/s"),
    ("velocity_scale: 0.5", "velocity_scale: 1e-300", "moves[2].ptp.velocity_scale", "at least 0.001"),
    ("velocity_scale: 0.8", "velocity_scale: 1e-300", "limits.velocity_scale", "at least 0.001"),
    ("acceleration: [5, 5, 5, 10, 10, 10]", "acceleration: 1e-300", "limits.acceleration", "at least 0.01"),
    ("position_tolerance_mm: 0.01", "position_tolerance_mm: 1e-300", "singularity.position_tolerance_mm", "at least"),
    ("orientation_tolerance_deg: 2", "orientation_tolerance_deg: 1e-300", "singularity.orientation_tolerance_deg",
     "at least"),
    ("shoulder_mm: 10", "shoulder_mm: 1e-300", "singularity.zone.shoulder_mm", "at least"),
    ("tool: {xyz: [0, 0, 0.1]", "tool: {xyz: [0, 0, 11]", "tool.xyz[2]", "at most 10 m"),
    ("robot: abb_irb2400", "robot: " + "x" * 300, "robot", "over the cap"),
    ("robot: abb_irb2400", 'robot: "abb\\tirb"', "robot", "U+0009"),
    ("robot: abb_irb2400", "robot: arm.xml", "robot", "must end in .urdf"),
    ("tool: {xyz: [0, 0, 0.1], rpy_deg: [0, 0, 0]}", "tool: []", "tool", "expected a mapping"),
    ("zone: {wrist_deg: 4, shoulder_mm: 10, elbow_deg: 3}", "zone: 0", "singularity.zone", "expected a mapping"),
    ("output: {period: 0.002}", "output: false", "output", "expected a mapping"),
    ("speed: 0.25,", "<<: {speed: 0.3},", "moves[0].lin.<<", "merge keys"),
    ("speed: 0.25,", "? [a]\n      : 1,", "moves[0].lin", "plain name"),
])
def test_out_of_range_and_odd_values_are_named(tmp_path: Path, snippet: str, replacement: str, field: str,
                                               words: str) -> None:
    assert snippet in GOOD
    with pytest.raises(TaskError) as info:
        load_task(write(tmp_path, GOOD.replace(snippet, replacement, 1)))
    assert info.value.field == field, str(info.value)
    assert words in str(info.value) and len(str(info.value)) < 300


@pytest.mark.parametrize(("content", "words"), [
    (b"", "the task file is empty; it needs at least robot, start and moves"),
    (b"# only a comment\n", "the task file is empty"),
    (b"---\n...\n", "the task file is empty"),
    (b"robot: abb_irb2400\n---\nrobot: ur5\n", "more than one YAML document"),
    (b"just a scalar\n", "the task must be a mapping of keys .*, got str 'just a scalar'"),
    (b"robot: \xc3\x28\n", r"not a UTF-8 text file \(byte 7 is invalid\)"),
    pytest.param(b"x: [" + b",".join([b"0"] * 500_001) + b"]\n", "500000 YAML nodes",
                 marks=pytest.mark.slow),  # parsing half a million nodes up to the cap takes seconds
])
def test_unusable_files_name_the_file(tmp_path: Path, content: bytes, words: str) -> None:
    path = tmp_path / "odd.yaml"
    path.write_bytes(content)
    with pytest.raises(TaskError, match=words) as info:
        load_task(path)
    assert "odd.yaml" in str(info.value)


def test_directory_and_oversized_file(tmp_path: Path) -> None:
    with pytest.raises(TaskError, match="is a directory"):
        load_task(tmp_path)
    big = tmp_path / "big.yaml"
    big.write_bytes(b"#" * (MAX_FILE_BYTES + 1))
    cap = rf"big\.yaml: {MAX_FILE_BYTES + 1} bytes is over the {MAX_FILE_BYTES}-byte cap for a task file"
    with pytest.raises(TaskError, match=cap):
        load_task(big)


def test_every_positive_range_keeps_durations_finite() -> None:
    """The longest path (a LIN across the +-100 m cube) at the slowest speed, and the widest joint
    move at the smallest combined velocity scale, take a finite time in floats."""
    longest_m = math.dist((-100, -100, -100), (100, 100, 100))
    assert math.isfinite(longest_m / SPEED_M_S.low)
    slowest_joint_rad_s = VELOCITY_SCALE.low ** 2 * VELOCITY_LIMIT_RAD_S[0]
    assert math.isfinite(math.radians(2 * JOINT_DEG.high) / slowest_joint_rad_s / PERIOD_S.low)
    assert math.isfinite(math.sqrt(math.radians(2 * JOINT_DEG.high) / ACCELERATION_RAD_S2.low) / PERIOD_S.low)


@pytest.mark.parametrize(("changes", "field", "words"), [
    ({"acceleration_rad_s2": (0.0,)}, "limits.acceleration", "positive"),
    ({"acceleration_rad_s2": (5.0, 5.0, 5.0, 1e5, 5.0, 5.0)}, "limits.acceleration[3]", "at most 10000"),
    ({"jerk_rad_s3": (100.0, math.nan)}, "limits.jerk[1]", "finite"),
    ({"jerk_rad_s3": ("fast",)}, "limits.jerk", "expected a number"),
    ({"ptp_time_law": "cubic"}, "limits.ptp_time_law", "expected one of optimal, quintic"),
])
def test_limits_made_in_python_are_checked_when_made(changes: dict[str, object], field: str, words: str) -> None:
    """The record checks its own ranges (the one check, for parsed and Python-made limits alike)."""
    limits = parse_task(MINIMAL_TASK).limits
    with pytest.raises(TaskError, match=words) as info:
        replace(limits, **changes)
    assert info.value.field == field


def test_a_parsed_range_error_names_the_list_item() -> None:
    task = {**MINIMAL_TASK, "limits": {"jerk": [100, 100, -1, 100, 100, 100]}}
    with pytest.raises(TaskError, match="must be positive") as info:
        parse_task(task)
    assert info.value.field == "limits.jerk[2]"


def test_the_joint_speed_scale_of_the_task_and_of_each_move() -> None:
    """limits.velocity_scale for the trajectory and its LINs, times its own velocity_scale for a PTP."""
    task = parse_task({"robot": "abb_irb2400", "start": {"joints_deg": [0, 0, 0, 0, 30, 0]},
                       "limits": {"velocity_scale": 0.5},
                       "moves": [{"ptp": {"to": {"joints_deg": [10, 0, 0, 0, 30, 0]}, "velocity_scale": 0.4}},
                                 {"lin": {"to": {"xyz": [0.9, 0.1, 1.2], "rpy_deg": [0, 90, 0]}}}]})
    assert task.joint_speed_scale() == 0.5
    assert task.joint_speed_scale(task.moves[0]) == pytest.approx(0.2, rel=1e-15)
    assert task.joint_speed_scale(task.moves[1]) == 0.5
