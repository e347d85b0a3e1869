"""Task YAML v1 validation: every error names its field; exit code 2."""

from __future__ import annotations

import textwrap
from pathlib import Path

import pytest

from singplan.errors import TaskError
from singplan.task import MAX_MOVES, load_task, parse_task

GOOD = """
robot: abb_irb2400
tool: {xyz: [0, 0, 0.1], rpy_deg: [0, 0, 0]}
start: {joints_deg: [0, 10, 20, 0, 30, 0]}
moves:
  - lin: {to: {xyz: [1.0, 0.0, 1.0], rpy_deg: [180, 0, 0]}, speed: 0.25, config: auto}
  - circ: {via: {xyz: [1.1, 0.1, 1.0]}, to: {xyz: [1.0, 0.2, 1.0]}, speed: 0.1}
  - ptp: {to: {joints_deg: [0, 0, 0, 0, 30, 0]}, velocity_scale: 0.5}
singularity: {method: exact, orientation_tolerance_deg: 2, position_tolerance_mm: 0.01,
              zone: {wrist_deg: 4, shoulder_mm: 10, elbow_deg: 3}}
limits: {velocity_scale: 0.8, acceleration: [5, 5, 5, 10, 10, 10]}
output: {period: 0.002}
"""


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


@pytest.mark.parametrize(("text", "words"), [
    ("", "empty"),
    ("- just\n- a list\n", "mapping"),
    ("robot: abb_irb2400\nmoves: [lin: {to: {xyz: [1, 2, 3]}\n", "not valid YAML"),
    ("a: &x [1, 2]\nb: *x\n", "aliases"),
])
def test_unusable_documents(tmp_path: Path, text: str, words: str) -> None:
    with pytest.raises(TaskError, match=words):
        load_task(write(tmp_path, text))


def test_billion_laughs_is_refused_fast(tmp_path: Path) -> None:
    lines = ['a0: &a0 ["lol", "lol", "lol", "lol", "lol", "lol", "lol", "lol", "lol"]']
    lines += [f"a{i}: &a{i} [{', '.join(['*a' + str(i - 1)] * 9)}]" for i in range(1, 9)]
    with pytest.raises(TaskError, match="aliases"):
        load_task(write(tmp_path, "\n".join(lines) + "\n"))


def test_too_many_moves_is_bad_input(tmp_path: Path) -> None:
    moves = "\n".join("  - ptp: {to: {joints_deg: [0, 0, 0, 0, 30, 0]}}" for _ in range(MAX_MOVES + 1))
    text = f"robot: abb_irb2400\nstart: {{joints_deg: [0, 0, 0, 0, 30, 0]}}\nmoves:\n{moves}\n"
    with pytest.raises(TaskError, match="over the cap"):
        load_task(write(tmp_path, text))


def test_missing_file_and_binary_file(tmp_path: Path) -> None:
    with pytest.raises(TaskError, match="no such task file"):
        load_task(tmp_path / "nope.yaml")
    bad = tmp_path / "bin.yaml"
    bad.write_bytes(b"\xff\xfe\x00robot")
    with pytest.raises(TaskError):
        load_task(bad)
