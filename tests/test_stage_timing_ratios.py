"""planning.timing.ratios on its own: each ratio against a hand computation or a plain loop over the
samples written from its definition (forward differences, as the independent checker measures)."""

from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from hypothesis.extra.numpy import arrays

from singplan.planning.timing import ratios
from singplan.planning.timing.ratios import (
    difference_ratios,
    end_step_ratio,
    jerk_ratio,
    sample_ratios,
    third_difference_ratio,
    worst_sample,
)

FAST = settings(max_examples=60, deadline=None, derandomize=True)


def _samples(min_rows: int = 2) -> st.SearchStrategy[np.ndarray]:
    return st.integers(min_rows, 12).flatmap(
        lambda k: arrays(float, (k, 3), elements=st.floats(-3.0, 3.0, allow_nan=False)))


_limits = arrays(float, 3, elements=st.floats(0.1, 10.0))


def _loop_ratios(q: np.ndarray, dt: float, vmax: np.ndarray, amax: np.ndarray) -> tuple[list[float], list[float]]:
    """Speed and acceleration ratios written sample by sample from the checker's definitions."""
    speed = [max(abs(q[k + 1, j] - q[k, j]) / dt / vmax[j] for j in range(q.shape[1])) for k in range(len(q) - 1)]
    accel = [max(abs(q[k + 1, j] - 2 * q[k, j] + q[k - 1, j]) / dt**2 / amax[j] for j in range(q.shape[1]))
             for k in range(1, len(q) - 1)]
    return speed, accel


def test_hand_computed_ratios() -> None:
    # one joint: steps 1 and 2 in a period of 0.5 s -> speeds 2 and 4 rad/s; acceleration (4 - 2) / 0.5 = 4
    q = np.array([[0.0], [1.0], [3.0]])
    speed, accel = difference_ratios(q, 0.5, np.array([4.0]), np.array([2.0]))
    np.testing.assert_allclose(speed, [0.5, 1.0], rtol=1e-15)
    np.testing.assert_allclose(accel, [2.0], rtol=1e-15)
    assert sample_ratios(q, 0.5, np.array([4.0]), np.array([2.0])) == (1.0, 2.0)
    # end steps 1 and 2 against amax dt^2 / 2 = 2 * 0.25 / 2 = 0.25: the larger, 2, is x8
    assert end_step_ratio(q, 0.5, np.array([2.0])) == pytest.approx(8.0, rel=1e-15)


def test_fewer_than_two_samples_measure_nothing() -> None:
    one = np.zeros((1, 3))
    assert sample_ratios(one, 0.004, np.ones(3), np.ones(3)) == (0.0, 0.0)
    assert end_step_ratio(one, 0.004, np.ones(3)) == 0.0
    assert jerk_ratio(one, 0.004, np.ones(3)) == 0.0
    # two samples: one speed, no acceleration
    two = np.array([[0.0, 0.0, 0.0], [0.004, 0.0, 0.0]])
    assert sample_ratios(two, 0.004, np.ones(3), np.ones(3)) == (1.0, 0.0)


@FAST
@given(_samples(), st.floats(1e-3, 0.1), _limits, _limits)
def test_difference_ratios_are_the_checkers_loop(q: np.ndarray, dt: float, vmax: np.ndarray, amax: np.ndarray) -> None:
    speed, accel = difference_ratios(q, dt, vmax, amax)
    loop_speed, loop_accel = _loop_ratios(q, dt, vmax, amax)
    np.testing.assert_allclose(speed, loop_speed, rtol=1e-12, atol=1e-12)
    np.testing.assert_allclose(accel, loop_accel, rtol=1e-12, atol=1e-9)
    assert sample_ratios(q, dt, vmax, amax) == pytest.approx(
        (max(loop_speed), max(loop_accel, default=0.0)), rel=1e-12, abs=1e-9)


@FAST
@given(_samples(), st.floats(1e-3, 0.1), _limits)
def test_the_end_step_ratio_is_the_larger_end_step_over_half_a_period_at_amax(q: np.ndarray, dt: float,
                                                                              amax: np.ndarray) -> None:
    bound = amax * dt**2 / 2.0  # from rest, one period at amax
    expected = max(max(abs(q[1, j] - q[0, j]), abs(q[-1, j] - q[-2, j])) / bound[j] for j in range(3))
    assert end_step_ratio(q, dt, amax) == pytest.approx(expected, rel=1e-12)


@FAST
@given(_samples(min_rows=1), st.floats(1e-3, 0.1), _limits, _limits)
def test_the_worst_sample_is_the_one_furthest_over_its_limits(q: np.ndarray, dt: float, vmax: np.ndarray,
                                                              amax: np.ndarray) -> None:
    """Brute force: the samples at rest before and after, each sample's worst of the step into it,
    the step out of it and its acceleration (an end sample's against amax dt^2 / 2, from rest)."""
    padded = np.concatenate([q[:1], q, q[-1:]])
    speed, accel = _loop_ratios(padded, dt, vmax, amax)
    over = []
    for k in range(len(q)):
        a = accel[k] * (2.0 if k in (0, len(q) - 1) else 1.0)
        over.append(max(speed[k], speed[k + 1], a))
    worst = worst_sample(q, dt, vmax, amax)
    assert over[worst] == pytest.approx(max(over), rel=1e-12, abs=1e-12)


def test_jerk_ratio_by_hand() -> None:
    dt, jmax = 0.5, np.array([2.0])  # unit J dt^3 = 0.25
    # steps 0.01, 0.03, 0.2, 0.03: third differences 0.2 - 0.06 + 0.01 = 0.15 and 0.03 - 0.4 + 0.03 = -0.34,
    # end steps 0.01 and 0.03 against 0.25 / 6, second steps 0.03 - 0.02 and 0.2 - 0.06 against 0.25 * 5 / 6
    q = np.cumsum([[0.0], [0.01], [0.03], [0.2], [0.03]], axis=0)
    third = 0.34 / 0.25
    ends = 0.03 / (0.25 / 6.0)
    second = max(abs(0.03 - 0.02), abs(0.2 - 0.06)) / (0.25 * 5.0 / 6.0)
    assert third_difference_ratio(q, dt, jmax) == pytest.approx(third, rel=1e-12)
    assert jerk_ratio(q, dt, jmax) == pytest.approx(max(third, ends, second), rel=1e-12)


@FAST
@given(_samples(min_rows=4), st.floats(1e-3, 0.1), _limits, st.integers(1, 3))
def test_third_differences_chunked_are_the_whole_ones(q: np.ndarray, dt: float, jmax: np.ndarray,
                                                      chunk: int) -> None:
    whole = float(np.max(np.abs(np.diff(q, n=3, axis=0)) / (jmax * dt**3)))
    saved = ratios._CHUNK_SAMPLES
    ratios._CHUNK_SAMPLES = chunk
    try:
        chunked = third_difference_ratio(q, dt, jmax)
    finally:
        ratios._CHUNK_SAMPLES = saved
    assert math.isclose(chunked, whole, rel_tol=1e-12, abs_tol=1e-12)
