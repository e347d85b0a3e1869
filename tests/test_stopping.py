"""Stopping distance (SEEDS 002 glide path; singplan/stopping.py)."""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest

import singplan.kinematics.stopping as stopping
from singplan.cli import main
from singplan.kinematics.robot import Robot, load_robot
from singplan.kinematics.stopping import braking_joints, mean_norm, stopping_distances
from singplan.outputs.viewer import robot_of
from singplan.results.trajectory import load, save

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
    assert traj.metrics["max_stopping_distance_mm"] == series[k] * 1e3
    assert traj.metrics["max_stopping_distance_at_s"] == pytest.approx(traj.t[k])
    robot = robot_of(traj)
    acc = np.broadcast_to(np.asarray(traj.task["limits"]["acceleration"], dtype=float), (robot.n_joints,))
    np.testing.assert_allclose(series, stopping_distances(robot, traj.q, traj.qd, acc), rtol=1e-12, atol=0)
    # the file holds the floats as computed: loading gives the same ones back
    again = load(save(traj, planned_kuka.parent / "again"))
    np.testing.assert_array_equal(again.samples["stopping_distance_m"], series)


def test_plan_and_check_print_the_worst_figure(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    task = Path(__file__).resolve().parents[1] / "singplan" / "demo_task.yaml"
    assert main(["plan", str(task), "-o", str(tmp_path), "--no-report", "--no-replay"]) == 0
    planned = load(tmp_path).metrics["max_stopping_distance_mm"]
    assert f"stopping distance: up to {planned:.3f} mm" in capsys.readouterr().out
    assert main(["check", str(task)]) == 0
    lines = capsys.readouterr().out.strip().splitlines()
    line = next(x for x in lines if x.startswith("stopping distance (estimate"))
    assert line.startswith("stopping distance (estimate at the programmed speed, not planned): up to ")
    estimate = float(line.split("up to ")[1].split(" mm")[0])
    # the estimate cruises at the programmed speeds the plan reaches only in part: the same order, not less
    assert planned * 0.9 <= estimate <= planned * 3
