"""planning.timing.records (and the tightening rule of planning.timing.move) on their own: what the
limits of a move say about the TCP's clock and speed, the TCP trace's chords against Pinocchio's forward
kinematics one pose at a time, the sample allowance, and each tightening pass only lowering the limits
a sample broke."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from singplan.errors import BudgetError, PlanningError
from singplan.kinematics.robot import load_robot
from singplan.planning.timing.move import _tightened
from singplan.planning.timing.records import (
    UNSCALED,
    LimitScale,
    MoveLimits,
    TcpTrace,
    TimingError,
    check_move_samples,
)

ROBOT = load_robot("abb_irb2400")


def test_the_tcp_clock_is_the_time_at_the_programmed_speed() -> None:
    u = np.array([0.0, 0.25, 1.0])
    assert MoveLimits(np.ones(6), np.ones(6), 0.0, 0.5).tcp_clock(u) is None  # PTP: no TCP cap
    assert MoveLimits(np.ones(6), np.ones(6), 0.3, None).tcp_clock(u) is None  # no programmed speed
    np.testing.assert_allclose(MoveLimits(np.ones(6), np.ones(6), 0.3, 0.5).tcp_clock(u), u * 0.3 / 0.5)
    trace = TcpTrace(ROBOT, np.array([0.0, 0.5, 1.0]), np.array([0.0, 0.3, 0.4]))
    with_trace = MoveLimits(np.ones(6), np.ones(6), 0.3, 0.5, trace=trace)
    np.testing.assert_allclose(with_trace.tcp_clock(u), np.array([0.0, 0.15, 0.4]) / 0.5)
    chained = MoveLimits(np.ones(6), np.ones(6), 0.3, 0.5, clock=lambda x: 2.0 * x**2, trace=trace)
    np.testing.assert_allclose(chained.tcp_clock(u), 2.0 * u**2)  # a chain's clock wins


def test_step_velocities_are_the_limits_at_each_steps_midpoint() -> None:
    u = np.array([0.0, 0.2, 1.0])
    plain = MoveLimits(np.full(6, 1.5), np.ones(6), 0.0, None)
    np.testing.assert_array_equal(plain.step_velocities(u), np.full(6, 1.5))
    varying = MoveLimits(np.full(6, 1.5), np.ones(6), 0.0, None, velocity_at=lambda x: np.outer(1.0 + x, np.ones(6)))
    np.testing.assert_allclose(varying.step_velocities(u), np.outer([1.1, 1.6], np.ones(6)))


def test_the_tcp_step_ratio_counts_periods_of_the_clock_and_the_traces_chords() -> None:
    q = np.radians([[0, 10, 20, 0, 30, 0], [2, 10, 20, 0, 30, 0], [4, 12, 20, 0, 30, 0]])
    u = np.array([0.0, 0.4, 1.0])
    plain = MoveLimits(np.ones(6), np.ones(6), 0.5, 0.25)  # 2 s for the whole path
    assert plain.tcp_step_ratio(u, q, 0.1) == pytest.approx(0.6 * 2.0 / 0.1)  # the longer step: 1.2 s in 0.1 s
    # a trace: the clock follows it, and the samples' own chords are measured as a checker does
    chords = np.array([np.linalg.norm(ROBOT.fk(q[k + 1]).translation - ROBOT.fk(q[k]).translation) for k in range(2)])
    trace = TcpTrace(ROBOT, u, np.array([0.0, 0.001, 0.002]))  # a trace shorter than the chords
    traced = MoveLimits(np.ones(6), np.ones(6), 0.5, 0.25, trace=trace)
    np.testing.assert_allclose(trace.steps_m(q), chords, rtol=1e-12)
    assert traced.tcp_step_ratio(u, q, 0.1) == pytest.approx(np.max(chords) / (0.1 * 0.25), rel=1e-12)
    assert plain.tcp_step_ratio(u[:1], q[:1], 0.1) == 0.0


def test_a_move_within_the_allowance_passes_and_one_over_it_is_a_budget_error_naming_it() -> None:
    check_move_samples(3, 1000, 1000, 4.0, 0.004)
    with pytest.raises(BudgetError, match=r"move 3 lasts 4\.0 s: 1001 samples .* only 1000") as caught:
        check_move_samples(3, 1001, 1000, 4.0, 0.004)
    assert "moves[3]" in str(caught.value)


def test_a_timing_error_names_the_move_its_kind_and_where() -> None:
    error = TimingError(2, 0.25, "too fast", kind="lin")
    assert isinstance(error, PlanningError) and (error.move, error.u) == (2, 0.25)
    assert str(error) == "move 2 (lin): too fast at u = 0.250000 along the move"
    assert str(TimingError(2, 0.25, "too fast", where="s = 3 mm")) == "move 2: too fast at s = 3 mm"


_ratio = st.floats(0.5, 3.0)


@settings(max_examples=60, deadline=None, derandomize=True)
@given(_ratio, _ratio, _ratio, _ratio, st.floats(0.2, 1.0), st.floats(0.2, 1.0))
def test_a_tightening_pass_lowers_exactly_the_limits_a_sample_broke(v: float, c: float, a: float, t: float,
                                                                    start_v: float, start_a: float) -> None:
    scale = LimitScale(velocity=start_v, acceleration=start_a)
    after = _tightened(scale, v, c, a, t)
    for before, now, worst, keep in ((scale.velocity, after.velocity, v, 0.998), (scale.tcp_speed, after.tcp_speed,
                                     c, 0.998), (scale.acceleration, after.acceleration, a, 0.995),
                                     (scale.torque, after.torque, t, 0.995)):
        # broken: lowered by the ratio it broke by and a little more; kept: unchanged
        assert now == pytest.approx(before * keep / worst if worst > 1.0 else before, rel=1e-15)
        assert now <= before
    assert _tightened(UNSCALED, 1.0, 1.0, 1.0, 1.0) == UNSCALED
