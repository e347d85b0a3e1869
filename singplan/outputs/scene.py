"""The robot in meshcat's scene: its URDF visuals as meshcat objects, and an animation of them.

This does what Pinocchio's ``MeshcatVisualizer`` did for the replay (its primitives and mesh
files, their colours and placements), without importing ``pinocchio.visualize``, which loads
every Pinocchio viewer with trimesh and SciPy (half a second to a second before any page is
built). Which mesh files are read, and how much of them, is decided by
:mod:`singplan.outputs.visuals` (the robot's own folders only, bounded sizes); Pinocchio never
opens a mesh. The animation is formed from arrays: the placements of every visual at every keyframe
from one Pinocchio call per keyframe, packed straight into meshcat's message format
(:meth:`AnimationCommand.packed`) instead of one Python object per key, which took seconds
for a long program.
"""

from __future__ import annotations

import base64
import logging
import mimetypes
import xml.etree.ElementTree as ET
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import coal
import meshcat
import meshcat.geometry as mg
import numpy as np
import pinocchio as pin
import umsgpack

from singplan.errors import InputError, RobotModelError
from singplan.kinematics.files import display_path, read_bounded
from singplan.kinematics.packages import MeshFile, texture_allowed
from singplan.kinematics.robot import Robot, load_full_model
from singplan.outputs.visuals import MAX_MESH_BYTES, VisualMeshes, checked_visuals

logger = logging.getLogger(__name__)

ROOT = "robot/visuals"  # the visuals' node under meshcat's scene (pinocchio's layout: robot/visuals/<name>)
_Y_TO_Z = np.array([[1.0, 0, 0, 0], [0, 0, -1.0, 0], [0, 1.0, 0, 0], [0, 0, 0, 1.0]])  # three.js cylinders run along y
_COLLADA = "{http://www.collada.org/2005/11/COLLADASchema}"
_UINT8_ARRAY = mg.threejs_type(np.uint8)[1]  # msgpack extension code of a byte array, as meshcat's STL loader sends it


class ZCylinder(mg.Cylinder):
    """A cylinder (or cone, radiusTop 0) along z, as URDF and coal have it."""

    def intrinsic_transform(self) -> np.ndarray:
        return _Y_TO_Z


class _ColladaObject:
    """A .dae mesh with its texture images inlined, sent as meshcat's ``_meshfile_object``
    (the file's own materials are kept unless the URDF overrides them).

    A texture is inlined only from the folders its mesh may come from
    (:func:`~singplan.kinematics.packages.texture_allowed`), as a regular file within the page's
    remaining mesh bytes; any other (``../../etc/passwd``, ``/etc/shadow``, a missing image, a
    FIFO) is left out with a warning and the mesh drawn without it.
    """

    def __init__(self, mesh: MeshFile, text: str, urdf_path: Path, meshes: VisualMeshes,
                 material: mg.Material | None) -> None:
        assert mesh.path is not None
        self.text = text
        self.resources: dict[str, str] = {}
        try:
            images = ET.fromstring(text).find(f"{_COLLADA}library_images")
        except ET.ParseError as exc:
            raise RobotModelError(display_path(mesh.path), f"not a Collada (XML) file: {exc}") from None
        for element in images.iter() if images is not None else ():
            if element.tag.endswith("init_from") and element.text:
                data = _texture(element.text.strip(), mesh, urdf_path, meshes)
                if data is not None:
                    self.resources[element.text] = data
        self.material = material

    def command(self, node: str) -> dict[str, Any]:
        data: dict[str, Any] = {
            "type": "set_object", "path": node,
            "object": {"metadata": {"version": 4.5, "type": "Object"}, "geometries": [], "materials": [],
                       "object": {"uuid": mg.Geometry().uuid, "type": "_meshfile_object", "format": "dae",
                                  "data": self.text, "resources": self.resources,
                                  "matrix": np.eye(4).flatten().tolist()}}}
        if self.material is not None:
            self.material.lower_in_object(data)
        return data


class _Raw:
    """A command already lowered (``window.send`` takes anything with ``lower()``)."""

    def __init__(self, data: dict[str, Any]) -> None:
        self.data = data

    def lower(self) -> dict[str, Any]:
        return self.data


@dataclass
class RobotScene:
    """The robot's URDF visuals and the chain -> full-model joint map.

    Attributes:
        model, data: the URDF's whole kinematic model (extra joints at neutral).
        visual, visual_data: its visual geometry.
        names: the visuals' node names under :data:`ROOT`, in geometry order.
        meshes: the mesh files behind the visuals' placeholders, and what the page may still carry.
        urdf_path: the URDF (textures are looked up from it).
    """

    model: pin.Model
    data: pin.Data
    visual: pin.GeometryModel
    visual_data: pin.GeometryData
    names: list[str]
    _index: np.ndarray
    meshes: VisualMeshes
    urdf_path: Path

    @classmethod
    def of(cls, robot: Robot) -> RobotScene:
        """The scene of the robot's URDF: read and scanned again for its visuals, its visual meshes
        checked (:func:`~singplan.outputs.visuals.checked_visuals`); its joints must still be the robot's
        (a trajectory's robot read back was checked against the trajectory by
        :func:`~singplan.outputs.timeline.robot_of`)."""
        model, scan = load_full_model(robot.urdf_path)  # continuous joints as unlimited revolute ones, as planned
        meshes = checked_visuals(scan.text, robot.urdf_path)
        try:
            visual = pin.buildGeomFromUrdfString(model, meshes.urdf_text, pin.GeometryType.VISUAL)
        except ValueError as exc:
            raise RobotModelError(str(robot.urdf_path),
                                  f"cannot load its visual geometry for the replay ({exc})") from None
        finally:
            meshes.close()  # the placeholders are read; the real meshes are read when sent
        if visual.ngeoms == 0:
            logger.warning("replay: %s has no <visual> geometry; the replay shows the tool's paths only",
                           robot.urdf_path)
        missing = [name for name in robot.joint_names if not model.existJointName(name)]
        if missing:  # the file was read again after the robot: it may have changed since
            raise InputError(f"joint_names: {missing[0]!r} is not a joint of {display_path(robot.urdf_path)} "
                             "(the URDF changed since the plan?)")
        index = np.array([model.joints[model.getJointId(name)].idx_q for name in robot.joint_names])
        names = [g.name for g in visual.geometryObjects]
        return cls(model, model.createData(), visual, visual.createData(), names, index, meshes, robot.urdf_path)

    def full(self, q: np.ndarray) -> np.ndarray:
        """The whole model's configuration for the chain's joint values q (n,) [rad]."""
        out = pin.neutral(self.model)
        out[self._index] = q
        return out

    def send(self, vis: meshcat.Visualizer, q: np.ndarray) -> list[str]:
        """Send every visual to ``vis`` placed at q (n,); return the node names it could show
        (a geometry meshcat cannot draw is left out with a warning in the log, as Pinocchio does)."""
        shown = []
        placements = self._placements(q)
        for g, name, placement in zip(self.visual.geometryObjects, self.names, placements, strict=True):
            node = vis[f"{ROOT}/{name}"]
            obj = self._meshcat_object(g)
            if obj is None:
                logger.warning("replay: visual %s (%s) cannot be drawn; left out", name, type(g.geometry).__name__)
                continue
            if isinstance(obj, _ColladaObject):
                node.window.send(_Raw(obj.command(node.path.lower())))
            else:
                node.set_object(*obj)
            node.set_transform(placement @ np.diag([*g.meshScale, 1.0]))  # the mesh's scale, as Pinocchio does
            shown.append(name)
        return shown

    def _meshcat_object(self, g: pin.GeometryObject) -> tuple[Any, ...] | _ColladaObject | None:
        """(geometry, material) for ``set_object``, a Collada object, or None if meshcat cannot draw it.

        A mesh is read here, from the file its placeholder stands for, within the cap it was checked against.
        """
        mesh = self.meshes.files.get(g.meshPath)
        if mesh is None:
            return _primitive(g)
        assert mesh.path is not None
        material = _material(g)
        data = read_bounded(mesh.path, MAX_MESH_BYTES, "mesh")
        suffix = mesh.path.suffix.lower()
        if suffix == ".dae":
            return _ColladaObject(mesh, _text(data, mesh), self.urdf_path, self.meshes,
                                  material if g.overrideMaterial else None)
        if suffix == ".stl":
            return mg.MeshGeometry(umsgpack.Ext(_UINT8_ARRAY, data), "stl"), material
        return mg.MeshGeometry(_text(data, mesh), "obj"), material

    def _update(self, q: np.ndarray) -> list[pin.SE3]:
        """The visuals' placements at joints q (n,)."""
        pin.forwardKinematics(self.model, self.data, self.full(q))
        pin.updateGeometryPlacements(self.model, self.data, self.visual, self.visual_data)
        return list(self.visual_data.oMg)

    def _placements(self, q: np.ndarray) -> list[np.ndarray]:
        return [m.homogeneous for m in self._update(q)]

    def poses(self, q: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Positions [m] (m, G, 3) and unit quaternions (x, y, z, w) (m, G, 4) of the G visuals at
        joint samples q (m, n)."""
        count = len(self.visual.geometryObjects)
        xyz, quat = np.empty((len(q), count, 3)), np.empty((len(q), count, 4))
        for k, qk in enumerate(q):
            for g, m in enumerate(self._update(qk)):
                xyz[k, g] = m.translation
                quat[k, g] = pin.Quaternion(m.rotation).coeffs()
        return xyz, quat


def _text(data: bytes, mesh: MeshFile) -> str:
    try:
        return data.decode("utf-8-sig")
    except UnicodeDecodeError as exc:
        raise RobotModelError(display_path(mesh.uri), f"a text mesh that is not UTF-8 (byte {exc.start})") from None


def _texture(name: str, mesh: MeshFile, urdf_path: Path, meshes: VisualMeshes) -> str | None:
    """A Collada texture as a data URI, or None (left out with a warning) when it may not be read."""
    assert mesh.path is not None
    text = name.removeprefix("file://")
    image = Path(text) if Path(text).is_absolute() else mesh.path.parent / text
    if not texture_allowed(image, mesh, urdf_path):
        _no_texture(name, mesh, "it lies outside the robot's own folders")
        return None
    try:
        data = read_bounded(image, max(min(MAX_MESH_BYTES, meshes.remaining_bytes), 0), "texture")
    except InputError as exc:
        _no_texture(name, mesh, getattr(exc, "reason", str(exc)))
        return None
    meshes.remaining_bytes -= len(data)
    kind = mimetypes.guess_type(image.name)[0] or "image/png"
    return f"data:{kind};base64,{base64.b64encode(data).decode('ascii')}"


def _no_texture(name: str, mesh: MeshFile, reason: str) -> None:
    logger.warning("replay: texture %r of mesh %r left out: %s", name[:200], mesh.uri, reason)


def _primitive(g: pin.GeometryObject) -> tuple[Any, ...] | None:
    """(geometry, material) of a URDF primitive, or None if meshcat cannot draw it."""
    material = _material(g)
    shape = g.geometry
    if isinstance(shape, (coal.Cylinder, coal.Capsule)):  # a capsule drawn as its cylinder
        return ZCylinder(2.0 * shape.halfLength, shape.radius), material
    if isinstance(shape, coal.Cone):
        return ZCylinder(2.0 * shape.halfLength, radiusTop=0.0, radiusBottom=shape.radius), material
    if isinstance(shape, coal.Box):
        return mg.Box((2.0 * shape.halfSide).tolist()), material
    if isinstance(shape, coal.Sphere):
        return mg.Sphere(shape.radius), material
    if isinstance(shape, coal.Ellipsoid):
        return mg.Ellipsoid(np.asarray(shape.radii)), material
    return None


def _material(g: pin.GeometryObject) -> mg.MeshPhongMaterial:
    """The URDF colour (and Phong figures when it overrides the mesh's), as Pinocchio's viewer sets them."""
    material = mg.MeshPhongMaterial(color=_rgb(g.meshColor))
    if float(g.meshColor[3]) != 1.0:
        material.transparent, material.opacity = True, float(g.meshColor[3])
    phong = g.meshMaterial
    if g.overrideMaterial and isinstance(phong, pin.GeometryPhongMaterial):
        material.emissive, material.specular = _rgb(phong.meshEmissionColor), _rgb(phong.meshSpecularColor)
        material.shininess = phong.meshShininess * 100.0
    return material


def _rgb(rgba: np.ndarray) -> int:
    return int(rgba[0] * 255) * 65536 + int(rgba[1] * 255) * 256 + int(rgba[2] * 255)


@dataclass(frozen=True)
class AnimationCommand:
    """meshcat's ``set_animation`` of nodes from keyframe arrays.

    Attributes:
        paths: the animated nodes' meshcat paths ("/meshcat/robot/visuals/link_6_0").
        frames: keyframe numbers (m,), ascending (the clip plays ``fps`` of them a second).
        positions: (m, len(paths), 3) [m]; quaternions: (m, len(paths), 4), (x, y, z, w).
    """

    paths: tuple[str, ...]
    frames: np.ndarray
    positions: np.ndarray
    quaternions: np.ndarray
    fps: float
    play: bool = False
    repetitions: int = 1

    def lower(self) -> dict[str, Any]:
        """The command as meshcat's Python side lowers it (for a live server)."""
        return _command(self, [[_keys(self.frames, self.positions[:, i]), _keys(self.frames, self.quaternions[:, i])]
                               for i in range(len(self.paths))])

    def packed(self) -> bytes:
        """:meth:`lower` as msgpack, keyframe values and times in single precision (0.1 um at 1 m,
        1e-7 of a quaternion; frame numbers exact below 2**24), formed with numpy."""
        tracks = [[_RawBytes(_packed_keys(self.frames, self.positions[:, i])),
                   _RawBytes(_packed_keys(self.frames, self.quaternions[:, i]))] for i in range(len(self.paths))]
        return _pack(_command(self, tracks))


def _command(cmd: AnimationCommand, keys: list[list[Any]]) -> dict[str, Any]:
    clips = [{"path": path, "clip": {"fps": cmd.fps, "name": "default",
                                     "tracks": [{"name": ".position", "type": "vector3", "keys": k[0]},
                                                {"name": ".quaternion", "type": "quaternion", "keys": k[1]}]}}
             for path, k in zip(cmd.paths, keys, strict=True)]
    return {"type": "set_animation", "animations": clips,
            "options": {"play": cmd.play, "repetitions": cmd.repetitions}, "path": ""}


def _keys(frames: np.ndarray, values: np.ndarray) -> list[dict[str, Any]]:
    return [{"time": float(f), "value": v} for f, v in zip(frames.tolist(), values.tolist(), strict=True)]


class _RawBytes(bytes):
    """Bytes already in msgpack form, written as they are by :func:`_pack`."""


def _packed_keys(frames: np.ndarray, values: np.ndarray) -> bytes:
    """msgpack of ``[{"time": f32, "value": [f32 x d]} ...]`` for m keys: fixed-size records."""
    m, d = values.shape
    fields = [("head", "S6"), ("t_tag", "u1"), ("t", ">f4"), ("value", "S6"), ("n", "u1")]
    fields += [item for c in range(d) for item in ((f"tag{c}", "u1"), (f"v{c}", ">f4"))]
    records = np.zeros(m, dtype=np.dtype(fields))
    records["head"], records["t_tag"], records["t"] = b"\x82\xa4time", 0xCA, frames
    records["value"], records["n"] = b"\xa5value", 0x90 | d
    for c in range(d):
        records[f"tag{c}"], records[f"v{c}"] = 0xCA, values[:, c]
    return _array_header(m) + records.tobytes()


def _array_header(n: int) -> bytes:
    """msgpack's header of an array of n items (fixarray, array 16 or array 32)."""
    return bytes([0x90 | n]) if n < 16 else (b"\xdc" + n.to_bytes(2, "big") if n < 65536
                                             else b"\xdd" + n.to_bytes(4, "big"))


def _pack(value: Any) -> bytes:
    """msgpack of a command: maps, lists and :class:`_RawBytes` by hand, scalars by umsgpack."""
    if isinstance(value, _RawBytes):
        return bytes(value)
    if isinstance(value, dict):
        n = len(value)
        head = bytes([0x80 | n]) if n < 16 else b"\xde" + n.to_bytes(2, "big")
        return head + b"".join(_pack(k) + _pack(v) for k, v in value.items())
    if isinstance(value, list):
        return _array_header(len(value)) + b"".join(_pack(v) for v in value)
    return bytes(umsgpack.packb(value))
