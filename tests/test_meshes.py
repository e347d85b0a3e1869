"""Meshes and textures only from the robot's own folders, found as ROS would, of bounded size (issues 22, 23).

* ``package://`` found without ROS: the package holding the URDF (by its folder or its package.xml
  ``<name>``), a description copied without package.xml, example-robot-data's share folder,
  ROS_PACKAGE_PATH, AMENT_PREFIX_PATH; ``package://etc/passwd`` finds no package.
* A replay page carries nothing from outside the URDF's own tree and its packages: a mesh or a
  Collada texture outside (``../../../../etc/passwd``, an absolute path, a link pointing out) is
  left out with a warning, through ``plan`` and through ``replay`` of a trajectory.json; so is a
  FIFO or a format meshcat cannot draw.
* Mesh memory is bounded: a mesh over the cap is drawn as its bounding box (binary STL) or left
  out; the pages' meshes together are capped. The slow test plans with a valid 200 MB STL and
  measures the peak.
"""

from __future__ import annotations

import base64
import io
import json
import os
import re
import subprocess
import sys
import time
from pathlib import Path
from typing import Any

import numpy as np
import pytest
import umsgpack
import yaml

from singplan.cli import main
from singplan.kinematics import packages
from singplan.kinematics.packages import find_package, locate_mesh, own_tree, resolve_uri
from singplan.kinematics.robot import robots_dir

ROOT = Path(__file__).resolve().parents[1]
KUKA = (robots_dir() / "kuka_kr6_r900_2.urdf").read_text()
START_DEG = [10, -80, 95, 20, 40, 0]
TARGET = {"xyz": [0.55, -0.08, 0.66], "rpy_deg": [-157.09, 31.93, -172.02]}
SECRET = b"SECRET-OUTSIDE-THE-ROBOT"
LINK_1_VISUALS = KUKA[KUKA.index('<link name="link_1"'):].split("</link>", 1)[0].count("<visual")  # the meshes follow
DAE = """<?xml version="1.0" encoding="UTF-8"?>
<COLLADA xmlns="http://www.collada.org/2005/11/COLLADASchema" version="1.4.1">
  <asset><up_axis>Z_UP</up_axis></asset>
  <library_images>{images}</library_images>
  <library_geometries><geometry id="g"><mesh>
    <source id="p"><float_array id="pa" count="9">0 0 0 0.1 0 0 0 0.1 0</float_array>
      <technique_common><accessor source="#pa" count="3" stride="3"><param name="X" type="float"/>
      <param name="Y" type="float"/><param name="Z" type="float"/></accessor></technique_common></source>
    <vertices id="v"><input semantic="POSITION" source="#p"/></vertices>
    <triangles count="1"><input semantic="VERTEX" source="#v" offset="0"/><p>0 1 2</p></triangles>
  </mesh></geometry></library_geometries>
  <library_visual_scenes><visual_scene id="s"><node id="n"><instance_geometry url="#g"/></node></visual_scene>
  </library_visual_scenes><scene><instance_visual_scene url="#s"/></scene>
</COLLADA>
"""


def stl(path: Path, triangles: int = 4, header: bytes = b"singplan test") -> Path:
    """A binary STL of small triangles inside a 0.1 m box (its first vertex at the box's low corner)."""
    record = np.zeros(triangles, dtype=[("n", "<f4", 3), ("v", "<f4", (3, 3)), ("a", "<u2")])
    rng = np.random.default_rng(triangles)
    record["v"] = rng.uniform(0.0, 0.1, (triangles, 3, 3))
    record["v"][0, 0], record["v"][0, 1] = [0.0, 0.0, 0.0], [0.1, 0.1, 0.1]
    path.parent.mkdir(parents=True, exist_ok=True)
    path.write_bytes(header.ljust(80, b" ")[:80] + triangles.to_bytes(4, "little") + record.tobytes())
    return path


def with_visuals(urdf: str, *filenames: str) -> str:
    """The KUKA URDF with one mesh visual per file name on link_1."""
    visuals = "".join(f'<visual><geometry><mesh filename="{name}"/></geometry></visual>' for name in filenames)
    at = urdf.index("</link>", urdf.index('<link name="link_1"'))
    return urdf[:at] + visuals + urdf[at:]


def robot_folder(root: Path, urdf_text: str, name: str = "arm") -> Path:
    """A description package: root/name/{package.xml, urdf/robot.urdf}; returns the URDF."""
    urdf = root / name / "urdf" / "robot.urdf"
    urdf.parent.mkdir(parents=True, exist_ok=True)
    (root / name / "package.xml").write_text(f"<package><name>{name}</name></package>")
    urdf.write_text(urdf_text)
    return urdf


def plan_page(urdf: Path, out: Path) -> tuple[str, str]:
    """Plan the short KUKA LIN on ``urdf`` with the replay page; (the page, stderr)."""
    task = out.parent / f"{out.name}.yaml"
    task.write_text(yaml.safe_dump({"robot": str(urdf), "tip": "tool0", "start": {"joints_deg": START_DEG},
                                    "moves": [{"lin": {"to": TARGET, "speed": 0.25}}]}))
    err = io.StringIO()
    code = main(["plan", str(task), "-o", str(out), "--quiet", "--no-report"], out=io.StringIO(), err=err)
    assert code == 0, err.getvalue()
    return (out / "replay.html").read_text(), err.getvalue()


def commands(page: str) -> list[dict[str, Any]]:
    match = re.search(r"const SINGPLAN = (.*?);</script>", page, re.S)
    assert match is not None
    data = json.loads(match.group(1).replace("<\\/", "</"))
    return [umsgpack.unpackb(base64.b64decode(c)) for c in data["commands"]]


def carried(page: str) -> bytes:
    """Every byte the page's scene commands carry (meshes, texture data URIs decoded)."""
    out = []
    for command in commands(page):
        obj = command.get("object", {}) if isinstance(command, dict) else {}
        for geometry in obj.get("geometries", []):
            data = geometry.get("data")
            out.append(data.data if isinstance(data, umsgpack.Ext) else str(data).encode())
        inner = obj.get("object", {})
        out.append(str(inner.get("data", "")).encode())
        for uri in inner.get("resources", {}).values():
            out.append(base64.b64decode(uri.split(",", 1)[1]))
    return b"".join(out)


# --- package:// as ROS would find it ------------------------------------------------------------------

def test_a_package_is_found_by_its_folder_or_its_package_xml_name(tmp_path: Path) -> None:
    urdf = robot_folder(tmp_path / "ws" / "src", KUKA, name="ur_description-main")
    (urdf.parents[1] / "package.xml").write_text("<package>\n  <name>ur_description</name>\n</package>")
    mesh = stl(urdf.parents[1] / "meshes" / "base.stl")
    for uri in ("package://ur_description/meshes/base.stl", "package://ur_description-main/meshes/base.stl",
                "meshes/../../meshes/base.stl", f"file://{mesh}"):
        found = locate_mesh(uri if not uri.startswith("meshes") else "../meshes/base.stl", urdf)
        assert found.path is not None and found.path.resolve() == mesh and found.allowed, uri
    assert resolve_uri("package://ur_description/meshes/base.stl", urdf) is not None
    assert own_tree(urdf) == urdf.parents[1].resolve()


def test_a_description_without_package_xml_finds_its_own_meshes(tmp_path: Path) -> None:
    urdf = tmp_path / "my_robot" / "urdf" / "robot.urdf"
    urdf.parent.mkdir(parents=True)
    urdf.write_text(KUKA)
    mesh = stl(tmp_path / "my_robot" / "meshes" / "a.stl")
    found = locate_mesh("package://my_robot/meshes/a.stl", urdf)
    assert found.path == mesh and found.allowed and own_tree(urdf) == (tmp_path / "my_robot").resolve()


def test_folders_above_that_are_no_package_are_not_one(tmp_path: Path) -> None:
    """``package://etc/passwd`` (``/etc`` is above every file, holds no package.xml) and a folder
    above the URDF's own tree named as the package find nothing."""
    urdf = robot_folder(tmp_path / "evil", KUKA)
    stl(tmp_path / "evil" / "secret.stl")
    assert find_package("etc", urdf) is None and resolve_uri("package://etc/passwd", urdf) is None
    assert find_package(tmp_path.name, urdf) is None  # tmp_path is above the package: not part of it
    assert locate_mesh("package://evil/secret.stl", urdf).path is None
    for bad in ("", ".", ".."):
        assert find_package(bad, urdf) is None


@pytest.mark.parametrize("variable", ["ROS_PACKAGE_PATH", "AMENT_PREFIX_PATH"])
def test_packages_on_the_ros_paths(tmp_path: Path, monkeypatch, variable: str) -> None:
    urdf = robot_folder(tmp_path / "robot", KUKA)
    elsewhere = tmp_path / "opt" / ("share" if variable == "AMENT_PREFIX_PATH" else "pkgs")
    (elsewhere / "tool_pkg").mkdir(parents=True)
    (elsewhere / "tool_pkg" / "package.xml").write_text("<package><name>tool_pkg</name></package>")
    (elsewhere / "not_a_pkg").mkdir()
    mesh = stl(elsewhere / "tool_pkg" / "meshes" / "gripper.stl")
    stl(elsewhere / "not_a_pkg" / "x.stl")
    assert locate_mesh("package://tool_pkg/meshes/gripper.stl", urdf).path is None  # not on the path yet
    monkeypatch.setenv(variable, str(elsewhere.parent if variable == "AMENT_PREFIX_PATH" else elsewhere))
    found = locate_mesh("package://tool_pkg/meshes/gripper.stl", urdf)
    assert found.path == mesh and found.allowed and found.root == elsewhere / "tool_pkg"
    assert locate_mesh("package://not_a_pkg/x.stl", urdf).path is None  # no package.xml: no package
    escape = locate_mesh("package://tool_pkg/../not_a_pkg/x.stl", urdf)
    assert escape.path is not None and escape.path.exists() and not escape.allowed  # ``..`` leaves the package


def test_example_robot_data_meshes_from_a_copied_urdf(tmp_path: Path) -> None:
    share = packages._example_robot_data_share()
    if share is None:
        pytest.skip("example-robot-data is not installed")
    urdf = robot_folder(tmp_path, KUKA)
    uri = "package://example-robot-data/robots/ur_description/meshes/ur5/visual/base.dae"
    found = locate_mesh(uri, urdf)
    assert found.path is not None and found.path.is_file() and found.allowed
    assert found.root == share / "example-robot-data"


def test_outside_paths_and_links_are_not_allowed(tmp_path: Path) -> None:
    urdf = robot_folder(tmp_path, KUKA)
    outside = stl(tmp_path / "outside.stl")
    (urdf.parents[1] / "meshes").mkdir()
    (urdf.parents[1] / "meshes" / "link.stl").symlink_to(outside)
    for uri in ("../../outside.stl", str(outside), f"file://{outside}", "../meshes/link.stl"):
        found = locate_mesh(uri, urdf)
        assert found.path is not None and found.path.exists() and not found.allowed, uri


# --- what a page carries ------------------------------------------------------------------------------

def test_meshes_outside_the_robot_or_undrawable_are_left_out_with_a_warning(tmp_path: Path) -> None:
    package = tmp_path / "arm"
    stl(tmp_path / "outside.stl", header=SECRET)
    stl(package / "meshes" / "inside.stl", header=b"INSIDE-MESH")
    (package / "meshes" / "link.stl").parent.mkdir(parents=True, exist_ok=True)
    (package / "meshes" / "link.stl").symlink_to(tmp_path / "outside.stl")
    os.mkfifo(package / "meshes" / "fifo.stl")
    (package / "meshes" / "part.ply").write_text("ply\n")
    urdf = robot_folder(tmp_path, with_visuals(KUKA, "../meshes/inside.stl", "../../outside.stl",
                                               str(tmp_path / "outside.stl"), "../meshes/link.stl",
                                               "../meshes/fifo.stl", "../meshes/part.ply"), name="arm")
    page, err = plan_page(urdf, tmp_path / "out")
    assert SECRET not in carried(page) and b"INSIDE-MESH" in carried(page)
    assert err.count("outside the robot's own folders") == 3, err
    assert f"fifo.stl' of link link_1 visual {LINK_1_VISUALS + 4} left out: it is not a regular file" in err
    assert "not .ply" in err and "no such file" not in err


def test_a_mesh_of_a_package_that_is_not_found_leaves_the_page_out_naming_it(tmp_path: Path) -> None:
    urdf = robot_folder(tmp_path, with_visuals(KUKA, "package://etc/passwd"), name="arm")
    task = tmp_path / "t.yaml"
    task.write_text(yaml.safe_dump({"robot": str(urdf), "tip": "tool0", "start": {"joints_deg": START_DEG},
                                    "moves": [{"lin": {"to": TARGET, "speed": 0.25}}]}))
    err = io.StringIO()
    assert main(["plan", str(task), "-o", str(tmp_path / "out"), "--quiet", "--no-report"], out=io.StringIO(),
                err=err) == 0
    assert "replay.html not written (the plan succeeded)" in err.getvalue()
    assert "visual mesh 'package://etc/passwd' of link link_1" in err.getvalue()
    assert "no package 'etc' found" in err.getvalue()
    assert sorted(p.name for p in (tmp_path / "out").iterdir()) == ["trajectory.csv", "trajectory.json"]


def _texture_dae(folder: Path, secret: Path) -> Path:
    folder.mkdir(parents=True)
    images = "".join(f'<image id="i{k}"><init_from>{name}</init_from></image>' for k, name in enumerate(
        ["../../../../../../../../etc/passwd", str(secret), f"../../{secret.name}", "texture.png",
         "missing.png"]))
    (folder / "texture.png").write_bytes(b"\x89PNG-INSIDE-TEXTURE")
    dae = folder / "part.dae"
    dae.write_text(DAE.format(images=images))
    return dae


def _assert_no_foreign_texture(page: str, err: str) -> None:
    data = carried(page)
    assert SECRET not in data and b"root:" not in data and b"PNG-INSIDE-TEXTURE" in data
    assert err.count("left out: it lies outside the robot's own folders") == 3, err
    assert "'missing.png' of mesh" in err and "no such texture" in err


def test_collada_textures_outside_the_robot_never_reach_the_page(tmp_path: Path, planned_kuka: Path) -> None:
    secret = tmp_path / "secret.png"
    secret.write_bytes(SECRET)
    package = tmp_path / "arm"
    _texture_dae(package / "meshes", secret)
    urdf = robot_folder(tmp_path, with_visuals(KUKA, "package://arm/meshes/part.dae"), name="arm")
    page, err = plan_page(urdf, tmp_path / "out")
    _assert_no_foreign_texture(page, err)
    # the same URDF named by a trajectory.json given to `singplan replay`
    doc = json.loads((planned_kuka / "trajectory.json").read_text())
    doc.update(robot="robot", urdf=str(urdf))
    (tmp_path / "t.json").write_text(json.dumps(doc))
    err_stream = io.StringIO()
    assert main(["replay", str(tmp_path / "t.json"), "--html", str(tmp_path / "r.html")], out=io.StringIO(),
                err=err_stream) == 0
    _assert_no_foreign_texture((tmp_path / "r.html").read_text(), err_stream.getvalue())


def _boxes(page: str) -> list[list[float]]:
    return [g["width"] and [g["width"], g["height"], g["depth"]] for c in commands(page) if isinstance(c, dict)
            for g in c.get("object", {}).get("geometries", []) if g.get("type") == "BoxGeometry"]


def test_an_oversize_mesh_is_drawn_as_its_bounding_box_or_left_out(tmp_path: Path, monkeypatch) -> None:
    monkeypatch.setattr("singplan.outputs.visuals.MAX_MESH_BYTES", 10_000)
    package = tmp_path / "arm"
    stl(package / "meshes" / "big.stl", triangles=400, header=b"BIG-BINARY")  # 20 084 bytes
    (package / "meshes" / "big_ascii.stl").write_text("solid x\n" + "facet normal 0 0 1\n" * 800 + "endsolid x\n")
    urdf = robot_folder(tmp_path, with_visuals(KUKA, "../meshes/big.stl", "../meshes/big_ascii.stl"), name="arm")
    page, err = plan_page(urdf, tmp_path / "out")
    assert b"BIG-BINARY" not in carried(page)
    base = LINK_1_VISUALS
    assert f"big.stl' of link link_1 visual {base} drawn as its bounding box: 20084 bytes is over the 10000-byte" in err
    assert f"big_ascii.stl' of link link_1 visual {base + 1} left out: " in err
    assert [0.1, 0.1, 0.1] in [[round(v, 6) for v in box] for box in _boxes(page)]


def test_the_meshes_of_one_page_are_capped_together(tmp_path: Path, monkeypatch) -> None:
    monkeypatch.setattr("singplan.outputs.visuals.MAX_PAGE_MESH_BYTES", 1_500)
    package = tmp_path / "arm"
    for k in (1, 2, 3):
        stl(package / "meshes" / f"m{k}.stl", triangles=10, header=f"MESH-{k}".encode())  # 584 bytes each
    urdf = robot_folder(tmp_path, with_visuals(KUKA, *(f"../meshes/m{k}.stl" for k in (1, 2, 3))), name="arm")
    page, err = plan_page(urdf, tmp_path / "out")
    data = carried(page)
    assert b"MESH-1" in data and b"MESH-2" in data and b"MESH-3" not in data
    assert (f"m3.stl' of link link_1 visual {LINK_1_VISUALS + 2} drawn as its bounding box: the page's 1500 bytes "
            "of meshes are used up") in err


@pytest.mark.slow  # writes a 200 MB mesh and plans with it (about 10 s)
def test_a_200_mb_mesh_is_planned_and_replayed_in_bounded_memory(tmp_path: Path) -> None:
    """Issue 22: a valid 200 MB STL visual peaked at 4.6 GB (Pinocchio's mesh loading); the
    contract is 1.5 GB in all. It is now drawn as its bounding box and never opened by Pinocchio."""
    package = tmp_path / "arm"
    big = package / "meshes" / "big.stl"
    big.parent.mkdir(parents=True)
    triangles = 4_000_000
    with big.open("wb") as f:
        f.write(b"big".ljust(80) + triangles.to_bytes(4, "little"))
        rng = np.random.default_rng(0)
        for _ in range(4):
            record = np.zeros(triangles // 4, dtype=[("n", "<f4", 3), ("v", "<f4", (3, 3)), ("a", "<u2")])
            record["v"] = rng.uniform(-0.05, 0.05, (triangles // 4, 3, 3))
            f.write(record.tobytes())
    urdf = robot_folder(tmp_path, with_visuals(KUKA, "../meshes/big.stl"), name="arm")
    task = tmp_path / "task.yaml"
    task.write_text(yaml.safe_dump({"robot": str(urdf), "tip": "tool0", "start": {"joints_deg": START_DEG},
                                    "moves": [{"lin": {"to": TARGET, "speed": 0.25}}]}))
    started = time.perf_counter()
    proc = subprocess.Popen([sys.executable, "-m", "singplan", "plan", str(task), "-o", str(tmp_path / "out"),
                             "--quiet", "--no-report"], stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True,
                            env={**os.environ, "PYTHONPATH": str(ROOT)})
    _, status, usage = os.wait4(proc.pid, 0)
    wall_s = time.perf_counter() - started
    err = proc.stderr.read() if proc.stderr is not None else ""
    proc.communicate()
    peak_mb = usage.ru_maxrss / 1024
    print(f"200 MB STL: exit {os.waitstatus_to_exitcode(status)}, {wall_s:.1f} s, peak {peak_mb:.0f} MB")
    assert os.waitstatus_to_exitcode(status) == 0, err
    assert "drawn as its bounding box" in err
    assert peak_mb < 1500
    assert (tmp_path / "out" / "replay.html").stat().st_size < 5_000_000
