"""planning.timing.laws on their own: the S-curve's duration against the seven-phase closed form (cruise
reached, acceleration reached without cruise), its derivatives by finite differences, and the smoothed
law against a numerical quadrature of the profile it averages (tests/test_jerk.py checks the quintic)."""

from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import assume, given, settings
from hypothesis import strategies as st

from singplan.planning.timing.laws import SCurveLaw, SmoothedLaw
from singplan.planning.timing.profile import Profile

FAST = settings(max_examples=40, deadline=None, derandomize=True)


@FAST
@given(st.floats(0.2, 5.0), st.floats(0.5, 50.0), st.floats(1.0, 500.0))
def test_an_s_curve_that_cruises_takes_the_seven_phase_time(v: float, a: float, j: float) -> None:
    """Peak acceleration reached (v j >= a^2) and the ramps up and down covering less than the unit
    travel (v (v / a + a / j) <= 1): T = 1 / v + v / a + a / j."""
    assume(v * j >= a * a and v * (v / a + a / j) <= 1.0)
    law = SCurveLaw(v, a, j)
    assert law.duration_s == pytest.approx(1.0 / v + v / a + a / j, rel=1e-12)
    _reaches_its_limits(law, v, a, j, speed_reached=True)


@FAST
@given(st.floats(0.5, 50.0), st.floats(0.5, 50.0), st.floats(1.0, 500.0))
def test_an_s_curve_short_of_its_speed_takes_the_no_cruise_time(v: float, a: float, j: float) -> None:
    """The unit travel ends before v: the peak speed w solves w (w / a + a / j) = 1 (acceleration
    reached, w j >= a^2), and T = 2 (w / a + a / j)."""
    w = a * (-a / j + math.sqrt(a * a / (j * j) + 4.0 / a)) / 2.0
    assume(v * (v / a + a / j) > 1.0 and w * j >= a * a and w < v)
    law = SCurveLaw(v, a, j)
    assert law.duration_s == pytest.approx(2.0 * (w / a + a / j), rel=1e-9)
    _reaches_its_limits(law, w, a, j, speed_reached=False)


def _reaches_its_limits(law: SCurveLaw, v: float, a: float, j: float, speed_reached: bool) -> None:
    """From 0 to 1 at rest, within the limits by finite differences, peak speed v and acceleration a met."""
    t = np.linspace(0.0, law.duration_s, 6001)
    h = t[1] - t[0]
    u = law.u_at(t)
    assert u[0] == 0.0 and u[-1] == pytest.approx(1.0, abs=1e-12) and np.all(np.diff(u) >= -1e-15)
    speed = np.diff(u) / h
    accel = np.diff(u, n=2) / h**2
    assert np.max(speed) <= v * (1 + 1e-9) and np.max(speed) >= v * (1 - 1e-3)
    assert np.max(np.abs(accel)) <= a * (1 + 1e-6) and np.max(np.abs(accel)) >= a * (1 - 2e-2)
    assert np.max(np.abs(np.diff(u, n=3))) / h**3 <= j * (1 + 1e-3)
    assert speed_reached == bool(np.max(speed) >= law.speed * (1 - 1e-3))


@FAST
@given(st.lists(st.floats(0.1, 3.0), min_size=2, max_size=8), st.floats(0.01, 0.5), st.floats(0.0, 1.0))
def test_the_smoothed_law_is_the_moving_average_of_its_profile(speeds: list[float], window_s: float,
                                                               where: float) -> None:
    grid = np.linspace(0.0, 1.0, len(speeds) + 2)
    sd = np.concatenate([[0.0], speeds, [0.0]])
    profile = Profile(grid, sd)
    law = SmoothedLaw(profile.t_nodes, grid, sd, window_s)
    assert law.duration_s == pytest.approx(profile.t_nodes[-1] + window_s)
    t = where * law.duration_s
    # (1 / w) * integral of u over [t - w, t], u = 0 before the start and 1 after the end: Simpson's rule on
    # a fine grid of the profile's own positions
    tau = np.linspace(t - window_s, t, 4001)
    end = profile.t_nodes[-1]
    inside = profile.u_at(np.clip(tau, 0.0, end))
    u = np.where(tau < 0.0, 0.0, np.where(tau > end, 1.0, inside))
    h = tau[1] - tau[0]
    simpson = h / 3.0 * (u[0] + u[-1] + 4.0 * np.sum(u[1:-1:2]) + 2.0 * np.sum(u[2:-1:2]))
    assert law.u_at(np.array([t]))[0] == pytest.approx(simpson / window_s, abs=1e-7)
