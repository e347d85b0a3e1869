"""The bundled arms' collision shapes and SRDFs (robots/generate_urdfs.py): the shapes enclose the
visuals (points sampled on every visual surface lie inside a collision shape of the same link), every
SRDF pair names two links of its URDF, and the arms plan their public programs clear of themselves."""

from __future__ import annotations

import xml.etree.ElementTree as ET

import numpy as np
import pinocchio as pin
import pytest

from singplan.kinematics.clearance import check_clearance
from singplan.kinematics.collision import collision_model
from singplan.kinematics.robot import bundled_robots, load_robot

BUNDLED = [name for name, entry in bundled_robots().items() if entry.urdf_file is not None and entry.family == "opw"]


def _origin(element: ET.Element) -> np.ndarray:
    origin = element.find("origin")
    xyz = [float(v) for v in (origin.get("xyz", "0 0 0") if origin is not None else "0 0 0").split()]
    rpy = [float(v) for v in (origin.get("rpy", "0 0 0") if origin is not None else "0 0 0").split()]
    T = np.eye(4)
    T[:3, :3] = pin.rpy.rpyToMatrix(*rpy)
    T[:3, 3] = xyz
    return T


def _cylinders(link: ET.Element, tag: str) -> list[tuple[np.ndarray, float, float]]:
    """(placement in the link frame, radius, length) of each cylinder of the link's <visual> or <collision>."""
    out = []
    for element in link.findall(tag):
        cylinder = element.find("geometry/cylinder")
        assert cylinder is not None, f"{link.get('name')}: only cylinders are generated"
        out.append((_origin(element), float(cylinder.get("radius")), float(cylinder.get("length"))))
    return out


def _surface_points(radius: float, length: float, rng: np.random.Generator, n: int = 300) -> np.ndarray:
    """Points on a cylinder's side, rims and caps (its own frame, axis z)."""
    angle = rng.uniform(0.0, 2 * np.pi, n)
    z = rng.uniform(-length / 2, length / 2, n)
    z[: n // 3] = np.where(rng.random(n // 3) < 0.5, -length / 2, length / 2)  # on the caps ...
    r = np.full(n, radius)
    r[: n // 6] = radius * np.sqrt(rng.random(n // 6))  # ... inside them and on their rims
    return np.column_stack([r * np.cos(angle), r * np.sin(angle), z])


@pytest.mark.parametrize("name", BUNDLED)
def test_collision_shapes_enclose_the_visuals(name: str) -> None:
    root = ET.parse(bundled_robots()[name].urdf_path()).getroot()
    rng = np.random.default_rng(7)
    counted = 0
    for link in root.iter("link"):
        visuals, collisions = _cylinders(link, "visual"), _cylinders(link, "collision")
        assert bool(visuals) == bool(collisions), link.get("name")
        for T_visual, radius, length in visuals:
            points = _surface_points(radius, length, rng) @ T_visual[:3, :3].T + T_visual[:3, 3]
            inside = np.zeros(len(points), dtype=bool)
            for T_coll, r_c, l_c in collisions:
                local = (points - T_coll[:3, 3]) @ T_coll[:3, :3]  # into the collision cylinder's frame
                inside |= (np.hypot(local[:, 0], local[:, 1]) <= r_c + 1e-12) & (np.abs(local[:, 2]) <= l_c / 2 + 1e-12)
            assert inside.all(), f"{name} {link.get('name')}: {np.count_nonzero(~inside)} visual points outside"
            counted += len(points)
    assert counted > 1000


@pytest.mark.parametrize("name", BUNDLED)
def test_every_bundled_arm_has_an_srdf_of_its_own_links(name: str) -> None:
    urdf = bundled_robots()[name].urdf_path()
    srdf = urdf.with_suffix(".srdf")
    links = {link.get("name") for link in ET.parse(urdf).getroot().iter("link")}
    pairs = [(e.get("link1"), e.get("link2"), e.get("reason")) for e in ET.parse(srdf).getroot().iter(
        "disable_collisions")]
    assert pairs and all(a in links and b in links for a, b, _ in pairs)
    assert {reason for _, _, reason in pairs} <= {"Adjacent", "Default", "Always", "Never"}
    model = collision_model(load_robot(name))
    assert model.srdf == srdf and model.self_collision
    checked = {frozenset(p.names) for p in model.pairs}
    assert checked and not checked & {frozenset((a, b)) for a, b, _ in pairs}
    assert frozenset(("base_link", "link_6")) in checked or "base_link" not in {b.name for b in model.bodies}


@pytest.mark.parametrize("name", BUNDLED)
def test_the_home_position_is_clear_of_itself(name: str) -> None:
    """Every arm at its zero joints (clipped to its limits) is clear of itself with its SRDF."""
    robot = load_robot(name)
    model = collision_model(robot)
    zero = np.clip(np.zeros(robot.n_joints), robot.lower_rad, robot.upper_rad)
    assert check_clearance(model, zero[None]).clear
