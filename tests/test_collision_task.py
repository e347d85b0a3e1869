"""The task keys `cell`, `tool.geometry` and `collision` (DESIGN.md "Task YAML"): what they read as,
and bad input refused with exit 2 naming the field."""

from __future__ import annotations

import io
from pathlib import Path
from typing import Any

import pytest
import yaml

from singplan.cli import main
from singplan.kinematics.shapes import CollisionSettings
from singplan.task.load import load_task, parse_task

BASE: dict[str, Any] = {
    "robot": "kuka_kr6_r900_2", "tool": {"xyz": [0, 0, 0.15]},
    "start": {"joints_deg": [0.0, -90.0, 90.0, 0.0, 45.0, 0.0]},
    "moves": [{"ptp": {"to": {"joints_deg": [20.0, -80.0, 80.0, 0.0, 40.0, 10.0]}}}],
}
STL = b"\0" * 80 + (0).to_bytes(4, "little")  # a binary STL without a triangle


def _task(tmp_path: Path, **extra: Any) -> Path:
    path = tmp_path / "task.yaml"
    path.write_text(yaml.safe_dump({**BASE, **extra}))
    return path


def _plan(task: Path, tmp_path: Path) -> tuple[int, str]:
    err = io.StringIO()
    code = main(["plan", str(task), "-o", str(tmp_path / "out"), "--quiet"], out=io.StringIO(), err=err)
    return code, err.getvalue().strip().splitlines()[-1] if err.getvalue().strip() else ""


def test_the_keys_read_as_records(tmp_path: Path) -> None:
    (tmp_path / "part.stl").write_bytes(STL)
    task = load_task(_task(
        tmp_path, tool={"xyz": [0, 0, 0.15], "geometry": [{"cylinder": {"radius": 0.02, "length": 0.1},
                                                           "xyz": [0, 0, 0.05]}]},
        cell=[{"name": "table", "box": {"size": [1, 0.8, 0.05]}, "xyz": [0.6, 0, -0.3]},
              {"sphere": {"radius": 0.05}, "xyz": [0.6, 0.5, 0.2]},
              {"name": "part", "mesh": {"file": "part.stl", "scale": 0.001}, "rpy_deg": [0, 0, 90]}],
        collision={"clearance_mm": 5, "allow": [["link_6", "part"]]}))
    assert [s.name for s in task.cell] == ["table", "cell[1]", "part"]
    assert task.cell[2].mesh_file == str((tmp_path / "part.stl").resolve())
    assert task.cell[2].mesh_scale == (0.001, 0.001, 0.001)
    assert task.tool_geometry[0].kind == "cylinder" and task.tool_geometry[0].dimensions_m == (0.02, 0.1)
    assert task.collision == CollisionSettings(5.0, True, None, (("link_6", "part"),))
    mapping = task.to_mapping()
    assert mapping["cell"][1]["name"] == "cell[1]" and mapping["collision"]["clearance_mm"] == 5.0
    assert parse_task(mapping, tmp_path).cell == task.cell  # trajectory.json's task reads back the same


def test_checking_is_on_with_any_of_the_keys() -> None:
    assert parse_task(BASE).collision is None
    assert parse_task({**BASE, "cell": []}).collision == CollisionSettings()
    assert parse_task({**BASE, "collision": None}).collision == CollisionSettings()
    assert parse_task({**BASE, "tool": {"geometry": []}}).collision == CollisionSettings()


BAD = [
    ({"cell": [{"box": {"size": [1, 0, 1]}}]}, "cell[0].box.size[1]: must be positive"),
    ({"cell": [{"box": {"size": [1, -0.8, 1]}}]}, "cell[0].box.size[1]: must be positive"),
    ({"cell": [{"cylinder": {"radius": 0.1, "length": -1}}]}, "cell[0].cylinder.length: must be positive"),
    ({"cell": [{"sphere": {"radius": 0}}]}, "cell[0].sphere.radius: must be positive"),
    ({"cell": [{"cone": {"radius": 1}}]}, "cell[0].cone: unknown key"),
    ({"cell": [{"xyz": [0, 0, 0]}]}, "cell[0]: needs exactly one shape kind of box, cylinder, sphere, mesh; got none"),
    ({"cell": [{"box": {"size": [1, 1, 1]}, "sphere": {"radius": 1}}]}, "cell[0]: needs exactly one shape kind"),
    ({"cell": [{"box": {"size": [1, 1]}}]}, "cell[0].box.size: expected 3 numbers"),
    ({"cell": [{"box": {}}]}, "cell[0].box.size: missing"),
    ({"cell": [{"sphere": {"radius": 0.1, "colour": 1}}]}, "cell[0].sphere.colour: unknown key"),
    ({"cell": [{"mesh": {"file": "nothing.stl"}}]}, "cell[0].mesh.file: mesh file nothing.stl does not exist"),
    ({"cell": [{"mesh": {"file": "part.step"}}]}, "cell[0].mesh.file: part.step is not an STL or OBJ file"),
    ({"cell": [{"mesh": {"file": "garbage.stl"}}]}, "cell[0].mesh.file: "),
    ({"cell": [{"mesh": {"file": "empty.stl"}}]}, "cell[0].mesh.file: "),
    ({"cell": [{"mesh": {"file": "garbage.stl", "scale": 0}}]}, "cell[0].mesh.scale: must be positive"),
    ({"cell": [{"name": "a", "sphere": {"radius": 1}}, {"name": "a", "sphere": {"radius": 1}}]},
     "cell[1].name: 'a' is used twice (cell[0] and cell[1])"),
    ({"cell": [{"name": "tool", "sphere": {"radius": 1}}]}, "cell[0].name: 'tool' names the tool's geometry"),
    ({"cell": [{"name": "link_3", "sphere": {"radius": 1}}]}, "cell[0].name: 'link_3' is a link"),
    ({"cell": {"box": {"size": [1, 1, 1]}}}, "cell: expected a list of shapes"),
    ({"tool": {"geometry": [{"box": {"size": [1, 1, -1]}}]}}, "tool.geometry[0].box.size[2]: must be positive"),
    ({"collision": {"clearance_mm": -1}}, "collision.clearance_mm: must be at least 0"),
    ({"collision": {"self": "yes"}}, "collision.self: expected true or false"),
    ({"collision": {"srdf": "none.srdf"}}, "collision.srdf: SRDF file none.srdf does not exist"),
    ({"collision": {"srdf": "garbage.stl"}}, "collision.srdf: "),
    ({"collision": {"allow": [["link_1"]]}}, "collision.allow[0]: expected a pair of body names"),
    ({"collision": {"allow": [["link_1", "lnk_2"]]}}, "collision.allow[0][1]: unknown body 'lnk_2'; did you mean"),
    ({"collision": {"margin": 3}}, "collision.margin: unknown key"),
]


@pytest.mark.parametrize(("extra", "message"), BAD, ids=[m.split(":")[0] + f"-{i}" for i, (_, m) in enumerate(BAD)])
def test_bad_collision_input_is_refused_naming_the_field(tmp_path: Path, extra: dict[str, Any], message: str) -> None:
    (tmp_path / "garbage.stl").write_text("solid garbage\nthis is not a mesh\n")
    (tmp_path / "empty.stl").write_bytes(STL)
    code, last = _plan(_task(tmp_path, **extra), tmp_path)
    assert code == 2, last
    assert message in last, last


def test_a_fifo_as_mesh_is_refused_not_waited_on(tmp_path: Path) -> None:
    import os

    os.mkfifo(tmp_path / "pipe.stl")
    code, last = _plan(_task(tmp_path, cell=[{"mesh": {"file": "pipe.stl"}}]), tmp_path)
    assert code == 2 and "cell[0].mesh.file" in last and "FIFO" in last, last
