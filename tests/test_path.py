"""Path geometry against closed forms."""

from __future__ import annotations

import math

import numpy as np
import pinocchio as pin
import pytest
from hypothesis import assume, given, settings
from hypothesis import strategies as st

from singplan.errors import TaskError
from singplan.kinematics.geometry import (
    rotation_angle,
    rotation_angles,
    rotation_log_jacobians,
    rotation_logs,
    rpy_deg_to_rotation,
)
from singplan.planning.path.cartesian import make_circ, make_lin


def se3(xyz: list[float], rpy_deg: list[float]) -> pin.SE3:
    return pin.SE3(rpy_deg_to_rotation(rpy_deg), np.array(xyz, dtype=float))


def test_rpy_convention_is_urdf_fixed_axes() -> None:
    r, p, y = np.radians([10.0, 20.0, 30.0])
    Rz = pin.AngleAxis(y, np.array([0, 0, 1.0])).matrix()
    Ry = pin.AngleAxis(p, np.array([0, 1.0, 0])).matrix()
    Rx = pin.AngleAxis(r, np.array([1.0, 0, 0])).matrix()
    np.testing.assert_allclose(rpy_deg_to_rotation([10, 20, 30]), Rz @ Ry @ Rx, atol=1e-15)


def test_slerp_rotations_match_pinocchio_exp3(rng) -> None:
    for k in range(20):
        a = se3([0.5, 0.1, 0.8], list(rng.uniform(-170, 170, size=3)))
        b = a if k == 0 else se3([0.6, 0.0, 0.7], list(rng.uniform(-170, 170, size=3)))  # k = 0: no turn
        if rotation_angle(a.rotation, b.rotation) > 3.0:
            continue
        piece = make_lin(a, b, "m")
        u = rng.uniform(0, 1, size=5)
        for uk, R in zip(u, piece.rotations(u), strict=True):
            np.testing.assert_allclose(R, a.rotation @ pin.exp3(uk * piece.rotation_vector), atol=1e-14)


def test_lin_is_a_straight_line_at_constant_rotation_rate() -> None:
    a, b = se3([0.5, 0.1, 0.8], [170, 10, 0]), se3([0.8, -0.2, 0.6], [150, 30, 40])
    piece = make_lin(a, b, "moves[0].lin")
    u = np.linspace(0, 1, 101)
    p = piece.positions(u)
    np.testing.assert_allclose(p, a.translation + u[:, None] * (b.translation - a.translation), atol=1e-15)
    assert math.isclose(piece.length_m, float(np.linalg.norm(b.translation - a.translation)))
    R = piece.rotations(u)
    np.testing.assert_allclose(R[0], a.rotation, atol=1e-14)
    np.testing.assert_allclose(R[-1], b.rotation, atol=1e-14)
    angles = [rotation_angle(R[0], Rk) for Rk in R]
    np.testing.assert_allclose(angles, u * piece.rotation_rad, atol=1e-12)


@pytest.mark.parametrize("kind", ["lin", "circ"])
def test_velocity_is_the_central_difference_of_the_poses(kind: str) -> None:
    a, b = se3([0.5, 0.1, 0.8], [170, 10, 0]), se3([0.8, -0.2, 0.6], [150, 30, 40])
    piece = make_lin(a, b, "m") if kind == "lin" else make_circ(a, np.array([0.7, 0.05, 0.75]), b, "m")
    h = 1e-6
    for u in (0.1, 0.37, 0.9):
        T0, T1 = piece.poses(np.array([u - h, u + h]))
        v = (T1[:3, 3] - T0[:3, 3]) / (2 * h)
        w = T0[:3, :3] @ pin.log3(T0[:3, :3].T @ T1[:3, :3]) / (2 * h)
        np.testing.assert_allclose(piece.velocity(u), np.concatenate([v, w]), atol=1e-7)


def test_circ_passes_through_via_on_its_circle() -> None:
    a, via, b = np.array([1.0, 0.0, 0.5]), np.array([0.9, 0.3, 0.55]), np.array([0.6, 0.4, 0.6])
    piece = make_circ(se3(list(a), [180, 0, 0]), via, se3(list(b), [170, 0, 20]), "moves[0].circ")
    u = np.linspace(0, 1, 2001)
    p = piece.positions(u)
    np.testing.assert_allclose(np.linalg.norm(p - piece.center, axis=1), piece.radius, atol=1e-12)
    np.testing.assert_allclose((p - piece.center) @ piece.normal, 0.0, atol=1e-12)
    np.testing.assert_allclose(p[0], a, atol=1e-12)
    np.testing.assert_allclose(p[-1], b, atol=1e-12)
    assert np.min(np.linalg.norm(p - via, axis=1)) < piece.length_m / 2000
    steps = np.linalg.norm(np.diff(p, axis=0), axis=1)
    np.testing.assert_allclose(steps, piece.length_m / 2000, rtol=1e-6)  # constant speed in u


def test_degenerate_circ_and_half_turn_are_bad_input() -> None:
    a, b = se3([1, 0, 0.5], [180, 0, 0]), se3([0.6, 0.4, 0.5], [180, 0, 0])
    with pytest.raises(TaskError, match="start, via and end are collinear or coincide: no unique circle") as info:
        make_circ(a, np.array([0.8, 0.2, 0.5]), b, "moves[3].circ")
    assert info.value.field == "moves[3].circ.via"
    with pytest.raises(TaskError, match=r"the orientation turns 180\.0000 deg: a 180 deg turn is ambiguous") as info:
        make_lin(se3([1, 0, 0.5], [0, 0, 0]), se3([1, 0.1, 0.5], [0, 0, 180]), "moves[1].lin")
    assert info.value.field == "moves[1].lin.to.rpy_deg"


def test_rotation_angles_equal_pinocchio_log3_pair_by_pair() -> None:
    """The batch angle against log3 per pair: random pairs, tiny angles (1e-14 .. 1e-6 rad) where
    a cosine alone would lose them, and angles within 1e-9 of pi."""
    rng = np.random.default_rng(11)
    R_a = np.array([pin.exp3(rng.normal(size=3)) for _ in range(300)])
    axes = rng.normal(size=(300, 3))
    axes /= np.linalg.norm(axes, axis=1)[:, None]
    angles = np.concatenate([rng.uniform(0, np.pi, 100), 10.0 ** rng.uniform(-14, -6, 100),
                             np.pi - 10.0 ** rng.uniform(-9, -3, 100)])
    R_b = np.array([Ra @ pin.exp3(axis * angle) for Ra, axis, angle in zip(R_a, axes, angles, strict=True)])
    batch = rotation_angles(R_a, R_b)
    one_by_one = np.array([rotation_angle(Ra, Rb) for Ra, Rb in zip(R_a, R_b, strict=True)])
    np.testing.assert_allclose(batch, one_by_one, rtol=1e-9, atol=1e-15)
    np.testing.assert_allclose(batch[:200], angles[:200], rtol=1e-8, atol=1e-15)


def _rotations_of_every_size(rng: np.random.Generator) -> tuple[np.ndarray, np.ndarray]:
    """Rotations (N, 3, 3) and their rotation vectors (N, 3): random axes at angles from 0 and 1e-14
    rad up to within 1e-9 of a half turn, across the batch formulas' switch points."""
    angles = np.concatenate([[0.0], 10.0 ** rng.uniform(-14, -3, 60), rng.uniform(0, np.pi, 60), [1e-4, 2e-4],
                             np.pi - 10.0 ** rng.uniform(-9, -1, 60)])
    axes = rng.normal(size=(len(angles), 3))
    logs = axes / np.linalg.norm(axes, axis=1)[:, None] * angles[:, None]
    return np.array([pin.exp3(w) for w in logs]), logs


HALF_TURNS = np.array([np.diag([1.0, -1.0, -1.0]), np.diag([-1.0, 1.0, -1.0]), np.diag([-1.0, -1.0, 1.0])])


def test_rotation_logs_equal_pinocchio_log3_one_by_one() -> None:
    """Against the rotation vectors the rotations were made from (to 1e-15 rad up to 1e-3 rad, where
    the small-angle series decides, and 1e-12 up to 3 rad), Pinocchio's log3 everywhere, and
    exp3 of each log giving its rotation back, exact half turns too, with no floating-point warning."""
    M, logs = _rotations_of_every_size(np.random.default_rng(21))
    with np.errstate(all="raise"):
        batch = rotation_logs(np.concatenate([M, HALF_TURNS]))
    np.testing.assert_allclose([pin.exp3(w) for w in batch], np.concatenate([M, HALF_TURNS]), rtol=0.0, atol=1e-13)
    np.testing.assert_allclose(np.linalg.norm(batch[len(M):], axis=1), np.pi, rtol=0.0, atol=1e-15)
    batch = batch[:len(M)]
    np.testing.assert_allclose(batch, np.array([pin.log3(m) for m in M]), rtol=0.0, atol=1e-10)
    theta = np.linalg.norm(logs, axis=1)
    small, away = theta <= 1e-3, theta < 3.0  # nearer a half turn the rotation itself pins its log less well
    np.testing.assert_allclose(batch[small], logs[small], rtol=0.0, atol=1e-15)
    np.testing.assert_allclose(batch[away], logs[away], rtol=0.0, atol=1e-12)


def _jlog3_reference(logs: np.ndarray) -> np.ndarray:
    """Jlog3 (N, 3, 3) in 80-bit floats: the closed form from 1e-2 rad, its series to theta^6 below
    ((theta/2) cot(theta/2) = 1 - theta^2/12 - theta^4/720 - theta^6/30240 - ...)."""
    r = logs.astype(np.longdouble)
    theta = np.sqrt(np.sum(r * r, axis=1))
    t2, closed = theta**2, theta >= 1e-2
    series_diag = 1 - t2 / 12 - t2**2 / 720 - t2**3 / 30240
    series_outer = 1 / 12 + t2 / 720 + t2**2 / 30240 + t2**3 / 1209600
    diag = np.where(closed, theta / 2 / np.tan(np.maximum(theta, 1e-2) / 2), series_diag)
    outer = np.where(closed, (1 - diag) / np.maximum(t2, 1e-4), series_outer)
    skew = np.zeros((len(r), 3, 3), dtype=np.longdouble)
    skew[:, 0, 1], skew[:, 0, 2], skew[:, 1, 2] = -r[:, 2], r[:, 1], -r[:, 0]
    skew -= skew.transpose(0, 2, 1)
    J = diag[:, None, None] * np.eye(3) + outer[:, None, None] * r[:, :, None] * r[:, None, :] + skew / 2
    return J.astype(float)


def test_rotation_log_jacobians_match_finite_differences_and_pinocchio() -> None:
    """d log3(R exp(dw)) / dw against an 80-bit evaluation of the closed form and its series (to
    1e-14, every angle: the small-angle terms are 1e-9 at 1e-4 rad), central differences (h = 1e-6
    rad, up to 3 rad: nearer a half turn the log's derivatives grow and so does the differences'
    error), and Pinocchio's Jlog3 (off by ~3e-9 near its own small-angle switch, 2e-4 rad)."""
    M, logs = _rotations_of_every_size(np.random.default_rng(22))
    batch_logs = rotation_logs(M)
    J = rotation_log_jacobians(batch_logs)
    np.testing.assert_allclose(J, _jlog3_reference(batch_logs), rtol=0.0, atol=1e-14)
    h = 1e-6
    for k in range(len(M)):
        np.testing.assert_allclose(J[k], pin.Jlog3(M[k]), rtol=0.0, atol=5e-9)
        if np.linalg.norm(logs[k]) >= 3.0:
            continue
        fd = np.array([(pin.log3(M[k] @ pin.exp3(h * e)) - pin.log3(M[k] @ pin.exp3(-h * e))) / (2 * h)
                       for e in np.eye(3)]).T
        np.testing.assert_allclose(J[k], fd, rtol=0.0, atol=1e-8)


_point = st.lists(st.floats(-1.0, 1.0), min_size=3, max_size=3)


@settings(max_examples=60, deadline=None, derandomize=True)
@given(_point, _point, _point)
def test_any_circ_is_the_circle_through_its_three_points_passing_via_between_them(a: list[float], via: list[float],
                                                                                 b: list[float]) -> None:
    """Geometric checks for every start, via and end: the centre equidistant from the three (in their
    plane), the arc from start about the normal reaching via before the end, its length r * arc."""
    pa, pv, pb = np.array(a), np.array(via), np.array(b)
    try:
        piece = make_circ(se3(a, [180, 0, 0]), pv, se3(b, [170, 0, 20]), "m")
    except TaskError:
        assume(False)  # collinear or coinciding: bad input (tested above)
    assume(piece.radius < 50.0)  # nearly collinear: a huge circle whose round-off is not this test's subject
    assert piece.center is not None and piece.normal is not None
    for p in (pa, pv, pb):
        assert np.linalg.norm(p - piece.center) == pytest.approx(piece.radius, rel=1e-9)
        assert abs((p - piece.center) @ piece.normal) < 1e-9 * max(1.0, piece.radius)
    r_a, r_v = pa - piece.center, pv - piece.center
    via_angle = math.atan2(float(np.cross(r_a, r_v) @ piece.normal), float(r_a @ r_v)) % (2 * math.pi)
    assert 0.0 < via_angle < piece.arc_rad
    np.testing.assert_allclose(piece.positions(np.array([via_angle / piece.arc_rad]))[0], pv, atol=1e-9 * piece.radius)
    assert piece.length_m == pytest.approx(piece.radius * piece.arc_rad, rel=1e-12)
    chords = np.linalg.norm(np.diff(piece.positions(np.linspace(0.0, 1.0, 4001)), axis=0), axis=1)
    assert float(np.sum(chords)) == pytest.approx(piece.length_m, rel=1e-6)  # a fine polyline's length


@settings(max_examples=60, deadline=None, derandomize=True)
@given(_point, st.floats(0.0, 170.0), st.floats(1e-4, 0.05), st.floats(1e-3, 0.2))
def test_the_grid_steps_no_further_and_turns_no_more_than_asked(b: list[float], turn_deg: float, step_m: float,
                                                                step_rad: float) -> None:
    piece = make_lin(se3([0.0, 0.0, 0.0], [0, 0, 0]), se3(b, [turn_deg, 0, 0]), "m")
    grid = piece.grid(step_m, step_rad)
    assert grid[0] == 0.0 and grid[-1] == 1.0 and len(grid) >= 3
    p = piece.positions(grid)
    R = piece.rotations(grid)
    assert np.max(np.linalg.norm(np.diff(p, axis=0), axis=1)) <= step_m * (1 + 1e-9)
    assert max(rotation_angle(R[k], R[k + 1]) for k in range(len(grid) - 1)) <= step_rad * (1 + 1e-9)
    # and no coarser a grid than needed: one interval fewer would break a step
    assert len(grid) - 2 < max(2, piece.length_m / step_m, piece.rotation_rad / step_rad) + 1


def test_sample_deviations_are_the_distances_from_each_samples_pose_to_the_path(rng) -> None:
    from singplan.kinematics.robot import load_robot
    from singplan.planning.path.cartesian import sample_deviations

    robot = load_robot("abb_irb2400")
    q = np.radians([10, 20, 15, 40, 50, -30]) + rng.normal(0.0, 0.05, size=(7, 6))
    piece = make_lin(robot.fk(q[0]), robot.fk(q[-1]), "m")
    u = np.linspace(0.0, 1.0, 7)
    pos, ori = sample_deviations(robot, piece, u, q)
    for k in range(7):
        T, want = robot.fk(q[k]), piece.poses(u[k:k + 1])[0]
        assert pos[k] == pytest.approx(np.linalg.norm(T.translation - want[:3, 3]), abs=1e-12)
        assert ori[k] == pytest.approx(np.linalg.norm(pin.log3(want[:3, :3].T @ T.rotation)), abs=1e-9)
    assert pos[0] < 1e-12 and pos[-1] < 1e-12 and pos[3] > 1e-4  # the ends on the path, the middle off it
    assert np.all(sample_deviations(robot, None, u, q)[0] == 0.0)  # a PTP has no path to leave
