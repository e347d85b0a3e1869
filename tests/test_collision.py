"""Collision geometry and the clearance check (singplan.kinematics.collision, .clearance), against
brute force: every pair measured at every sample, and the motion between samples sub-sampled densely."""

from __future__ import annotations

import math
import struct
from pathlib import Path

import coal
import numpy as np
import pinocchio as pin
import pytest

from singplan.errors import RobotModelError, TaskError
from singplan.kinematics.clearance import BETWEEN_TOLERANCE_M, EXACT_M, check_clearance, segment_distances
from singplan.kinematics.collision import collision_model, load_mesh
from singplan.kinematics.robot import Robot, load_robot
from singplan.kinematics.shapes import CollisionSettings, Shape
from tests.conftest import erd_urdf

UR5_START = np.radians([0.0, -100.0, 100.0, -90.0, -90.0, 0.0])
UR5_SRDF = Path(erd_urdf("ur5")).parents[1] / "srdf" / "ur5.srdf"


def _cylinder(name: str, radius: float, length: float, xyz: tuple[float, float, float]) -> Shape:
    return Shape("cylinder", (radius, length), xyz, name=name, field=f"cell[{name}]")


def _brute(model, robot: Robot, q: np.ndarray) -> np.ndarray:
    """(N, pairs) distances at every sample."""
    R, P = robot.joint_frames(q)
    return np.array([[model.pair_distance(p, R[k], P[k]).distance_m for p in model.pairs] for k in range(len(q))])


def test_segment_distances_match_dense_sampling(rng: np.random.Generator) -> None:
    n = 150
    p1, q1, p2, q2 = (rng.normal(size=(n, 3)) for _ in range(4))
    q1[:20] = p1[:20]  # points
    q2[10:30] = p2[10:30]
    q2[60:90] = p2[60:90] + 0.7 * (q1[60:90] - p1[60:90])  # parallel segments
    d = segment_distances(p1, q1, p2, q2)
    s = np.linspace(0.0, 1.0, 401)
    for i in range(n):
        a = p1[i] + np.outer(s, q1[i] - p1[i])
        b = p2[i] + np.outer(s, q2[i] - p2[i])
        dense = np.min(np.linalg.norm(a[:, None] - b[None], axis=2))
        assert d[i] <= dense + 1e-12  # never above the true distance (a lower bound must hold) ...
        assert d[i] >= dense - 4e-3  # ... and the sampled one is at most a grid step above it


@pytest.fixture(scope="module")
def ur5() -> Robot:
    return load_robot(erd_urdf("ur5"), tip="tool0")


def test_least_clearance_per_span_is_the_brute_force_least_within_its_tolerance(ur5: Robot) -> None:
    rng = np.random.default_rng(3)
    cell = (_cylinder("post", 0.04, 1.1, (-0.1, -0.3, 0.45)),
            Shape("box", (1.0, 1.0, 0.05), (0.3, 0.0, -0.05), name="table", field="cell[1]"))
    model = collision_model(ur5, cell=cell, settings=CollisionSettings(5.0))
    for _ in range(2):
        a = UR5_START + rng.normal(0.0, 0.3, 6)
        q = np.linspace(a, a + rng.normal(0.0, 0.6, 6), 80)
        found = check_clearance(model, q, spans=[(0, 39), (39, 79)])
        brute = _brute(model, ur5, q)
        for (k0, k1), least in zip([(0, 39), (39, 79)], found.least, strict=True):
            true = brute[k0:k1 + 1].min()
            assert least is not None
            assert true - 1e-9 <= least.distance_m <= true + EXACT_M
            k = least.sample
            assert brute[k, [p.names for p in model.pairs].index(least.bodies)] == pytest.approx(least.distance_m)
        assert found.clear == bool(brute.min() >= model.clearance_m)


def test_separating_planes_bound_every_shape_pair_and_are_exact_where_measured() -> None:
    """The planes of one measurement, a shape pair each (link_1 and link_4 of the KR 6 have two
    cylinders each), never exceed the brute-force distance near it and equal it where measured; so
    a long slow motion whose closest pair barely changes needs a few measurements, not one a sample."""
    from singplan.kinematics.clearance import _PLANE_REACH, _Relative
    from singplan.kinematics.collision import ShapeGap

    kuka = load_robot("kuka_kr6_r900_2")
    model = collision_model(kuka, settings=CollisionSettings(0.0))
    pair = next(p for p in model.pairs if set(p.names) == {"link_1", "link_4"})
    assert len(pair.a.geoms) * len(pair.b.geoms) > 1
    a = np.radians([30.0, -70.0, 100.0, 60.0, -15.0, -10.0])
    q = np.linspace(a, a + np.radians([0.0, 8.0, -9.0, 20.0, 5.0, 1.0]), 400)
    brute = _brute(model, kuka, q)[:, model.pairs.index(pair)]
    R, P = kuka.joint_frames(q)
    relative = _Relative(pair, R, P)
    for i in (0, 150, 399):
        gaps: list[ShapeGap] = []
        found = model.pair_distance(pair, R[i], P[i], gaps=gaps)
        planes = relative.plane_bounds(i, gaps)
        assert planes is not None
        lo, bounds = planes
        assert lo == max(i - _PLANE_REACH, 0) and len(bounds) == min(len(q), i + _PLANE_REACH + 1) - lo
        assert np.all(bounds <= brute[lo:lo + len(bounds)] + 1e-12)
        assert bounds[i - lo] == pytest.approx(found.distance_m, abs=1e-9)
        assert np.max(brute[lo:lo + len(bounds)] - bounds) < 5e-3  # second order in the turn (8 deg of A2 here)
    checked = check_clearance(model, q)
    assert checked.least[0] is not None
    assert brute.min() - 1e-9 <= checked.closest.distance_m <= brute.min() + EXACT_M
    assert checked.distance_calls < 40 * len(model.pairs)  # not the 400 samples a pair


def test_the_compiled_support_of_each_shape_kind_is_the_support_function(tmp_path: Path) -> None:
    """The planes' compiled least of n . x over a shape of b (sphere, box, cylinder, a mesh's hull) at
    many placements equals collision.support applied as numpy would."""
    from singplan.kinematics.clearance import _low_b, _support_form
    from singplan.kinematics.collision import _shape_geom, support

    rng = np.random.default_rng(11)
    mesh = str(_stl_cube(tmp_path / "cube.stl", 0.05))
    shapes = [Shape("sphere", (0.07,), (0.1, 0.0, 0.2), (10.0, 20.0, 30.0)),
              Shape("box", (0.1, 0.2, 0.3), (0.0, 0.1, 0.0), (0.0, 45.0, 10.0)),
              Shape("cylinder", (0.04, 0.5), (0.2, 0.0, 0.1), (90.0, 0.0, 0.0)),
              Shape("mesh", (), (0.0, 0.0, 0.3), (5.0, 5.0, 5.0), mesh_file=mesh, mesh_scale=(1.0, 2.0, 3.0))]
    R = np.array([pin.rpy.rpyToMatrix(*rng.uniform(-3.0, 3.0, 3)) for _ in range(40)])
    t = rng.normal(size=(40, 3))
    n = rng.normal(size=3)
    n /= np.linalg.norm(n)
    for shape in shapes:
        g = _shape_geom(shape, pin.SE3.Identity())
        nb = n @ R
        expected = t @ n + nb @ g.translation + support(g, nb @ g.rotation)
        np.testing.assert_allclose(_low_b(R, t, n, g.translation, g.rotation, *_support_form(g)), expected,
                                   rtol=0.0, atol=1e-14)


def test_a_collision_between_two_clear_samples_is_found(ur5: Robot) -> None:
    """A post between two samples far apart: both samples clear, the motion through it is not."""
    q0 = UR5_START.copy()
    q1 = q0 + np.radians([80.0, 0, 0, 0, 0, 0])
    mid = ur5.joint_frames(((q0 + q1) / 2)[None])
    wrist = mid[1][0, 5]  # the wrist_2 joint's origin half way
    model = collision_model(ur5, cell=(_cylinder("post", 0.03, 2.0, (wrist[0], wrist[1], 1.0)),),
                            settings=CollisionSettings(0.0, self_collision=False))
    brute = _brute(model, ur5, np.array([q0, q1]))
    assert brute.min() > 0.05  # the samples themselves are clear
    found = check_clearance(model, np.array([q0, q1]))
    assert not found.clear
    contact = found.contacts[0]
    assert contact.between and contact.sample == 0 and 0.0 < contact.fraction < 1.0
    dense = _brute(model, ur5, np.linspace(q0, q1, 401))
    assert dense.min() < 0.0
    assert contact.distance_m < BETWEEN_TOLERANCE_M


def test_motion_clear_at_samples_is_clear_between_them_to_the_tolerance(ur5: Robot) -> None:
    """Where the check says clear, dense sub-sampling finds no pair below clearance - tolerance."""
    rng = np.random.default_rng(8)
    cell = (_cylinder("post", 0.04, 1.1, (-0.1, -0.3, 0.45)),
            Shape("box", (1.0, 1.0, 0.05), (0.3, 0.0, -0.05), name="table", field="cell[1]"))
    model = collision_model(ur5, cell=cell, settings=CollisionSettings(20.0, self_collision=False))
    checked = 0
    for _ in range(4):
        a = UR5_START + rng.normal(0.0, 0.4, 6)
        q = np.linspace(a, a + rng.normal(0.0, 0.5, 6), 6)  # few samples: large motion between them
        if not check_clearance(model, q).clear:
            continue
        checked += 1
        dense = _brute(model, ur5, np.concatenate([np.linspace(q[k], q[k + 1], 40) for k in range(len(q) - 1)]))
        assert dense.min() >= model.clearance_m - BETWEEN_TOLERANCE_M
    assert checked >= 2


def _stl_cube(path: Path, half: float) -> Path:
    """A binary STL cube of half edge ``half`` [m] centred on the origin."""
    c = np.array([[x, y, z] for x in (-half, half) for y in (-half, half) for z in (-half, half)])
    faces = [(0, 1, 3), (0, 3, 2), (4, 6, 7), (4, 7, 5), (0, 4, 5), (0, 5, 1), (2, 3, 7), (2, 7, 6), (0, 2, 6),
             (0, 6, 4), (1, 5, 7), (1, 7, 3)]
    data = bytearray(b"\0" * 80 + struct.pack("<I", len(faces)))
    for f in faces:
        data += struct.pack("<3f", 0, 0, 0) + b"".join(struct.pack("<3f", *c[i]) for i in f) + b"\0\0"
    path.write_bytes(bytes(data))
    return path


def test_a_body_wholly_inside_a_mesh_at_the_start_is_a_collision(ur5: Robot, tmp_path: Path) -> None:
    """A small tool sphere inside a mesh crate (only that pair checked)."""
    tip = ur5.fk_tip(UR5_START)
    centre = tip.act(np.array([0.0, 0.0, 0.2]))
    cube = Shape("mesh", (), tuple(centre), mesh_file=str(_stl_cube(tmp_path / "cube.stl", 0.05)), name="crate",
                 field="cell[0]")
    links = [b.name for b in collision_model(ur5).bodies]
    model = collision_model(ur5, tool=(Shape("sphere", (0.01,), (0.0, 0.0, 0.2), name="tool"),), cell=(cube,),
                            settings=CollisionSettings(0.0, self_collision=False,
                                                       allow=tuple((link, "crate") for link in links)))
    assert [p.names for p in model.pairs] == [("tool", "crate")]
    inside = check_clearance(model, UR5_START[None], start=True)
    assert not inside.clear and inside.contacts[0].distance_m == -math.inf
    assert check_clearance(model, UR5_START[None], start=False).clear  # coal alone sees the surface only


def test_meshes_read_through_the_bounded_reader(tmp_path: Path) -> None:
    mesh = load_mesh(_stl_cube(tmp_path / "cube.stl", 0.05), (2.0, 2.0, 2.0))
    assert mesh.num_tris == 12 and np.allclose(np.abs(np.array(mesh.vertices())), 0.1)
    (tmp_path / "bad.stl").write_text("solid not really\n this is no mesh\n")
    with pytest.raises(Exception, match="cannot be read as a mesh"):
        load_mesh(tmp_path / "bad.stl", (1.0, 1.0, 1.0))
    with pytest.raises(Exception, match="no such mesh"):
        load_mesh(tmp_path / "missing.stl", (1.0, 1.0, 1.0))


def test_pairs_follow_the_urdf_tree_the_srdf_and_allow(ur5: Robot) -> None:
    model = collision_model(ur5, tool=(Shape("sphere", (0.03,), (0.0, 0.0, 0.05), name="tool"),),
                            cell=(_cylinder("post", 0.04, 1.1, (-0.1, -0.3, 0.45)),),
                            settings=CollisionSettings(0.0, allow=(("base_link", "post"),)))
    names = {frozenset(p.names) for p in model.pairs}
    assert frozenset(("shoulder_link", "upper_arm_link")) not in names  # one joint apart
    assert frozenset(("wrist_3_link", "ee_link")) not in names  # one rigid group (a fixed joint)
    assert frozenset(("tool", "ee_link")) not in names  # the tool on the tip's link
    assert frozenset(("tool", "wrist_2_link")) in names  # ... but not adjacent to its parent
    assert frozenset(("base_link", "post")) not in names and frozenset(("shoulder_link", "post")) in names
    assert frozenset(("forearm_link", "wrist_2_link")) in names  # no SRDF given, none beside the URDF
    with_srdf = collision_model(ur5, settings=CollisionSettings(0.0, srdf=str(UR5_SRDF)))
    assert frozenset(("forearm_link", "wrist_2_link")) not in {frozenset(p.names) for p in with_srdf.pairs}
    assert with_srdf.skipped["srdf"] > 0


def test_panda_fingers_are_their_own_groups_as_in_the_urdf() -> None:
    """The planned chain locks the fingers, but the pairs follow the URDF's tree (as the checker does):
    the two fingers are checked against each other unless an SRDF or allow says otherwise."""
    panda = load_robot(erd_urdf("panda"))
    model = collision_model(panda, settings=CollisionSettings(0.0))
    names = {frozenset(p.names) for p in model.pairs}
    assert frozenset(("panda_leftfinger", "panda_rightfinger")) in names
    assert frozenset(("panda_hand", "panda_leftfinger")) not in names  # one (prismatic) joint apart
    default = collision_model(panda, start=np.zeros(7))  # no collision key, no SRDF: contacts at rest left out
    assert frozenset(("panda_leftfinger", "panda_rightfinger")) not in {frozenset(p.names) for p in default.pairs}
    assert default.skipped["resting"] >= 1 and "touching at the zero or start" in default.notes[-1]


def test_allow_and_cell_names_are_checked_against_the_robot(ur5: Robot) -> None:
    with pytest.raises(TaskError, match=r"collision.allow\[0\]\[1\]: unknown body 'pst'; did you mean 'post'"):
        collision_model(ur5, cell=(_cylinder("post", 0.04, 1.1, (0, 0, 0)),),
                        settings=CollisionSettings(allow=(("base_link", "pst"),)))
    with pytest.raises(TaskError, match=r"cell\[forearm_link\].name: 'forearm_link' is a link"):
        collision_model(ur5, cell=(_cylinder("forearm_link", 0.04, 1.1, (0, 0, 0)),))


def test_a_urdf_collision_mesh_that_is_missing_is_named(tmp_path: Path) -> None:
    text = Path(erd_urdf("ur5")).read_text()
    broken = tmp_path / "ur5_broken.urdf"
    broken.write_text(text.replace("meshes/ur5/collision/forearm.stl", "meshes/ur5/collision/nothing.stl"))
    robot = load_robot(broken, tip="tool0")
    with pytest.raises(RobotModelError, match=r"link 'forearm_link': collision mesh .*nothing\.stl.* not found"):
        collision_model(robot)


def test_hull_distances_bound_the_mesh_distances(ur5: Robot) -> None:
    """The convex hulls answer first: their distance never exceeds the mesh's."""
    model = collision_model(ur5, settings=CollisionSettings(0.0))
    rng = np.random.default_rng(5)
    q = UR5_START + rng.normal(0.0, 0.8, (40, 6))
    R, P = ur5.joint_frames(q)
    for pair in model.pairs:
        for k in range(0, 40, 7):
            exact = model.pair_distance(pair, R[k], P[k]).distance_m
            bound = model.pair_distance(pair, R[k], P[k], enough=-1.0)
            assert bound.distance_m <= exact + 1e-9
    assert isinstance(model.bodies[0].geoms[0].hull, coal.ConvexBase)
