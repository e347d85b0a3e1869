"""Stopping distance (SEEDS 002 glide path; singplan/stopping.py)."""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pinocchio as pin
import pytest

import singplan.kinematics.stopping as stopping
from singplan.cli import main
from singplan.errors import SingplanError
from singplan.kinematics.robot import Robot, load_robot
from singplan.kinematics.stopping import (
    braking_joints,
    mean_norm,
    reach_bounds,
    rest_speed_bounds,
    scaled_stopping_bound,
    stopping_bound,
    stopping_distances,
    travel,
)
from singplan.outputs.viewer import robot_of
from singplan.results.detect import detect
from singplan.results.plan import plan
from singplan.results.trajectory import load, save
from singplan.task.load import parse_task

from .task_strategies import seeded_task

ACC = 10.0


@pytest.fixture(scope="module")
def abb() -> Robot:
    return load_robot("abb_irb2400")


def _polyline(robot: Robot, q: np.ndarray, qd: np.ndarray, acc: np.ndarray, steps: int) -> np.ndarray:
    """The definition by brute force: the TCP polyline through ``steps`` equal time steps of the braking."""
    out = np.zeros(len(q))
    for k in range(len(q)):
        T = float(np.max(np.abs(qd[k]) / acc))
        t = np.linspace(0.0, T, steps + 1)[None, :]
        xyz = robot.tcp_positions(braking_joints(q[k:k + 1], qd[k:k + 1], acc, t)[0])
        out[k] = np.linalg.norm(np.diff(xyz, axis=0), axis=1).sum()
    return out


def test_one_turning_joint_brakes_along_its_circle(abb: Robot) -> None:
    """Axis 1 alone, hand-computed: the TCP turns about the vertical axis through the base on a circle of
    radius r = hypot(x, y), by w^2 / (2 a) rad, so it travels r w^2 / (2 a)."""
    q = np.radians([10.0, 20.0, -10.0, 30.0, 40.0, 50.0])
    np.testing.assert_allclose(abb.jacobian(q)[3:, 0], [0, 0, 1], atol=1e-12)  # axis 1 vertical ...
    np.testing.assert_allclose(abb.joint_placements(q)[0].translation[:2], [0, 0], atol=1e-12)  # ... through 0
    x, y, _ = abb.fk(q).translation
    for w in (0.1, 1.0, 2.5):
        qd = np.array([[w, 0, 0, 0, 0, 0]])
        expected = math.hypot(x, y) * w**2 / (2 * ACC)
        assert stopping_distances(abb, q[None], qd, np.full(6, ACC))[0] == pytest.approx(expected, rel=1e-12)
        assert stopping_distances(abb, q[None], -qd, np.full(6, ACC))[0] == pytest.approx(expected, rel=1e-12)


@pytest.mark.parametrize("name", ["abb_irb2400", "ur5", "kuka_kr6_r900_2"])
def test_the_figure_is_within_one_percent_of_a_fine_polyline(name: str) -> None:
    """Random states, every joint at up to its speed limit (times 1, 0.3, 0.03) in any direction,
    against the polyline through 10 000 steps of forward kinematics (finite differences of positions)."""
    robot = load_robot(name)
    rng = np.random.default_rng(7)
    acc = rng.uniform(5.0, 20.0, robot.n_joints)
    for scale in (1.0, 0.3, 0.03):
        q = rng.uniform(0.8 * robot.lower_rad, 0.8 * robot.upper_rad, (12, robot.n_joints))
        qd = rng.uniform(-1.0, 1.0, q.shape) * robot.velocity_rad_s * scale
        reference = _polyline(robot, q, qd, acc, 10_000)
        np.testing.assert_allclose(stopping_distances(robot, q, qd, acc), reference, rtol=0.01)


def test_it_grows_with_speed_and_is_zero_at_rest(abb: Robot) -> None:
    rng = np.random.default_rng(3)
    q = rng.uniform(-1.0, 1.0, (40, 6))
    direction = rng.uniform(-1.0, 1.0, (40, 6)) * abb.velocity_rad_s
    acc = np.full(6, ACC)
    speeds = [0.0, 0.01, 0.1, 0.3, 0.6, 1.0]
    d = np.array([stopping_distances(abb, q, s * direction, acc) for s in speeds])  # (speeds, samples)
    assert np.all(d[0] == 0.0)
    assert np.all(np.diff(d, axis=0) > 0.0)
    # slow motion brakes almost along a straight line at a falling speed: the distance goes as speed^2
    np.testing.assert_allclose(d[1] / d[2], 0.01, rtol=0.02)


def test_a_harder_brake_stops_sooner(abb: Robot) -> None:
    rng = np.random.default_rng(4)
    q = rng.uniform(-1.0, 1.0, (20, 6))
    qd = rng.uniform(-1.0, 1.0, (20, 6)) * abb.velocity_rad_s
    assert np.all(stopping_distances(abb, q, qd, np.full(6, 20.0)) < stopping_distances(abb, q, qd, np.full(6, 10.0)))


def test_mean_norm_is_the_integral_of_a_linear_velocity_even_through_a_reversal() -> None:
    rng = np.random.default_rng(5)
    a = rng.normal(size=(200, 3))
    b = rng.normal(size=(200, 3))
    b[:20] = -rng.uniform(0.1, 3.0, (20, 1)) * a[:20]  # the velocity passes through zero
    b[20:40] = a[20:40] * (1 + 1e-9)  # nearly constant
    s = (np.arange(50_000) + 0.5) / 50_000  # midpoint rule
    for k in range(len(a)):
        speed = np.linalg.norm(a[k] + np.outer(s, b[k] - a[k]), axis=1)
        assert mean_norm(a[k], b[k]) == pytest.approx(speed.mean(), rel=1e-7, abs=1e-12)


def test_chunking_changes_nothing(abb: Robot, monkeypatch: pytest.MonkeyPatch) -> None:
    rng = np.random.default_rng(6)
    q = rng.uniform(-1.0, 1.0, (300, 6))
    qd = rng.uniform(-1.0, 1.0, (300, 6)) * abb.velocity_rad_s * rng.uniform(0, 1, (300, 1))
    qd[::7] = 0.0
    whole = stopping_distances(abb, q, qd, np.full(6, ACC))
    monkeypatch.setattr(stopping, "_CHUNK_VALUES", 500)
    np.testing.assert_array_equal(stopping_distances(abb, q, qd, np.full(6, ACC)), whole)


def test_a_planned_trajectory_carries_the_series_its_worst_and_loads_it_back(planned_kuka: Path) -> None:
    traj = load(planned_kuka)
    series = traj.samples["stopping_distance_m"]
    assert series.shape == traj.t.shape and series[0] == 0.0 and series[-1] == 0.0  # at rest at both ends
    k = int(np.argmax(series))
    assert traj.metrics.max_stopping_distance_mm == series[k] * 1e3
    assert traj.metrics.max_stopping_distance_at_s == pytest.approx(traj.t[k])
    robot = robot_of(traj)
    acc = np.broadcast_to(np.asarray(traj.task.limits.acceleration_rad_s2, dtype=float), (robot.n_joints,))
    np.testing.assert_allclose(series, stopping_distances(robot, traj.q, traj.qd, acc), rtol=1e-12, atol=0)
    # the file holds the floats as computed: loading gives the same ones back
    again = load(save(traj, planned_kuka.parent / "again"))
    np.testing.assert_array_equal(again.samples["stopping_distance_m"], series)


def test_plan_and_check_print_the_worst_figure(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    task = Path(__file__).resolve().parents[1] / "singplan" / "demo_task.yaml"
    assert main(["plan", str(task), "-o", str(tmp_path), "--no-report", "--no-replay"]) == 0
    planned = load(tmp_path).metrics.max_stopping_distance_mm
    assert f"stopping distance: up to {planned:.3f} mm" in capsys.readouterr().out
    assert main(["check", str(task)]) == 0
    lines = capsys.readouterr().out.strip().splitlines()
    line = next(x for x in lines if x.startswith("stopping distance: at most "))
    assert line.startswith("stopping distance: at most ") and "a bound for every plan of the task" in line
    bound = float(line.split("at most ")[1].split(" mm")[0])
    assert planned <= bound <= 1.1 * planned  # a bound, and a close one where the plan cruises


# --- the bound `singplan check` gives -----------------------------------------------------------------

@pytest.mark.parametrize("name", ["abb_irb2400", "ur5", "kuka_kr6_r900_2", "panda"])
def test_reach_bounds_hold_in_every_configuration(name: str) -> None:
    """The TCP's distance from each joint axis (the Jacobian column's length), brute force over random
    joints, never exceeds the joint's reach bound; and the bound is met closely somewhere."""
    robot = load_robot(name).with_tool(pin.SE3(np.eye(3), np.array([0.03, -0.02, 0.15])))
    rng = np.random.default_rng(8)
    q = rng.uniform(np.maximum(robot.lower_rad, -np.pi), np.minimum(robot.upper_rad, np.pi), (20_000, robot.n_joints))
    distance = np.linalg.norm(robot.tcp_jacobians(q), axis=1)  # (N, n)
    reach = reach_bounds(robot)
    assert np.all(distance <= reach + 1e-12)
    assert np.all(distance.max(axis=0) >= 0.6 * reach)


def _random_states(robot: Robot, rng: np.random.Generator, count: int) -> tuple[np.ndarray, np.ndarray]:
    q = rng.uniform(0.8 * robot.lower_rad, 0.8 * robot.upper_rad, (count, robot.n_joints))
    qd = rng.uniform(-1.0, 1.0, q.shape) * robot.velocity_rad_s * rng.choice([1.0, 0.3, 0.03], (count, 1))
    return q, qd


@pytest.mark.parametrize("name", ["abb_irb2400", "ur5", "kuka_kr6_r900_2"])
def test_the_joint_by_joint_bound_covers_every_slower_state(name: str) -> None:
    """stopping_bound(q, s) >= the figure of every (q, qd) with |qd_j| <= s_j, whatever the signs:
    random speed bounds, and states under them with random signs and fractions."""
    robot = load_robot(name)
    rng = np.random.default_rng(9)
    acc = rng.uniform(5.0, 20.0, robot.n_joints)
    q, speed = _random_states(robot, rng, 40)
    bound = stopping_bound(robot, q, np.abs(speed), acc)
    for _ in range(5):
        qd = np.abs(speed) * rng.uniform(-1.0, 1.0, speed.shape)
        assert np.all(stopping_distances(robot, q, qd, acc) <= bound)
    moved = rng.uniform(0.0, 0.2, robot.n_joints)  # a state displaced from q: the bound with moved_rad
    shifted = q + moved * rng.uniform(-1.0, 1.0, q.shape)
    assert np.all(stopping_distances(robot, shifted, speed, acc) <= stopping_bound(robot, q, np.abs(speed), acc, moved))


@pytest.mark.parametrize("name", ["abb_irb2400", "ur5", "kuka_kr6_r900_2"])
def test_the_scaled_bound_covers_every_slower_speed_along_a_direction(name: str) -> None:
    """scaled_stopping_bound(q, qd) >= the figure of (q, c qd) for c on a fine grid of [0, 1]."""
    robot = load_robot(name)
    rng = np.random.default_rng(10)
    acc = rng.uniform(5.0, 20.0, robot.n_joints)
    q, qd = _random_states(robot, rng, 30)
    bound = scaled_stopping_bound(robot, q, qd, acc)
    figures = np.array([stopping_distances(robot, q, c * qd, acc) for c in np.linspace(0.0, 1.0, 41)])
    assert np.all(figures <= bound)
    ratio = bound / figures.max(axis=0)  # not a trivial bound: 1.01 x wherever the speed is
    assert np.median(ratio) <= 1.011 and np.max(ratio) < 3.0  # moderate; up to 2.3 x at full speed


def test_a_joint_from_rest_is_no_faster_than_its_travel_allows(planned_kuka: Path) -> None:
    """rest_speed_bounds against a real plan: each sample's |qd| within sqrt(2 a travel) (+ a period's
    worth of acceleration), the travel counted from the start and to the end (both at rest)."""
    traj = load(planned_kuka)
    robot = robot_of(traj)
    acc = np.broadcast_to(np.asarray(traj.task.limits.acceleration_rad_s2, dtype=float), (robot.n_joints,))
    turned = travel(traj.q)
    away = np.minimum(turned, turned[-1] - turned)
    assert np.all(np.abs(traj.qd) <= rest_speed_bounds(away, acc, traj.period))


@pytest.mark.parametrize("seed", [1, 2, 4])
def test_check_bounds_the_planned_figure_on_random_tasks(seed: int) -> None:
    """Random valid tasks (tests/task_strategies.py: any bundled arm, PTP / LIN / CIRC, tools, fly-by
    corners): each move's planned figure is at or under check's bound for it."""
    _bounded(seeded_task(seed))


@pytest.mark.slow
@pytest.mark.parametrize("seed", range(10, 30))
def test_check_bounds_the_planned_figure_on_more_random_tasks(seed: int) -> None:
    _bounded(seeded_task(seed))


def _bounded(mapping: dict[str, object]) -> None:
    task = parse_task(mapping)
    try:
        traj = plan(task)
    except SingplanError:
        return  # nothing planned: nothing to bound (check may still pass; see tests/test_check.py)
    found = detect(task)
    d = traj.samples["stopping_distance_m"]
    bounds = [move.stopping.bound_m for move in found]
    for m, (move, record) in enumerate(zip(found, traj.moves, strict=True)):
        first, last = round(record.t0 / traj.period), round(record.t1 / traj.period)
        planned = d[first + 1:last].max(initial=0.0)  # the move's own samples
        assert planned <= move.stopping.bound_m, (move.index, planned, move.stopping)
        # a sample two moves share: its speeds are central differences over both, so either bound may hold it
        for k, neighbour in ((first, m - 1), (last, m + 1)):
            shared = max(move.stopping.bound_m, bounds[neighbour] if 0 <= neighbour < len(bounds) else 0.0)
            assert d[k] <= shared, (move.index, k, d[k], shared)
