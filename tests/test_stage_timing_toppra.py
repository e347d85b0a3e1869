"""planning.timing.toppra on its own: the time-optimal profile of a straight joint line against its closed
form (bang-bang or trapezoid in the path parameter, limited by the joint with the least speed and
acceleration per unit of travel, or by the TCP speed), TimingPath's grid and scaling, the move's size.

On a straight line q(u) = q0 + u (q1 - q0) joint j asks |du/dt| <= v_j / D_j and |d2u/dt2| <= a_j / D_j
(D_j its travel): the fastest rest-to-rest motion of u over [0, 1] under V = min v_j / D_j and
A = min a_j / D_j takes 1 / V + V / A where it reaches V (V^2 <= A), else 2 / sqrt(A). TOPP-RA solves it
on a grid with the squared speed x = (du/dt)^2 linear between grid points: its optimum there is
x_i = min(V^2, 2 A s_i, 2 A (1 - s_i)) at the grid points (each interval's acceleration within A), and
where a corner of the continuous profile falls inside an interval the grid's profile is slower by at most
the time of that interval at speed V (two corners: 2 ds / V)."""

from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from singplan.kinematics.robot import load_robot
from singplan.planning.path.jointmap import JointMap, JointPart
from singplan.planning.timing.move import time_move
from singplan.planning.timing.ratios import end_step_ratio
from singplan.planning.timing.records import UNSCALED, LimitScale, MoveLimits, TimingError
from singplan.planning.timing.toppra import path_scale, timing_path, toppra_profile

ROBOT = load_robot("abb_irb2400")
PERIOD_S = 0.004
ON_GRID = 1e-5  # TOPP-RA's speed bounds pass through single precision (tests/test_reachability.py)


def _line(q0: np.ndarray, q1: np.ndarray) -> JointMap:
    return JointMap(ROBOT, None, [JointPart("ptp", np.array([0.0, 1.0]), np.array([q0, q1]))])


def _closed_form_s(travel: np.ndarray, v: np.ndarray, a: np.ndarray, tcp: float = math.inf) -> float:
    """The time-optimal duration [s] of the straight line (module docstring); ``tcp``: a cap on du/dt."""
    moving = travel > 0
    speed = min(float(np.min(v[moving] / travel[moving])), tcp)
    accel = float(np.min(a[moving] / travel[moving]))
    return 1.0 / speed + speed / accel if speed * speed <= accel else 2.0 / math.sqrt(accel)


def _on_grid_s(grid: np.ndarray, travel: np.ndarray, v: np.ndarray, a: np.ndarray, tcp: float = math.inf) -> float:
    """The optimum of the same problem with x linear between the grid points (module docstring) [s]."""
    moving = travel > 0
    speed = min(float(np.min(v[moving] / travel[moving])), tcp)
    accel = float(np.min(a[moving] / travel[moving]))
    x = np.minimum(speed * speed, 2.0 * accel * np.minimum(grid, 1.0 - grid))
    return float(np.sum(2.0 * np.diff(grid) / (np.sqrt(x[:-1]) + np.sqrt(x[1:]))))


def _within_the_grids_corners(duration: float, grid: np.ndarray, travel: np.ndarray, v: np.ndarray, a: np.ndarray,
                              tcp: float = math.inf) -> None:
    """The continuous optimum, and no more than two grid intervals at the cruise speed above it."""
    closed = _closed_form_s(travel, v, a, tcp)
    speed = min(float(np.min(v[travel > 0] / travel[travel > 0])), tcp)
    assert closed * (1 - ON_GRID) <= duration <= closed + 2.0 * float(np.max(np.diff(grid))) / speed


@pytest.mark.parametrize("distance_rad", [0.05, 0.4, 2.0])  # short of full speed, just past it, a long cruise
def test_one_limited_joint_gives_the_bang_bang_or_trapezoid_time(distance_rad: float) -> None:
    v, a = 1.5, 4.0
    q0 = np.radians([0, 10, 20, 0, 30, 0])
    q1 = q0 + distance_rad * np.array([1.0, 0.3, -0.2, 0.0, 0.1, 0.0])  # the others with room to spare
    limits = MoveLimits(np.array([v, 50, 50, 50, 50, 50]), np.array([a, 90, 90, 90, 90, 90]), 0.0, None)
    profile = toppra_profile(timing_path(_line(q0, q1), limits, 0), limits, UNSCALED, 0)
    closed = distance_rad / v + v / a if distance_rad >= v * v / a else 2.0 * math.sqrt(distance_rad / a)
    assert profile.t_nodes[-1] == pytest.approx(closed, rel=2e-4)  # the grid's corner at the cruise's start
    assert profile.t_nodes[-1] == pytest.approx(_on_grid_s(profile.grid, np.abs(q1 - q0), limits.velocity_rad_s,
                                                           limits.acceleration_rad_s2), rel=ON_GRID)
    # within the limiting joint's speed and acceleration, reaching them (time-optimal)
    speed = profile.sd * distance_rad
    accel = np.diff(profile.sd**2) / (2.0 * np.diff(profile.grid)) * distance_rad
    assert np.max(speed) <= v * (1 + 1e-6) and np.max(np.abs(accel)) <= a * (1 + 1e-6)
    assert np.max(np.abs(accel)) >= a * (1 - 1e-6)
    assert profile.sd[0] == 0.0 and profile.sd[-1] == 0.0


@settings(max_examples=25, deadline=None, derandomize=True)
@given(st.lists(st.floats(-2.0, 2.0), min_size=6, max_size=6), st.lists(st.floats(0.3, 3.0), min_size=6, max_size=6),
       st.lists(st.floats(1.0, 20.0), min_size=6, max_size=6))
def test_any_joint_line_takes_the_closed_form_time_of_its_binding_joint(step: list[float], v: list[float],
                                                                        a: list[float]) -> None:
    travel = np.abs(step)
    if np.max(travel) < 1e-3 or np.min(travel[travel > 0] / np.max(travel), initial=1.0) < 1e-4:
        return  # a joint that barely moves beside one that moves far: ill-conditioned, not this test's subject
    q0 = np.zeros(6)
    vmax, amax = np.array(v), np.array(a)
    profile = toppra_profile(timing_path(_line(q0, q0 + np.array(step)), MoveLimits(vmax, amax, 0.0, None), 0),
                             MoveLimits(vmax, amax, 0.0, None), UNSCALED, 0)
    duration = float(profile.t_nodes[-1])
    assert duration == pytest.approx(_on_grid_s(profile.grid, travel, vmax, amax), rel=ON_GRID)
    _within_the_grids_corners(duration, profile.grid, travel, vmax, amax)


@pytest.mark.parametrize("tcp_m_s", [0.05, 0.5])
def test_the_tcp_speed_caps_the_path_speed_of_a_line(tcp_m_s: float) -> None:
    """length_m = 0.4 m covered at most at tcp_m_s: du/dt <= tcp / L beside the joints' own caps."""
    q0 = np.radians([0, 10, 20, 0, 30, 0])
    q1 = q0 + np.array([0.4, 0.1, 0.0, 0.0, 0.0, 0.0])
    limits = MoveLimits(np.full(6, 2.0), np.full(6, 6.0), 0.4, tcp_m_s)
    profile = toppra_profile(timing_path(_line(q0, q1), limits, 0), limits, UNSCALED, 0)
    args = (np.abs(q1 - q0), limits.velocity_rad_s, limits.acceleration_rad_s2, tcp_m_s / 0.4)
    assert profile.t_nodes[-1] == pytest.approx(_on_grid_s(profile.grid, *args), rel=ON_GRID)
    _within_the_grids_corners(float(profile.t_nodes[-1]), profile.grid, *args)
    assert np.max(profile.sd) * 0.4 <= tcp_m_s * (1 + 1e-6)


def test_scaled_limits_slow_the_line_as_the_closed_form_says() -> None:
    q0 = np.zeros(6)
    q1 = np.array([1.0, 0.5, 0, 0, 0, 0])
    limits = MoveLimits(np.full(6, 1.0), np.full(6, 4.0), 0.0, None)
    path = timing_path(_line(q0, q1), limits, 0)
    scale = LimitScale(velocity=0.5, acceleration=0.25)
    slowed = toppra_profile(path, limits, scale, 0).t_nodes[-1]
    args = (np.abs(q1 - q0), limits.velocity_rad_s * 0.5, limits.acceleration_rad_s2 * 0.25)
    assert slowed == pytest.approx(_on_grid_s(path.grid, *args), rel=ON_GRID)
    _within_the_grids_corners(float(slowed), path.grid, *args)


def test_time_move_rounds_the_optimal_line_up_to_whole_periods() -> None:
    q0 = np.radians([0, 10, 20, 0, 30, 0])
    q1 = q0 + np.array([0.9, -0.2, 0.3, 0.0, 0.1, 0.4])
    limits = MoveLimits(np.full(6, 2.0), np.full(6, 8.0), 0.0, None)
    tm = time_move(_line(q0, q1), limits, PERIOD_S, 0, 100_000)
    closed = _closed_form_s(np.abs(q1 - q0), limits.velocity_rad_s, limits.acceleration_rad_s2)
    assert closed <= tm.duration_s + 1e-9 <= closed * (1 + 1e-3) + PERIOD_S + 1e-9
    assert tm.duration_s / PERIOD_S == pytest.approx(round(tm.duration_s / PERIOD_S), abs=1e-9)
    # every sample on the line, inside the limits, from rest to rest
    along = (tm.q - q0) @ (q1 - q0) / ((q1 - q0) @ (q1 - q0))
    np.testing.assert_allclose(tm.q, q0 + np.outer(along, q1 - q0), atol=1e-12)
    np.testing.assert_allclose(along, tm.u, atol=1e-12)
    assert tm.speed_ratio <= 1.0 and tm.accel_ratio <= 1.0
    assert end_step_ratio(tm.q, PERIOD_S, limits.acceleration_rad_s2) <= 1.0


def test_the_moves_size_is_its_largest_travel_of_a_joint_or_the_tcp() -> None:
    q = np.array([[0.0, 0.0], [0.3, -0.1], [0.1, -0.4], [0.2, -0.4]])  # travels 0.3 + 0.2 + 0.1 and 0.1 + 0.3
    lim = MoveLimits(np.ones(2), np.ones(2), 0.0, None)
    assert path_scale(q, lim) == pytest.approx(0.6, rel=1e-15)
    assert path_scale(q, MoveLimits(np.ones(2), np.ones(2), 0.75, 0.1)) == 0.75
    assert path_scale(q[:1], lim) == 0.0


def test_the_timing_path_is_dimensionless_and_its_grid_holds_every_reference_sample() -> None:
    q0 = np.radians([0, 10, 20, 0, 30, 0])
    q1 = q0 + np.array([0.8, 0.2, 0, 0, 0, 0])
    limits = MoveLimits(np.full(6, 2.0), np.array([4.0, 8, 8, 8, 8, 8]), 0.0, None)
    path = timing_path(_line(q0, q1), limits, 0)
    assert path.length == pytest.approx(0.8)
    assert np.all(np.diff(path.grid) > 0) and len(path.grid) >= 100 and np.max(np.diff(path.grid)) <= 0.01 + 1e-12
    assert np.all(np.isin(path.u, path.grid)) and path.grid[0] == 0.0 and path.grid[-1] == 1.0
    d1, d2 = path.derivatives
    # (q - q0) / L: joint 0's slope is 1, joint 1's 0.25; the last coordinate (no TCP cap) is u itself
    np.testing.assert_allclose(d1[:, 0], 1.0, atol=1e-9)
    np.testing.assert_allclose(d1[:, 1], 0.25, atol=1e-9)
    np.testing.assert_allclose(d1[:, -1], 1.0, atol=1e-9)
    np.testing.assert_allclose(d2, 0.0, atol=1e-7)
    tau, vmax_1, amax_1 = path.scaled_limits(limits, UNSCALED)
    assert tau == pytest.approx(math.sqrt(0.8 / 4.0))  # L over the least acceleration
    np.testing.assert_allclose(vmax_1[:6], 2.0 * tau / 0.8)
    np.testing.assert_allclose(amax_1[:6], limits.acceleration_rad_s2 * tau**2 / 0.8)


def test_a_map_that_changes_nothing_has_no_path_and_one_without_joints_is_a_timing_error() -> None:
    q0 = np.radians([0, 10, 20, 0, 30, 0])
    limits = MoveLimits(np.full(6, 2.0), np.full(6, 4.0), 0.0, None)
    still = timing_path(_line(q0, q0), limits, 0)
    assert still.spline is None and still.length == 0.0
    missing = q0.copy()
    missing[2] = np.nan
    with pytest.raises(TimingError, match="no joint values") as caught:
        timing_path(_line(q0, missing), limits, 7)
    assert caught.value.move == 7 and 0.0 <= caught.value.u <= 1.0
