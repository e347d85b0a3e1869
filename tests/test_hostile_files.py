"""Hostile files other than the task (issue 22): the controller sidecar, trajectory.json, the URDF.

Each is read through singplan.kinematics.files (a regular file within its cap, bounded parse work,
every value checked before use); every case here must exit 2 with one short error naming the file
and the field, no traceback, no hang, and nothing written. The cases are those the issue lists
(invalid UTF-8, ``couplings: 5``, a link to /dev/zero, an alias bomb, a FIFO; 100 000-deep nesting,
times near 1e300, NaN in q, empty arrays, junk segments, ``tool.xyz: "abc"``, 7 joint names for 6
columns; a 10 000-joint URDF, an axis ``0 0 0``, a mimic joint on the chain) and their neighbours.
A hypothesis test mutates a real trajectory.json field by field: loading it either gives a
trajectory every export can write or is bad input, never another exception.
"""

from __future__ import annotations

import contextlib
import copy
import json
import math
import os
from collections.abc import Callable
from pathlib import Path
from typing import Any

import pytest
import yaml
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from singplan.errors import InputError
from singplan.kinematics.robot import load_robot, robots_dir
from singplan.kinematics.urdf_scan import MAX_JOINTS, MAX_TREE_DEPTH
from singplan.outputs import exports
from singplan.outputs.viewer import replay_html, robot_of
from singplan.results.trajectory import load
from tests.cli_helpers import assert_no_traceback, run_cli

KUKA = (robots_dir() / "kuka_kr6_r900_2.urdf").read_text()
START_DEG = [10, -80, 95, 20, 40, 0]
TARGET = {"xyz": [0.55, -0.08, 0.66], "rpy_deg": [-157.09, 31.93, -172.02]}  # ~40 mm from the start


def run_clean(*argv: str) -> tuple[int, str]:
    """Exit code and everything printed, which is never a traceback."""
    done = run_cli(*argv)
    assert_no_traceback(done.text)
    return done.code, done.text


def assert_refused(code: int, text: str, *words: str) -> None:
    assert code == 2, text
    assert text.startswith("singplan: error:") and len(text) < 1000, text
    for word in words:
        assert word in text, f"{word!r} not in {text!r}"


def _robot_task(folder: Path, urdf_text: str = KUKA) -> Path:
    (folder / "robot.urdf").write_text(urdf_text)
    task = folder / "task.yaml"
    task.write_text(yaml.safe_dump({"robot": "robot.urdf", "tip": "tool0", "start": {"joints_deg": START_DEG},
                                    "moves": [{"lin": {"to": TARGET, "speed": 0.25}}]}))
    return task


def _plan(task: Path, out: Path) -> tuple[int, str]:
    return run_clean("plan", str(task), "-o", str(out), "--quiet", "--no-report", "--no-replay")


# --- the controller sidecar -------------------------------------------------------------------------

def _alias_bomb() -> bytes:
    lines = ['a0: &a0 ["x", "x", "x", "x", "x", "x", "x", "x", "x"]']
    lines += [f"a{i}: &a{i} [{', '.join([f'*a{i - 1}'] * 9)}]" for i in range(1, 10)]
    return ("\n".join(lines) + "\ncontroller: {vendor: abb, axis_signs: *a9}\n").encode()


SidecarMaker = Callable[[Path], None]


def _bytes(data: bytes) -> SidecarMaker:
    return lambda side: side.write_bytes(data)


SIDECARS: dict[str, tuple[SidecarMaker, tuple[str, ...]]] = {
    "invalid UTF-8": (_bytes(b"controller: {vendor: \xff\xfe}\n"), ("UTF-8", "byte 21")),
    "couplings: 5": (_bytes(b"controller: {vendor: abb, couplings: 5}\n"), ("controller.couplings", "list")),
    "a link to /dev/zero": (lambda side: side.symlink_to("/dev/zero"), ("not a regular file", "device")),
    "an alias bomb": (_bytes(_alias_bomb()), ("a1[0]", "aliases are not allowed")),
    "a FIFO": (lambda side: os.mkfifo(side), ("not a regular file", "FIFO")),
    "a folder": (lambda side: side.mkdir(), ("is a directory",)),
    "over 64 KiB": (_bytes(b"# " + b"x" * 70_000 + b"\ncontroller: {vendor: none}\n"), ("cap",)),
    "not YAML": (_bytes(b"controller: [\n"), ("not valid YAML", "line")),
    "nested 20 deep": (_bytes(b"controller: " + b"[" * 20 + b"]" * 20 + b"\n"), ("deeper than 6",)),
    "vendor a list": (_bytes(b"controller: {vendor: [abb]}\n"), ("controller.vendor", "expected one of")),
    "axis signs as texts": (_bytes(b"controller: {vendor: abb, axis_signs: [a, b, c, d, e, f]}\n"),
                            ("controller.axis_signs[0]", "finite number")),
    "axis sign 2": (_bytes(b"controller: {vendor: abb, axis_signs: [1, 1, 2, 1, 1, 1]}\n"),
                    ("controller.axis_signs[2]", "got int 2")),
    "offset NaN": (_bytes(b"controller: {vendor: kuka, axis_offsets_deg: [0, .nan, 0, 0, 0, 0]}\n"),
                   ("controller.axis_offsets_deg[1]", "finite")),
    "offset 1e300": (_bytes(b"controller: {vendor: kuka, axis_offsets_deg: [0, 1e300, 0, 0, 0, 0]}\n"),
                     ("controller.axis_offsets_deg[1]", "at most 720")),
    "coupling axis 1.5": (_bytes(b"controller: {vendor: fanuc, couplings: [{axis: 1.5, joint: 2, factor: 1}]}\n"),
                          ("controller.couplings[0].axis", "whole number")),
    "coupling axis true": (_bytes(b"controller: {vendor: fanuc, couplings: [{axis: true, joint: 2, factor: 1}]}\n"),
                           ("controller.couplings[0].axis", "whole number")),
    "coupling factor text": (_bytes(b"controller: {vendor: fanuc, couplings: [{axis: 3, joint: 2, factor: x}]}\n"),
                             ("controller.couplings[0].factor", "finite number")),
    "singular couplings": (_bytes(b"controller: {vendor: fanuc, couplings: [{axis: 1, joint: 2, factor: 1},"
                                  b" {axis: 2, joint: 1, factor: 1}]}\n"), ("controller.couplings", "singular")),
    "an unknown top-level key": (_bytes(b"controller: {vendor: none}\ncontroller2: 1\n"),
                                 ("controller2", "unknown key")),
    "sources not texts": (_bytes(b"controller: {vendor: abb, sources: [[1, 2]]}\n"), ("controller.sources", "texts")),
    "no controller key": (_bytes(b"vendor: abb\n"), ("key 'controller'",)),
}


@pytest.mark.parametrize("name", SIDECARS)
def test_a_bad_controller_sidecar_is_refused_before_planning(name: str, tmp_path: Path) -> None:
    make, words = SIDECARS[name]
    task = _robot_task(tmp_path)
    make(tmp_path / "robot.controller.yaml")
    code, text = _plan(task, tmp_path / "out")
    assert_refused(code, text, "robot.controller.yaml", *words)
    assert not (tmp_path / "out").exists()


def test_a_good_sidecar_gives_the_vendor_configuration(tmp_path: Path) -> None:
    task = _robot_task(tmp_path)
    (tmp_path / "robot.controller.yaml").write_text("controller: {vendor: kuka, axis_signs: [-1, 1, 1, -1, 1, -1],"
                                                    " axis_offsets_deg: [0, -90, 90, 0, 0, 0]}\n")
    code, text = _plan(task, tmp_path / "out")
    assert code == 0, text
    moves = json.loads((tmp_path / "out" / "trajectory.json").read_text())["moves"]
    assert set(moves[0]["vendor_config"]) == {"kuka"}


# --- trajectory.json -------------------------------------------------------------------------------

Edit = Callable[[dict[str, Any]], None]


def _set(path: str, value: Any) -> Edit:
    def edit(doc: dict[str, Any]) -> None:
        *head, last = path.split(".")
        for key in head:
            doc = doc[int(key)] if isinstance(doc, list) else doc[key]
        doc[int(last) if isinstance(doc, list) else last] = value
    return edit


def _times(make: Callable[[int], float]) -> Edit:
    def edit(doc: dict[str, Any]) -> None:
        doc["t"] = [make(k) for k in range(len(doc["t"]))]
    return edit


def _empty(doc: dict[str, Any]) -> None:
    for key in ("t", "q", "qd", "qdd"):
        doc[key] = []


TRAJECTORIES: dict[str, tuple[Edit, tuple[str, ...]]] = {
    "times near 1e300": (_times(lambda k: 1e300 + k * 1e285), ("t[0]", "at most 1e+07")),
    "times that go back": (_times(lambda k: [0.0, 0.004, 0.002][k] if k < 3 else k * 0.004), ("t[2]", "increase")),
    "a negative start": (_times(lambda k: k * 0.004 - 1.0), ("t[0]", "start at 0 or later, got -1.0")),
    "NaN in q": (lambda d: d["q"][3].__setitem__(2, math.nan), ("q[3][2]", "finite")),
    "q of 1e9 rad": (lambda d: d["q"][3].__setitem__(2, 1e9), ("q[3][2]", "at most")),
    "a text in qd": (lambda d: d["qd"][5].__setitem__(0, "fast"), ("qd", "numbers")),
    "true in qdd": (lambda d: d.__setitem__("qdd", [[True] * 6 for _ in d["qdd"]]), ("qdd", "true/false")),
    "ragged q": (lambda d: d["q"][4].pop(), ("q", "different lengths")),
    "empty arrays": (_empty, ("t", "1 to 10000000")),
    "junk segments": (_set("segments", [1, "x", {"kind": "warp"}]), ("segments[0]", "JSON object")),
    "a segment of an unknown kind": (_set("segments.0.kind", "warp"), ("segments[0].kind", "expected one of")),
    "a segment past the end": (_set("segments.0.t1", 1e6), ("segments[0].t1", "[0, 1.904] s")),
    "a segment of move 99": (_set("segments.0.move", 99), ("segments[0].move", "index")),
    "crossing figures missing": (lambda d: next(s for s in d["segments"] if s["kind"] == "crossing").pop("time_lost_s"),
                                 ("segments[", "time_lost_s")),
    "tool.xyz abc": (_set("tool.xyz", "abc"), ("tool.xyz", "3 numbers")),
    "tool.rpy_deg NaN": (_set("tool.rpy_deg", [0, math.nan, 0]), ("tool.rpy_deg[1]",)),
    "7 joint names for 6 columns": (_set("joint_names", [f"joint_{i}" for i in range(1, 8)]),
                                    ("q", "7 joint names")),
    "joint names given twice": (_set("joint_names", ["a", "a", "b", "c", "d", "e"]), ("joint_names", "twice")),
    "a joint name with a line break": (_set("joint_names.2", "joint\n3"), ("joint_names[2]", "U+000A")),
    "period -1": (_set("period", -1), ("period", "[0.0001, 1]")),
    "period a text": (_set("period", "0.004"), ("period", "number")),
    "no task": (lambda d: d.pop("task"), ("task", "JSON object")),
    "task moves 5": (_set("task.moves", 5), ("task.moves",)),
    "task with a NaN target": (_set("task.moves.0.lin.to.xyz", [math.nan, 0, 1]), ("task.moves[0].lin.to.xyz[0]",)),
    "metrics a list": (_set("metrics", [1, 2]), ("metrics", "JSON object")),
    "metrics without duration": (lambda d: d["metrics"].pop("duration_s"), ("metrics", "duration_s")),
    "events junk": (_set("events", [{"t": "x"}]), ("events[0].t", "number")),
    "an event of move -1": (_set("events.0.move", -1), ("events[0].move",)),
    "moves with an unknown key": (_set("moves.0.extra", 1), ("moves[0].extra", "unknown key")),
    "samples of the wrong length": (lambda d: d["samples"]["position_error_mm"].pop(), ("samples.position_error_mm",)),
    "robot 5000 characters": (_set("robot", "r" * 5000), ("robot", "cap")),
    "the wrong format": (_set("format", "singplan.trajectory/9"), ("format", "singplan.trajectory/1")),
}

RAW: dict[str, tuple[Callable[[Path], None], tuple[str, ...]]] = {
    "a FIFO": (lambda p: os.mkfifo(p), ("not a regular file", "FIFO")),
    "a link to /dev/zero": (lambda p: p.symlink_to("/dev/zero"), ("not a regular file", "device")),
    "100 000-deep nesting": (lambda p: p.write_bytes(b"[" * 100_000 + b"]" * 100_000), ("nested too deeply",)),
    "not JSON": (lambda p: p.write_text('{"format": '), ("not valid JSON", "line 1")),
    "invalid UTF-8": (lambda p: p.write_bytes(b'{"format": "\xff"}'), ("UTF-8",)),
    "a JSON list": (lambda p: p.write_text("[1, 2]"), ("format", "not a singplan.trajectory/1 file")),
    "an integer of 5000 digits": (lambda p: p.write_text('{"t": ' + "9" * 5000 + "}"), ("cannot be read",)),
    "empty": (lambda p: p.write_text(""), ("not valid JSON",)),
}


def _commands(folder: Path) -> list[list[str]]:
    json_file = str(folder / "trajectory.json")
    return [["replay", json_file, "--html", str(folder / "r.html")],
            *[["export", json_file, "--format", fmt, "-o", str(folder / f"x.{fmt}")] for fmt in exports.FORMATS]]


@pytest.mark.parametrize("name", TRAJECTORIES)
def test_a_bad_trajectory_json_is_refused_by_replay_and_every_export(name: str, planned_kuka: Path,
                                                                     tmp_path: Path) -> None:
    edit, words = TRAJECTORIES[name]
    doc = json.loads((planned_kuka / "trajectory.json").read_text())
    edit(doc)
    (tmp_path / "trajectory.json").write_text(json.dumps(doc))
    for argv in _commands(tmp_path):
        code, text = run_clean(*argv)
        assert_refused(code, text, "trajectory.json", *words)
    assert sorted(p.name for p in tmp_path.iterdir()) == ["trajectory.json"]  # nothing written, no lock left


@pytest.mark.parametrize("name", RAW)
def test_a_trajectory_json_that_is_no_json_file_is_refused(name: str, tmp_path: Path) -> None:
    make, words = RAW[name]
    make(tmp_path / "trajectory.json")
    for argv in _commands(tmp_path)[:2]:
        code, text = run_clean(*argv)
        assert_refused(code, text, "trajectory.json", *words)


_JUNK = st.one_of(st.none(), st.booleans(), st.integers(-10**30, 10**30), st.text(max_size=8),
                  st.floats(allow_nan=True, allow_infinity=True), st.lists(st.integers(), max_size=3),
                  st.dictionaries(st.text(max_size=3), st.integers(), max_size=2), st.just([[]]), st.just({}))


def _paths(value: Any, prefix: tuple[Any, ...] = ()) -> list[tuple[Any, ...]]:
    """Every key path of a document, the long arrays cut to their first two items."""
    out = [prefix]
    if isinstance(value, dict):
        for key, item in value.items():
            out += _paths(item, (*prefix, key))
    elif isinstance(value, list):
        for i, item in enumerate(value[:2]):
            out += _paths(item, (*prefix, i))
    return out


@pytest.fixture(scope="module")
def kuka_document(planned_kuka: Path) -> dict[str, Any]:
    return json.loads((planned_kuka / "trajectory.json").read_text())


EXAMPLES = 40
SOAK_EXAMPLES = 2 * int(os.environ.get("SINGPLAN_SOAK_EXAMPLES", "300"))


def _check_mutant(document: dict[str, Any], folder: Path, data: st.DataObject, replay: bool) -> None:
    """One field of a real trajectory.json replaced by a junk value (or deleted): it is read back as
    a trajectory every export writes (and, with ``replay``, whose page is built), or refused as
    InputError; never another exception."""
    doc = copy.deepcopy(document)
    path = data.draw(st.sampled_from(_paths(doc)[1:]))
    parent = doc
    for key in path[:-1]:
        parent = parent[key]
    if data.draw(st.booleans()) and isinstance(parent, dict):
        del parent[path[-1]]
    else:
        parent[path[-1]] = data.draw(_JUNK)
    file = folder / "trajectory.json"
    file.write_text(json.dumps(doc))
    try:
        traj = load(file)
    except InputError:
        return
    for fmt in ("ros2", "ros2-json", "csv-deg"):
        with contextlib.suppress(InputError):
            exports.export(traj, fmt, folder / f"x.{fmt}")
    if replay:
        with contextlib.suppress(InputError):
            replay_html(traj, robot_of(traj))


@settings(max_examples=EXAMPLES, derandomize=True, deadline=None, database=None,
          suppress_health_check=[HealthCheck.function_scoped_fixture])
@given(data=st.data())
def test_any_field_replaced_by_junk_loads_or_is_bad_input(kuka_document: dict[str, Any], tmp_path: Path,
                                                          data: st.DataObject) -> None:
    _check_mutant(kuka_document, tmp_path, data, replay=False)


@pytest.mark.soak
@settings(max_examples=SOAK_EXAMPLES, derandomize=True, deadline=None, database=None,
          suppress_health_check=[HealthCheck.function_scoped_fixture])
@given(data=st.data())
def test_junk_trajectory_json_soak(kuka_document: dict[str, Any], tmp_path: Path, data: st.DataObject) -> None:
    _check_mutant(kuka_document, tmp_path, data, replay=True)


# --- URDF ----------------------------------------------------------------------------------------------

def _chain(n: int, links_per_joint: int = 1) -> str:
    links = "".join(f'<link name="l{i}"/>' for i in range(n + 1))
    joints = "".join(f'<joint name="j{i}" type="revolute"><parent link="l{i}"/><child link="l{i + 1}"/>'
                     f'<origin xyz="0 0 0.001"/><axis xyz="0 0 1"/>'
                     f'<limit lower="-1" upper="1" velocity="1" effort="1"/></joint>' for i in range(n))
    return f'<robot name="big">{links}{joints}</robot>'


def _kuka_edit(old: str, new: str) -> str:
    assert old in KUKA, old
    return KUKA.replace(old, new, 1)


def _joint_end(name: str) -> int:
    return KUKA.index("</joint>", KUKA.index(f'<joint name="{name}"'))


def _mimic(follower: str, leader: str) -> str:
    at = _joint_end(follower)
    return KUKA[:at] + f'<mimic joint="{leader}" multiplier="-2.0" offset="0.1"/>' + KUKA[at:]


AXIS_4 = KUKA[KUKA.index('<axis', KUKA.index('<joint name="joint_4"')):].split("/>", 1)[0] + "/>"

URDFS: dict[str, tuple[str, tuple[str, ...]]] = {
    "10 000 joints": (_chain(10_000), ("more than 1001 links",)),
    "a chain deeper than 256 joints": (_chain(MAX_TREE_DEPTH + 10), ("more than 256 joints from the root",)),
    "axis 0 0 0": (_kuka_edit(AXIS_4, '<axis xyz="0 0 0"/>'), ("joint 'joint_4'", "no direction")),
    "axis 1e-9 0 0": (_kuka_edit(AXIS_4, '<axis xyz="1e-9 0 0"/>'), ("joint 'joint_4'", "no direction")),
    "axis nan 0 1": (_kuka_edit(AXIS_4, '<axis xyz="nan 0 1"/>'), ("joint 'joint_4'", "finite numbers")),
    "axis of two numbers": (_kuka_edit(AXIS_4, '<axis xyz="0 1"/>'), ("joint 'joint_4'", "three")),
    "a mimic joint on the chain": (_mimic("joint_6", "joint_4"), ("joint 'joint_6' mimics 'joint_4'",
                                                                    "not supported")),
    "a mimic of no joint": (_mimic("joint_6", "nope"), ("joint 'joint_6'", "names no joint")),
    "a mimic multiplier nan": (_mimic("joint_6", "joint_4").replace('multiplier="-2.0"', 'multiplier="nan"'),
                               ("joint 'joint_6'", "multiplier")),
    "a joint name with a control character": (_kuka_edit('name="joint_3"', 'name="joint&#10;3"'),
                                              ("control character",)),
    "a root that is no robot": ("<model><link name='a'/></model>", ("root element is <model>",)),
    "not XML": ("<robot name='x'><link name='a'>", ("not well-formed XML",)),
    "XML 40 levels deep": ("<robot name='x'>" + "<a>" * 40 + "</a>" * 40 + "</robot>", ("deeper than 32",)),
}


@pytest.mark.parametrize("name", URDFS)
def test_a_hostile_urdf_is_refused_by_name_before_pinocchio(name: str, tmp_path: Path) -> None:
    text, words = URDFS[name]
    code, text = _plan(_robot_task(tmp_path, text), tmp_path / "out")
    assert_refused(code, text, "robot.urdf", *words)
    code, text = run_clean("info", str(tmp_path / "robot.urdf"))
    assert_refused(code, text, "robot.urdf", *words)


@pytest.mark.parametrize("kind", ["FIFO", "/dev/zero"])
def test_a_urdf_that_is_no_regular_file_is_refused(kind: str, tmp_path: Path) -> None:
    task = _robot_task(tmp_path)
    urdf = tmp_path / "robot.urdf"
    urdf.unlink()
    if kind == "FIFO":
        os.mkfifo(urdf)
    else:
        urdf.symlink_to("/dev/zero")
    code, text = run_clean("info", str(urdf))
    assert_refused(code, text, "robot.urdf" if kind == "FIFO" else "/dev/zero", "not a regular file")
    code, text = _plan(task, tmp_path / "out")
    assert_refused(code, text, "robot: ", "not a regular file")


def _with_gripper(urdf: str) -> str:
    """The KUKA with two fingers on tool0, the second mimicking the first (a gripper off the chain)."""
    fingers = "".join(
        f'<link name="finger_{k}"/><joint name="finger_joint_{k}" type="prismatic"><parent link="tool0"/>'
        f'<child link="finger_{k}"/><origin xyz="0 {0.02 * (2 * k - 3)} 0.05"/><axis xyz="0 1 0"/>'
        f'<limit lower="0" upper="0.04" velocity="0.2" effort="20"/>'
        + ('<mimic joint="finger_joint_1"/>' if k == 2 else "") + "</joint>" for k in (1, 2))
    return urdf.replace("</robot>", fingers + "</robot>")


def test_mimic_joints_off_the_chain_still_plan(tmp_path: Path) -> None:
    code, text = _plan(_robot_task(tmp_path, _with_gripper(KUKA)), tmp_path / "out")
    assert code == 0, text
    robot = load_robot(tmp_path / "robot.urdf", tip="tool0")
    assert robot.joint_names == tuple(f"joint_{i}" for i in range(1, 7))


def test_a_large_legitimate_urdf_still_loads(tmp_path: Path) -> None:
    """An arm in a cell of 900 other jointed bodies (a wide tree, each one joint from the root)
    stays within the caps: only what would crash or cannot be planned is refused."""
    extra = "".join(f'<link name="part_{k}"/><joint name="slide_{k}" type="prismatic"><parent link="base_link"/>'
                    f'<child link="part_{k}"/><axis xyz="1 0 0"/>'
                    f'<limit lower="0" upper="1" velocity="1" effort="1"/></joint>' for k in range(MAX_JOINTS - 100))
    (tmp_path / "cell.urdf").write_text(KUKA.replace("</robot>", extra + "</robot>"))
    robot = load_robot(tmp_path / "cell.urdf", tip="tool0")
    assert robot.n_joints == 6
