"""planning.timing.bound's speed caps on their own: on a straight joint line they are the on-grid optimum
in closed form (V^2 from the binding joint's speed, 2 A s from the start and 2 A (1 - s) to the end: the
forward and the stopping pass), and on curved joint paths no profile TOPP-RA finds, at any tightened
limits, rises above them (tests/test_bound.py checks the duration bound built on them)."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import assume, given, reject, settings
from hypothesis import strategies as st

from singplan.kinematics.robot import load_robot
from singplan.planning.path.jointmap import JointMap, JointPart
from singplan.planning.timing.bound import speed_caps
from singplan.planning.timing.records import UNSCALED, LimitScale, MoveLimits, TimingError
from singplan.planning.timing.toppra import timing_path, toppra_profile

ROBOT = load_robot("abb_irb2400")


def _line(q0: np.ndarray, q1: np.ndarray) -> JointMap:
    return JointMap(ROBOT, None, [JointPart("ptp", np.array([0.0, 1.0]), np.array([q0, q1]))])


@pytest.mark.parametrize(("step", "tcp"), [([0.9, -0.3, 0.2, 0.0, 0.5, 0.1], None), ([0.05, 0.02, 0, 0, 0, 0], None),
                                           ([0.4, 0.1, 0, 0, 0, 0], 0.05)])
def test_the_caps_of_a_straight_line_are_its_forward_and_stopping_parabolas_under_the_speed_cap(
        step: list[float], tcp: float | None) -> None:
    q0 = np.radians([0, 10, 20, 0, 30, 0])
    limits = MoveLimits(np.linspace(1.0, 2.5, 6), np.linspace(3.0, 9.0, 6), 0.0 if tcp is None else 0.4, tcp)
    path = timing_path(_line(q0, q0 + np.array(step)), limits, 0)
    _, vmax_1, amax_1 = path.scaled_limits(limits, UNSCALED)
    caps = speed_caps(path, vmax_1, amax_1)
    # dimensionless slopes: each joint's travel over the move's size, the TCP coordinate's u * length / size
    slopes = np.append(np.abs(step), limits.length_m) / path.length
    moving = slopes > 0
    v_sq = float(np.min(vmax_1[moving] / slopes[moving])) ** 2
    accel = float(np.min(amax_1[moving] / slopes[moving]))
    expected = np.minimum(v_sq, 2.0 * accel * np.minimum(path.grid, 1.0 - path.grid))
    np.testing.assert_allclose(caps, expected, rtol=1e-7, atol=1e-12)


def _curve(p0: np.ndarray, p1: np.ndarray, bulge: np.ndarray) -> JointMap:
    """q(u) = p0 + (p1 - p0) u + bulge sin(pi u), as a spline part through 40 samples (C2)."""
    u = np.linspace(0.0, 1.0, 40)
    q = p0 + np.outer(u, p1 - p0) + np.outer(np.sin(np.pi * u), bulge)
    return JointMap(ROBOT, None, [JointPart("spline", u, q)])


@settings(max_examples=25, deadline=None, derandomize=True)
@given(st.lists(st.floats(-1.5, 1.5), min_size=18, max_size=18), st.floats(0.3, 3.0), st.floats(1.0, 20.0),
       st.floats(0.3, 1.0), st.floats(0.3, 1.0))
def test_no_profile_toppra_finds_at_tightened_limits_rises_above_the_caps(points: list[float], v: float, a: float,
                                                                         scale_v: float, scale_a: float) -> None:
    p0, p1, bulge = np.reshape(points, (3, 6))
    limits = MoveLimits(np.full(6, v) * np.linspace(0.5, 1.0, 6), np.full(6, a), 0.0, None)
    path = timing_path(_curve(p0, p1, bulge), limits, 0)
    assume(path.spline is not None)
    tau, vmax_1, amax_1 = path.scaled_limits(limits, UNSCALED)
    caps = speed_caps(path, vmax_1, amax_1)
    for scale in (UNSCALED, LimitScale(velocity=scale_v, acceleration=scale_a)):
        try:
            profile = toppra_profile(path, limits, scale, 0)
        except TimingError:  # no timing at all: nothing to bound
            reject()
        x = (profile.sd * tau) ** 2  # the squared path speed in the unscaled dimensionless time
        assert np.all(x <= caps * (1.0 + 1e-6) + 1e-12)
