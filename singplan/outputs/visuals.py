"""The URDF's visual meshes checked before anything reads them: from the robot's own folders, of
bounded size, each read once and only by singplan.

A replay page is mailed around, so it must carry nothing but the robot: every visual mesh is
located as ROS would (:func:`singplan.kinematics.packages.locate_mesh`) and

* a mesh outside the URDF's own folder tree and its packages, or one that is not a regular file
  (a FIFO, a device), is left out of the page with a warning;
* a format meshcat cannot draw (other than STL, OBJ, Collada) is left out with a warning;
* a mesh file over :data:`MAX_MESH_BYTES`, or past :data:`MAX_PAGE_MESH_BYTES` of meshes in all,
  is drawn as its bounding box (a binary STL, whose bounds are read a chunk at a time) or left
  out (other formats), with a warning;
* a mesh that is missing is an error naming it (the page is not built; the plan stands).

Pinocchio never opens a mesh: it builds the visual geometry (names, placements, colours, scales)
from the URDF with each kept mesh replaced by a one-triangle placeholder, and the scene sends
the real file's bytes (:data:`MeshChoice`). Loading a valid 200 MB STL through Pinocchio
(assimp and coal) peaked at 4.6 GB and took 90 s; its bytes alone are 200 MB.
"""

from __future__ import annotations

import logging
import math
import os
import stat
import tempfile
import xml.etree.ElementTree as ET
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
import pinocchio as pin

from singplan.errors import RobotModelError
from singplan.kinematics.files import display_path
from singplan.kinematics.packages import PACKAGE_SEARCH, MeshFile, locate_mesh

logger = logging.getLogger("singplan.outputs.scene")  # the scene's warnings, which the CLI shows

MAX_MESH_BYTES = 32 * 1024 * 1024  # one visual mesh file carried into the page
MAX_PAGE_MESH_BYTES = 64 * 1024 * 1024  # all of them together
DRAWN = (".stl", ".obj", ".dae")
_STL_RECORD = np.dtype([("normal", "<f4", 3), ("v", "<f4", (3, 3)), ("attribute", "<u2")])
_STL_CHUNK = 1 << 20  # triangles read at once for the bounds (50 MB)


def _placeholder() -> bytes:
    """A binary STL of one small triangle (assimp drops a degenerate one and then refuses the file)."""
    record = np.zeros(1, _STL_RECORD)
    record["normal"], record["v"] = [0.0, 0.0, 1.0], [[0.0, 0.0, 0.0], [1e-3, 0.0, 0.0], [0.0, 1e-3, 0.0]]
    return b"\0" * 80 + (1).to_bytes(4, "little") + record.tobytes()


_PLACEHOLDER = _placeholder()


@dataclass
class VisualMeshes:
    """The URDF rewritten for Pinocchio and the real mesh behind each placeholder.

    Attributes:
        urdf_text: the URDF with every kept mesh's ``filename`` a placeholder file, left-out
            visuals removed and oversize meshes turned into boxes.
        files: placeholder path -> the mesh it stands for (read by the scene, within its root).
        folder: the temporary folder of the placeholders (removed by :meth:`close`).
        remaining_bytes: what the page may still carry of meshes and their textures.
    """

    urdf_text: str
    files: dict[str, MeshFile] = field(default_factory=dict)
    folder: tempfile.TemporaryDirectory[str] | None = None
    remaining_bytes: int = 0

    def close(self) -> None:
        if self.folder is not None:
            self.folder.cleanup()


def checked_visuals(urdf_text: str, urdf_path: Path) -> VisualMeshes:
    """The visual meshes of ``urdf_text`` (the URDF at ``urdf_path``) checked and replaced (module docstring).

    Raises:
        RobotModelError: a visual mesh file is missing (named with where it was looked for).
    """
    root = ET.fromstring(urdf_text)  # the scan (singplan.kinematics.urdf_scan) bounded its size and depth
    folder = tempfile.TemporaryDirectory(prefix="singplan-visuals-")
    out = VisualMeshes("", {}, folder, MAX_PAGE_MESH_BYTES)
    try:
        for link in root.findall("link"):
            for k, visual in enumerate(list(link.findall("visual"))):
                mesh = visual.find("geometry/mesh")
                if mesh is not None and not _keep(visual, mesh, f"{link.get('name')} visual {k}", urdf_path, out):
                    link.remove(visual)
    except BaseException:
        out.close()
        raise
    out.urdf_text = ET.tostring(root, encoding="unicode")
    return out


def _keep(visual: ET.Element, mesh: ET.Element, what: str, urdf_path: Path, out: VisualMeshes) -> bool:
    """Whether the visual stays: its mesh replaced by a placeholder or a box; False: leave it out."""
    uri = mesh.get("filename", "")
    ref = locate_mesh(uri, urdf_path)
    if ref.path is None:
        raise RobotModelError(display_path(urdf_path), f"visual mesh {uri!r} of link {what}: no package "
                                                       f"{uri.removeprefix('package://').split('/')[0]!r} found "
                                                       f"({PACKAGE_SEARCH})")
    if not ref.path.exists():
        raise RobotModelError(display_path(urdf_path), f"visual mesh {uri!r} of link {what}: no such file "
                                                       f"(looked for {display_path(ref.path)})")
    if not ref.allowed:
        return _left_out(what, uri, f"it lies outside the robot's own folders ({display_path(ref.root)})")
    try:
        info = os.stat(ref.path)
    except OSError as exc:
        return _left_out(what, uri, f"it cannot be read ({exc.strerror or exc})")
    if not stat.S_ISREG(info.st_mode):
        return _left_out(what, uri, "it is not a regular file")
    suffix = ref.path.suffix.lower()
    if suffix not in DRAWN:
        return _left_out(what, uri, f"the replay draws STL, OBJ and Collada meshes, not {suffix or 'this format'}")
    if info.st_size > min(MAX_MESH_BYTES, out.remaining_bytes):
        reason = (f"{info.st_size} bytes is over the {MAX_MESH_BYTES}-byte cap for one mesh"
                  if info.st_size > MAX_MESH_BYTES else f"the page's {MAX_PAGE_MESH_BYTES} bytes of meshes are used up")
        return _stand_in(visual, mesh, ref, what, reason)
    out.remaining_bytes -= info.st_size
    assert out.folder is not None
    placeholder = Path(out.folder.name) / f"{len(out.files)}.stl"
    placeholder.write_bytes(_PLACEHOLDER)
    mesh.set("filename", str(placeholder))
    out.files[str(placeholder)] = ref
    return True


def _left_out(what: str, uri: str, reason: str) -> bool:
    logger.warning("replay: visual mesh %r of link %s left out: %s", uri, what, reason)
    return False


def _stand_in(visual: ET.Element, mesh: ET.Element, ref: MeshFile, what: str, reason: str) -> bool:
    """Turn an oversize mesh into its bounding box (binary STL), else leave it out; warn either way."""
    assert ref.path is not None
    bounds = stl_bounds(ref.path)
    if bounds is None:
        return _left_out(what, ref.uri, reason)
    scale = _triple(mesh, "scale", 1.0)
    lo, hi = bounds[0] * scale, bounds[1] * scale
    origin = visual.find("origin")
    if origin is None:
        origin = ET.SubElement(visual, "origin")
    rpy = _triple(origin, "rpy", 0.0)
    centre = _triple(origin, "xyz", 0.0) + pin.rpy.rpyToMatrix(*rpy) @ (0.5 * (lo + hi))
    origin.set("xyz", " ".join(repr(float(v)) for v in centre))
    origin.set("rpy", " ".join(repr(float(v)) for v in rpy))
    geometry = visual.find("geometry")
    assert geometry is not None
    geometry.remove(mesh)
    ET.SubElement(geometry, "box", size=" ".join(repr(float(max(v, 1e-6))) for v in np.abs(hi - lo)))
    logger.warning("replay: visual mesh %r of link %s drawn as its bounding box: %s", ref.uri, what, reason)
    return True


def _triple(element: ET.Element, key: str, default: float) -> np.ndarray:
    """Three numbers of an attribute (``default`` each when absent or unreadable, as a page must not
    fail on a stand-in)."""
    try:
        values = [float(v) for v in (element.get(key) or "").split()]
    except ValueError:
        values = []
    return np.array(values if len(values) == 3 and all(map(math.isfinite, values)) else [default] * 3)


def stl_bounds(path: Path) -> tuple[np.ndarray, np.ndarray] | None:
    """Lowest and highest vertex coordinates (3,) of a binary STL, read a chunk of triangles at a
    time (bounded memory whatever the file's size); None if it is not a binary STL or has none."""
    flags = os.O_RDONLY | getattr(os, "O_NONBLOCK", 0) | getattr(os, "O_CLOEXEC", 0)
    try:
        fd = os.open(path, flags)
    except OSError:
        return None
    with os.fdopen(fd, "rb") as f:
        info = os.fstat(f.fileno())
        head = f.read(84)
        count = int.from_bytes(head[80:84], "little") if len(head) == 84 else -1
        if not stat.S_ISREG(info.st_mode) or count <= 0 or info.st_size != 84 + count * _STL_RECORD.itemsize:
            return None
        lo, hi = np.full(3, math.inf), np.full(3, -math.inf)
        while chunk := f.read(_STL_CHUNK * _STL_RECORD.itemsize):
            v = np.frombuffer(chunk, _STL_RECORD, count=len(chunk) // _STL_RECORD.itemsize)["v"].reshape(-1, 3)
            v = v[np.isfinite(v).all(axis=1)]
            if len(v):
                lo, hi = np.minimum(lo, v.min(axis=0)), np.maximum(hi, v.max(axis=0))
    return (lo, hi) if np.isfinite(lo).all() and np.isfinite(hi).all() else None
