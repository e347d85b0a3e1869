"""planning.timing.profile on its own: a path speed profile with constant path acceleration between grid
points against closed forms (constant speed, constant acceleration, a trapezoid), and the fewest samples
under a profile against a direct simulation that steps it period by period (bisection for the times)."""

from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from singplan.planning.timing.profile import Profile, fewest_samples, node_times

FAST = settings(max_examples=50, deadline=None, derandomize=True)


def _grid(cuts: list[float]) -> np.ndarray:
    """Grid points 0, 1 and the cuts, at least 1e-9 apart (as TOPP-RA's grids are: timing.toppra merges
    reference samples closer than 1e-12)."""
    grid = np.unique(np.concatenate([[0.0, 1.0], np.round(cuts, 9)]))
    return grid[np.concatenate([[True], np.diff(grid) >= 1e-9])]


@FAST
@given(st.lists(st.floats(1e-6, 1.0 - 1e-6), max_size=20), st.floats(0.1, 50.0))
def test_a_constant_speed_profile_is_a_uniform_motion(cuts: list[float], c: float) -> None:
    grid = _grid(cuts)
    profile = Profile(grid, np.full(len(grid), c))
    np.testing.assert_allclose(profile.t_nodes, grid / c, rtol=1e-12, atol=1e-15)
    t = np.linspace(0.0, 1.0 / c, 37)
    np.testing.assert_allclose(profile.u_at(t), c * t, rtol=1e-12, atol=1e-12)


@FAST
@given(st.lists(st.floats(1e-6, 1.0 - 1e-6), max_size=20), st.floats(0.1, 50.0))
def test_a_profile_of_constant_acceleration_from_rest_is_exact_between_its_grid_points(cuts: list[float],
                                                                                        a: float) -> None:
    """sd = sqrt(2 a s): one constant acceleration a, u = a t^2 / 2, whatever the grid."""
    grid = _grid(cuts)
    profile = Profile(grid, np.sqrt(2.0 * a * grid))
    np.testing.assert_allclose(profile.t_nodes, np.sqrt(2.0 * grid / a), rtol=1e-9, atol=1e-12)
    t = np.linspace(0.0, math.sqrt(2.0 / a), 41)
    np.testing.assert_allclose(profile.u_at(t), 0.5 * a * t**2, rtol=1e-9, atol=1e-12)


def _trapezoid(v: float, a: float) -> tuple[Profile, float]:
    """A rest-to-rest trapezoid over u in [0, 1] whose ramp ends fall on grid points, and its duration."""
    ramp_u = v * v / (2.0 * a)
    assert ramp_u < 0.5
    grid = np.unique(np.concatenate([np.linspace(0.0, ramp_u, 9), np.linspace(ramp_u, 1.0 - ramp_u, 5),
                                     np.linspace(1.0 - ramp_u, 1.0, 9)]))
    sd = np.sqrt(np.minimum(np.minimum(2.0 * a * grid, 2.0 * a * (1.0 - grid)), v * v))
    return Profile(grid, sd), 1.0 / v + v / a


def test_a_trapezoid_lasts_its_closed_form_and_goes_where_it_says() -> None:
    v, a = 2.0, 10.0
    profile, duration = _trapezoid(v, a)
    assert profile.t_nodes[-1] == pytest.approx(duration, rel=1e-12)
    t = np.linspace(0.0, duration, 201)
    ramp = v / a
    expected = np.where(t < ramp, 0.5 * a * t**2,
                        np.where(t < duration - ramp, v * t - v * v / (2.0 * a), 1.0 - 0.5 * a * (duration - t) ** 2))
    np.testing.assert_allclose(profile.u_at(t), expected, atol=1e-12)


def test_the_time_is_infinite_past_a_stop() -> None:
    t = node_times(np.array([0.0, 0.25, 0.5, 0.75, 1.0]), np.array([0.0, 1.0, 0.0, 0.0, 1.0]))
    assert np.all(np.isfinite(t[:3])) and np.all(np.isinf(t[3:]))
    assert fewest_samples(np.array([0.0, 0.5, 1.0]), np.array([0.0, 0.0, 1.0]), 0.01, math.inf) == 0


def _simulated_count(profile: Profile, period: float, clock_step: float) -> int:
    """Step the profile one period at a time, each step no further than clock_step: the time to reach a
    point found by bisection on the profile's own positions (u_at), not by its inverse formula."""
    end = float(profile.t_nodes[-1])

    def time_to(s: float) -> float:
        lo, hi = 0.0, end
        for _ in range(200):
            mid = 0.5 * (lo + hi)
            lo, hi = (mid, hi) if profile.u_at(np.array([mid]))[0] < s else (lo, mid)
        return hi

    count, s, t = 0, 0.0, 0.0
    while s < 1.0 - 1e-12:
        count += 1
        reach = 1.0 if t + period >= end else float(profile.u_at(np.array([t + period]))[0])
        if reach <= min(s + clock_step, 1.0):
            s, t = reach, t + period
        else:
            s = min(s + clock_step, 1.0)
            t = time_to(s)
    return count


@settings(max_examples=30, deadline=None, derandomize=True)
@given(st.lists(st.floats(0.05, 5.0), min_size=3, max_size=12), st.floats(0.005, 0.2),
       st.one_of(st.just(math.inf), st.floats(0.01, 0.5)))
def test_fewest_samples_is_a_direct_simulation_of_the_profile(speeds: list[float], period: float,
                                                             clock_step: float) -> None:
    grid = np.linspace(0.0, 1.0, len(speeds) + 2)
    sd = np.concatenate([[0.0], speeds, [0.0]])
    profile = Profile(grid, sd)
    count = fewest_samples(grid, sd, period, clock_step)
    assert count == _simulated_count(profile, period, clock_step)
    if clock_step == math.inf:  # only the profile: its duration in whole periods
        assert count == math.ceil(profile.t_nodes[-1] / period - 1e-9)
    else:
        assert count >= math.ceil(1.0 / clock_step - 1e-9)
