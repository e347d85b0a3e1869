"""The robot in meshcat's scene: its URDF visuals as meshcat objects, and an animation of them.

This does what Pinocchio's ``MeshcatVisualizer`` did for the replay (its primitives and mesh
files, their colours and placements), without importing ``pinocchio.visualize``, which loads
every Pinocchio viewer with trimesh and SciPy (half a second to a second before any page is
built). The animation is formed from arrays: the placements of every visual at every keyframe
from one Pinocchio call per keyframe, packed straight into meshcat's message format
(:meth:`AnimationCommand.packed`) instead of one Python object per key, which took seconds
for a long program.
"""

from __future__ import annotations

import base64
import logging
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

from singplan.errors import RobotModelError
from singplan.kinematics.robot import Robot

logger = logging.getLogger(__name__)

ROOT = "robot/visuals"  # the visuals' node under meshcat's scene (pinocchio's layout: robot/visuals/<name>)
_Y_TO_Z = np.array([[1.0, 0, 0, 0], [0, 0, -1.0, 0], [0, 1.0, 0, 0], [0, 0, 0, 1.0]])  # three.js cylinders run along y
_COLLADA = "{http://www.collada.org/2005/11/COLLADASchema}"


class ZCylinder(mg.Cylinder):
    """A cylinder (or cone, radiusTop 0) along z, as URDF and coal have it."""

    def intrinsic_transform(self) -> np.ndarray:
        return _Y_TO_Z


class _ColladaObject:
    """A .dae mesh with its texture images inlined, sent as meshcat's ``_meshfile_object``
    (the file's own materials are kept unless the URDF overrides them)."""

    def __init__(self, path: Path, material: mg.Material | None) -> None:
        self.text = path.read_text()
        self.resources: dict[str, str] = {}
        images = ET.fromstring(self.text).find(f"{_COLLADA}library_images")
        for element in images.iter() if images is not None else ():
            if element.tag.endswith("init_from") and element.text:
                image = Path(element.text) if Path(element.text).is_absolute() else path.parent / element.text
                data = base64.b64encode(image.read_bytes()).decode("ascii")
                self.resources[element.text] = f"data:image/png;base64,{data}"
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
    """

    model: pin.Model
    data: pin.Data
    visual: pin.GeometryModel
    visual_data: pin.GeometryData
    names: list[str]
    _index: np.ndarray

    @classmethod
    def of(cls, robot: Robot) -> RobotScene:
        # package:// meshes resolve against every folder above the URDF (example-robot-data's layout)
        package_dirs = [str(p) for p in robot.urdf_path.parents]
        try:
            model = pin.buildModelFromUrdf(str(robot.urdf_path))
            visual = pin.buildGeomFromUrdf(model, str(robot.urdf_path), pin.GeometryType.VISUAL,
                                           package_dirs=package_dirs)
        except ValueError as exc:
            raise RobotModelError(str(robot.urdf_path),
                                  f"cannot load its visual geometry for the replay ({exc})") from None
        if visual.ngeoms == 0:
            logger.warning("replay: %s has no <visual> geometry; the replay shows the tool's paths only",
                           robot.urdf_path)
        index = np.array([model.joints[model.getJointId(name)].idx_q for name in robot.joint_names])
        names = [g.name for g in visual.geometryObjects]
        return cls(model, model.createData(), visual, visual.createData(), names, index)

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
            obj = _meshcat_object(g)
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


def _meshcat_object(g: pin.GeometryObject) -> tuple[Any, ...] | _ColladaObject | None:
    """(geometry, material) for ``set_object``, a Collada object, or None if meshcat cannot draw it."""
    material = _material(g)
    suffix = Path(g.meshPath).suffix.lower() if g.meshPath else ""
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
    if suffix == ".dae":
        return _ColladaObject(Path(g.meshPath), material if g.overrideMaterial else None)
    if suffix == ".stl":
        return mg.StlMeshGeometry.from_file(g.meshPath), material
    if suffix == ".obj":
        return mg.ObjMeshGeometry.from_file(g.meshPath), material
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
