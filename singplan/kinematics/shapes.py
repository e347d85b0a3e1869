"""The collision shapes a task names (``cell``, ``tool.geometry``) and its ``collision`` settings, as records.

These are plain values (no coal object, nothing loaded): the task layer builds them from YAML with
field-named errors, and :mod:`singplan.kinematics.collision` turns them into coal geometry. A shape's
``field`` is where the task gives it (``cell[2]``, ``tool.geometry[0]``), so a mesh that cannot be
read later is still named by its field.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
from typing import Any, Literal

ShapeKind = Literal["box", "cylinder", "sphere", "mesh"]
SHAPE_KINDS: tuple[ShapeKind, ...] = ("box", "cylinder", "sphere", "mesh")
TOOL_BODY = "tool"  # the body `tool.geometry` forms (DESIGN.md, "Collision")
MESH_SUFFIXES = (".stl", ".obj")  # cell and tool meshes (a URDF's collision meshes may be any assimp format)


@dataclass(frozen=True)
class Shape:
    """One shape of the task's cell or tool.

    Attributes:
        kind: box | cylinder | sphere | mesh.
        dimensions_m: box: edge lengths (x, y, z); cylinder: (radius, length), centred along its z;
            sphere: (radius,); mesh: () [m].
        xyz, rpy_deg: its pose: in the base frame (cell) or the tip frame (tool) [m, deg].
        mesh_file: a mesh's file (absolute path), else None.
        mesh_scale: a mesh's scale per axis.
        name: a cell shape's unique name (default ``cell[i]``); ``tool`` for the tool's shapes.
        field: where the task gives it (``cell[2]``), for messages.
    """

    kind: ShapeKind
    dimensions_m: tuple[float, ...] = ()
    xyz: tuple[float, float, float] = (0.0, 0.0, 0.0)
    rpy_deg: tuple[float, float, float] = (0.0, 0.0, 0.0)
    mesh_file: str | None = None
    mesh_scale: tuple[float, float, float] = (1.0, 1.0, 1.0)
    name: str = ""
    field: str = ""

    def to_mapping(self, named: bool = True) -> dict[str, Any]:
        """The shape as the task's YAML gives it (``named``: with its name, as a cell shape)."""
        body: dict[str, Any]
        if self.kind == "box":
            body = {"size": list(self.dimensions_m)}
        elif self.kind == "cylinder":
            body = {"radius": self.dimensions_m[0], "length": self.dimensions_m[1]}
        elif self.kind == "sphere":
            body = {"radius": self.dimensions_m[0]}
        else:
            scale = self.mesh_scale
            body = {"file": self.mesh_file, "scale": scale[0] if len(set(scale)) == 1 else list(scale)}
        out: dict[str, Any] = {"name": self.name} if named else {}
        return {**out, self.kind: body, "xyz": list(self.xyz), "rpy_deg": list(self.rpy_deg)}


@dataclass(frozen=True)
class CollisionSettings:
    """The task's ``collision`` key.

    Attributes:
        clearance_mm: every checked pair stays at least this far apart [mm].
        self_collision: robot bodies are checked against each other.
        srdf: a MoveIt SRDF (absolute path) whose ``<disable_collisions>`` pairs are skipped; None:
            ``<urdf stem>.srdf`` beside the URDF if there is one.
        allow: further pairs never checked (URDF link names, ``tool``, cell names), as given.
    """

    clearance_mm: float = 0.0
    self_collision: bool = True
    srdf: str | None = None
    allow: tuple[tuple[str, str], ...] = ()

    def to_mapping(self) -> dict[str, Any]:
        out: dict[str, Any] = {"clearance_mm": self.clearance_mm, "self": self.self_collision}
        if self.srdf is not None:
            out["srdf"] = self.srdf
        return {**out, "allow": [list(p) for p in self.allow]}


def _triple(values: Sequence[Any]) -> tuple[float, float, float]:
    x, y, z = (float(v) for v in values)
    return x, y, z
