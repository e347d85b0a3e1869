"""Hostile inputs through the CLI: every one exits 2 naming the field or file, with no traceback.

One case per kind of bad input of issue 10 ("Tracebacks", "Silently wrong input") and of the
input contract (DESIGN.md "Task YAML", "Robots"). Every case fails before planning, so the
battery is fast; none may write the output folder.
"""

from __future__ import annotations

import os
from collections.abc import Callable
from pathlib import Path
from typing import NamedTuple

import pytest

from singplan.kinematics.robot import MAX_URDF_BYTES, robots_dir
from singplan.task.schema import MAX_FILE_BYTES
from tests.cli_helpers import assert_no_traceback, run_cli

GOOD = (Path(__file__).parent / "data" / "good_task.yaml").read_text()  # every field set
URDF = (robots_dir() / "abb_irb2400.urdf").read_text()
JOINT_5_LIMIT = 'velocity="6.283185307179586" lower="-2.0943951023931953" upper="2.0943951023931953"'


def edit(old: str, new: str) -> str:
    assert old in GOOD, old
    return GOOD.replace(old, new, 1)


def urdf_edit(old: str, new: str) -> str:
    assert old in URDF, old
    return URDF.replace(old, new, 1)


def nested_flow(depth: int) -> str:
    return "[" * depth + "]" * depth


def nested_block(depth: int) -> str:
    return "\n".join(" " * i + f"k{i}:" for i in range(depth)) + " 1"


class Case(NamedTuple):
    """A task file (text, or bytes) and optionally a URDF next to it named robot.urdf."""

    task: str | bytes
    words: tuple[str, ...]  # each must appear in the error message
    urdf: str | None = None
    check_too: bool = False  # also run `singplan check`


WITH_URDF = edit("robot: abb_irb2400", "robot: robot.urdf")

CASES: dict[str, Case] = {
    # YAML structure
    "duplicate key in a move": Case(edit("speed: 0.25,", "speed: 0.25, speed: 9.5,"),
                                    ("moves[0].lin.speed", "twice"), check_too=True),
    "duplicate top-level key": Case(GOOD + "robot: kuka_kr6_r900_2\n", ("robot", "twice", "lines 1 and 12")),
    "duplicate key in block style": Case(edit("output: {period: 0.002}", "output:\n  period: 0.002\n  period: 0.004"),
                                         ("output.period", "twice")),
    "nesting 3000 deep, flow": Case(f"robot: {nested_flow(3000)}\n", ("robot[0]", "deeper than 64"), check_too=True),
    "nesting 3000 deep, block": Case(nested_block(3000) + "\n", ("k0.k1", "deeper than 64")),
    "nesting 65 deep": Case(edit("acceleration: [5, 5, 5, 10, 10, 10]", f"acceleration: {nested_flow(64)}"),
                            ("limits.acceleration", "deeper than 64")),
    "alias": Case(edit("output: {period: 0.002}", "output: {period: &p 0.002}\nx: *p"), ("x", "aliases")),
    "billion laughs": Case("a: &a [1, 1, 1, 1, 1, 1, 1, 1, 1]\nb: &b [*a, *a, *a, *a, *a, *a, *a, *a, *a]\n",
                           ("b[0]", "aliases")),
    "merge key": Case(edit("speed: 0.25,", "<<: {speed: 0.3},"), ("moves[0].lin.<<", "merge")),
    "two documents": Case(GOOD + "---\n" + GOOD, ("task.yaml", "more than one YAML document")),
    "document is a list": Case("- robot: abb_irb2400\n", ("task.yaml", "mapping")),
    "document is a scalar": Case("abb_irb2400\n", ("task.yaml", "mapping")),
    "empty file": Case("", ("task.yaml", "empty")),
    "comments only": Case("# nothing here\n\n", ("task.yaml", "empty")),
    "not UTF-8": Case(b"robot: abb_irb2400\ntip: \xff\xfe\n", ("task.yaml", "UTF-8")),
    "syntax error": Case(edit("moves:", "moves: [\n"), ("task.yaml", "not valid YAML", "line")),
    "key that is a list": Case(edit("speed: 0.25,", "? [a, b] : 1,"), ("moves[0].lin", "plain name")),
    "20 000-character value": Case(edit("robot: abb_irb2400", "robot: " + "a" * 20_000), ("robot", "characters")),
    "over 500 000 YAML nodes": Case("x: [" + ",".join(["0"] * 500_001) + "]\n", ("task.yaml", "YAML nodes")),
    # numbers
    "400-digit integer": Case(edit("speed: 0.25", "speed: " + "9" * 400), ("moves[0].lin.speed", "too large"),
                              check_too=True),
    "5000-digit integer": Case(edit("period: 0.002", "period: " + "7" * 5000), ("output.period", "too large")),
    "350-digit integer": Case(edit("xyz: [1.0, 0.0, 1.0]", f"xyz: [1{'0' * 350}, 0.0, 1.0]"),
                              ("moves[0].lin.to.xyz[0]", "too large")),
    "speed 1e-300": Case(edit("speed: 0.25", "speed: 1e-300"), ("moves[0].lin.speed", "at least"), check_too=True),
    "ptp velocity_scale 1e-300": Case(edit("velocity_scale: 0.5", "velocity_scale: 1e-300"),
                                      ("moves[2].ptp.velocity_scale", "at least")),
    "limits.velocity_scale 1e-300": Case(edit("velocity_scale: 0.8", "velocity_scale: 1.0e-300"),
                                         ("limits.velocity_scale", "at least")),
    "acceleration 1e-300": Case(edit("acceleration: [5, 5, 5, 10, 10, 10]", "acceleration: 1e-300"),
                                ("limits.acceleration", "at least")),
    "acceleration 1e400 (inf)": Case(edit("[5, 5, 5, 10, 10, 10]", "[5, 5, 5, 10, 1e400, 10]"),
                                     ("limits.acceleration[4]", "finite")),
    "position tolerance 1e-300": Case(edit("position_tolerance_mm: 0.01", "position_tolerance_mm: 1e-300"),
                                      ("singularity.position_tolerance_mm", "at least")),
    "orientation tolerance 0": Case(edit("orientation_tolerance_deg: 2", "orientation_tolerance_deg: 0"),
                                    ("singularity.orientation_tolerance_deg", "positive")),
    "negative zone": Case(edit("wrist_deg: 4", "wrist_deg: -4"), ("singularity.zone.wrist_deg", "positive")),
    "period 1e-300": Case(edit("period: 0.002", "period: 1e-300"), ("output.period", "at least")),
    "NaN speed": Case(edit("speed: 0.1", "speed: .nan"), ("moves[1].circ.speed", "finite")),
    "infinite coordinate": Case(edit("via: {xyz: [1.1, 0.1, 1.0]}", "via: {xyz: [1.1, -.inf, 1.0]}"),
                                ("moves[1].circ.via.xyz[1]", "finite")),
    "speed over 10 m/s": Case(edit("speed: 0.25", "speed: 11"), ("moves[0].lin.speed", "at most 10")),
    "boolean as a number": Case(edit("speed: 0.25", "speed: true"), ("moves[0].lin.speed", "expected a number")),
    "string as a number": Case(edit("period: 0.002", "period: fast"), ("output.period", "expected a number")),
    "date as a number": Case(edit("speed: 0.25", "speed: 2024-01-01"), ("moves[0].lin.speed", "expected a number")),
    "joint value 1e9 deg": Case(edit("[0, 10, 20, 0, 30, 0]", "[0, 10, 1e9, 0, 30, 0]"),
                                ("start.joints_deg[2]", "at most")),
    # list lengths
    "xyz with 2 numbers": Case(edit("xyz: [1.0, 0.0, 1.0]", "xyz: [1.0, 0.0]"), ("moves[0].lin.to.xyz", "got 2")),
    "start joints 5 for a 6-joint arm": Case(edit("[0, 10, 20, 0, 30, 0]", "[0, 10, 20, 0, 30]"),
                                             ("start.joints_deg", "expected 6")),
    "ptp joints 7 for a 6-joint arm": Case(edit("[0, 0, 0, 0, 30, 0]", "[0, 0, 0, 0, 30, 0, 0]"),
                                           ("moves[2].ptp.to.joints_deg", "expected 6")),
    "acceleration with 4 numbers": Case(edit("[5, 5, 5, 10, 10, 10]", "[5, 5, 5, 10]"),
                                        ("limits.acceleration", "expected 1 or 6")),
    "100 joint values": Case(edit("[0, 10, 20, 0, 30, 0]", str([0] * 100)), ("start.joints_deg", "100 joint values")),
    "misspelt top-level key": Case(edit("moves:\n", "moves: []\nx_moves:\n"), ("x_moves", "unknown key")),
    "no moves": Case("robot: abb_irb2400\nstart: {joints_deg: [0, 10, 20, 0, 30, 0]}\nmoves: []\n",
                     ("moves", "empty")),
    "move with two kinds": Case(edit("  - ptp:", "  - lin: {to: {xyz: [1, 0, 1]}}\n    ptp:"),
                                ("moves[2]", "only key")),
    # names, keys, choices
    "robot name 5000 characters": Case(edit("robot: abb_irb2400", "robot: " + "r" * 5000),
                                       ("robot", "over the cap")),
    "robot name with a control character": Case(edit("robot: abb_irb2400", 'robot: "abb\\x07irb"'),
                                                ("robot", "control character U+0007")),
    "tip with a NUL": Case(edit("robot: abb_irb2400", 'robot: abb_irb2400\ntip: "tool\\0"'),
                           ("tip", "control character U+0000")),
    "tip 300 characters": Case(edit("robot: abb_irb2400", "robot: abb_irb2400\ntip: " + "t" * 300),
                               ("tip", "over the cap")),
    "unknown tip frame": Case(edit("robot: abb_irb2400", "robot: abb_irb2400\ntip: flange_x"),
                              ("tip frame", "flange_x")),
    "unknown robot": Case(edit("robot: abb_irb2400", "robot: abb_irb9999"), ("robot", "abb_irb9999")),
    "unknown method": Case(edit("method: exact", "method: teleport"), ("singularity.method", "teleport")),
    "unknown configuration": Case(edit("config: auto", "config: X Y Z"), ("moves[0].lin.config", "F U N")),
    "unknown key": Case(edit("speed: 0.25", "sped: 0.25"), ("moves[0].lin.sped", "did you mean 'speed'")),
    "key of 500 characters": Case(edit("speed: 0.25,", "k" * 500 + ": 1,"), ("moves[0].lin.'kkkk", "over the cap")),
    "hexadecimal key of 4000 digits": Case(edit("speed: 0.25,", "0x" + "f" * 4000 + ": 1,"),
                                           ("moves[0].lin.'0xfff", "over the cap")),
    "hexadecimal number of 300 digits": Case(edit("speed: 0.25", "speed: 0x" + "f" * 300),
                                             ("moves[0].lin.speed", "number too large")),
    "mapping given as a number": Case(edit("tool: {xyz: [0, 0, 0.1], rpy_deg: [0, 0, 0]}", "tool: 0"),
                                      ("tool", "expected a mapping")),
    "mapping given as an empty list": Case(edit("output: {period: 0.002}", "output: []"),
                                           ("output", "expected a mapping")),
    # robot files
    "robot path not ending in .urdf": Case(edit("robot: abb_irb2400", "robot: arm.xml"), ("robot", ".urdf")),
    "robot directory named x.urdf": Case(edit("robot: abb_irb2400", "robot: folder.urdf"),
                                         ("folder.urdf", "directory")),
    "missing URDF": Case(edit("robot: abb_irb2400", "robot: missing.urdf"), ("missing.urdf", "does not exist")),
    "URDF zero velocity limit": Case(WITH_URDF, ("robot.urdf", "joint_5", "no velocity limit"),
                                     urdf_edit(JOINT_5_LIMIT, JOINT_5_LIMIT.replace("6.283185307179586", "0")),
                                     check_too=True),
    "URDF velocity limit 1e-300": Case(WITH_URDF, ("robot.urdf", "joint_5", "velocity limit"),
                                       urdf_edit(JOINT_5_LIMIT, JOINT_5_LIMIT.replace("6.283185307179586", "1e-300"))),
    "URDF NaN velocity limit": Case(WITH_URDF, ("robot.urdf", "joint_5", "nan"),
                                    urdf_edit(JOINT_5_LIMIT, JOINT_5_LIMIT.replace("6.283185307179586", "nan"))),
    "URDF lower above upper": Case(WITH_URDF, ("robot.urdf", "joint_5", "lower < upper"),
                                   urdf_edit(JOINT_5_LIMIT, 'velocity="6.3" lower="2" upper="-2"')),
    "URDF limits of 10 turns": Case(WITH_URDF, ("robot.urdf", "joint_5", "4 turns"),
                                    urdf_edit(JOINT_5_LIMIT, 'velocity="6.3" lower="-31.5" upper="31.5"')),
    "URDF with 4 joints": Case(WITH_URDF, ("robot.urdf", "4 revolute joints from base_link to tool0",
                                           "singplan plans arms with 5, 6 or 7"),
                               urdf_edit('<joint name="joint_6" type="revolute">',
                                         '<joint name="joint_6" type="fixed">').replace(
                                   '<joint name="joint_5" type="revolute">', '<joint name="joint_5" type="fixed">', 1),
                               check_too=True),
    "URDF prismatic joint": Case(WITH_URDF, ("robot.urdf", "joint_4", "prismatic"),
                                 urdf_edit('<joint name="joint_4" type="revolute">',
                                           '<joint name="joint_4" type="prismatic">')),
    "URDF continuous joint without a speed limit": Case(
        WITH_URDF, ("robot.urdf", "joint_5", "no velocity limit"),
        urdf_edit('<joint name="joint_5" type="revolute">', '<joint name="joint_5" type="continuous">').replace(
            JOINT_5_LIMIT, JOINT_5_LIMIT.replace("6.283185307179586", "0"), 1)),
    "URDF floating joint": Case(WITH_URDF, ("robot.urdf", "joint_4", "FreeFlyer"),
                                urdf_edit('<joint name="joint_4" type="revolute">',
                                          '<joint name="joint_4" type="floating">')),
    "URDF not XML": Case(WITH_URDF, ("robot.urdf", "cannot be read as URDF"), "this is not XML"),
    "URDF empty": Case(WITH_URDF, ("robot.urdf", "cannot be read as URDF"), ""),
    "URDF without links": Case(WITH_URDF, ("robot.urdf", "No link"), '<robot name="x"></robot>'),
    "URDF joint 1e308 m away": Case(WITH_URDF, ("robot.urdf", "forward kinematics"),
                                    urdf_edit('<origin xyz="0.497 0.0 0.0"', '<origin xyz="1e308 1e308 0.0"')),
    "URDF in millimetres": Case(WITH_URDF, ("robot.urdf", "units in mm"),
                                urdf_edit('<origin xyz="0.497 0.0 0.0"', '<origin xyz="1497 0.0 0.0"')),
}


def _write_case(case: Case, folder: Path) -> Path:
    task = folder / "task.yaml"
    if isinstance(case.task, bytes):
        task.write_bytes(case.task)
    else:
        task.write_text(case.task)
    if case.urdf is not None:
        (folder / "robot.urdf").write_text(case.urdf)
    (folder / "folder.urdf").mkdir()
    return task


def run_clean(argv: list[str], capsys: pytest.CaptureFixture[str]) -> tuple[int, str]:
    """Exit code and everything printed (the out/err streams and anything else on sys.stdout/stderr),
    which is never a traceback."""
    done = run_cli(*argv)
    captured = capsys.readouterr()
    text = done.text + captured.out + captured.err
    assert_no_traceback(text)
    return done.code, text


def assert_refused(code: int, text: str, words: tuple[str, ...]) -> None:
    """Exit 2, one short error naming what is wrong (long values are quoted shortened)."""
    assert code == 2, text
    assert "singplan: error:" in text
    assert len(text) < 1000, f"{len(text)} characters"
    for word in words:
        assert word in text, f"{word!r} not in {text!r}"


# parsing half a million nodes up to the cap takes seconds: with the slow tests
_SLOW_CASES = {"over 500 000 YAML nodes"}


@pytest.mark.parametrize("name", [pytest.param(n, marks=pytest.mark.slow) if n in _SLOW_CASES else n for n in CASES])
def test_plan_refuses(name: str, tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    case = CASES[name]
    task = _write_case(case, tmp_path)
    out_dir = tmp_path / "out"
    code, text = run_clean(["plan", str(task), "-o", str(out_dir)], capsys)
    assert_refused(code, text, case.words)
    assert not out_dir.exists()


@pytest.mark.parametrize("name", [pytest.param(n, marks=pytest.mark.slow) if n in _SLOW_CASES else n
                                  for n, case in CASES.items() if case.check_too])
def test_check_refuses(name: str, tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    case = CASES[name]
    code, text = run_clean(["check", str(_write_case(case, tmp_path))], capsys)
    assert_refused(code, text, case.words)


FileMaker = Callable[[Path], Path]


def _big_task(folder: Path) -> Path:
    path = folder / "big.yaml"
    path.write_text(GOOD + "#" * (MAX_FILE_BYTES + 1 - len(GOOD)) + "\n")
    return path


def _big_urdf(folder: Path) -> Path:
    (folder / "robot.urdf").write_text(URDF.replace("</robot>", "<!--" + "x" * MAX_URDF_BYTES + "--></robot>"))
    path = folder / "task.yaml"
    path.write_text(WITH_URDF)
    return path


def _unreadable(folder: Path) -> Path:
    path = folder / "locked.yaml"
    path.write_text(GOOD)
    path.chmod(0)
    return path


FILES: dict[str, tuple[FileMaker, tuple[str, ...]]] = {
    "task file over 8 MiB": (_big_task, ("big.yaml", "cap")),
    "URDF over 32 MiB": (_big_urdf, ("robot.urdf", "cap")),
    "task path is a directory": (lambda folder: folder, ("is a directory",)),
    "task file missing": (lambda folder: folder / "nope.yaml", ("nope.yaml", "no such task file")),
    "task path with a NUL byte": (lambda folder: Path(f"{folder}/a\0b.yaml"), ("a\\x00b.yaml", "no such task file")),
    "task path 5000 characters": (lambda folder: folder / ("n" * 5000 + ".yaml"), ("nnnn", "cannot be read")),
    "task file unreadable": (_unreadable, ("locked.yaml", "permission denied")),
}


@pytest.mark.parametrize("name", FILES)
def test_unusable_files_are_refused(name: str, tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    if name == "task file unreadable" and os.geteuid() == 0:
        pytest.skip("root reads any file")
    make, words = FILES[name]
    (tmp_path / "folder.urdf").mkdir()
    code, text = run_clean(["plan", str(make(tmp_path)), "-o", str(tmp_path / "out")], capsys)
    assert_refused(code, text, words)
    assert not (tmp_path / "out").exists()
