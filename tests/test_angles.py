"""Angle wrapping and whole-turn shifts: the one home (kinematics.angles) and the compiled copies."""

from __future__ import annotations

import math

import numpy as np
import pytest

from singplan.kinematics.angles import TWO_PI, nearest_shifted, wrap_to_pi
from singplan.planning import tracking


def test_wrap_to_pi_lands_in_the_half_open_interval_and_keeps_the_angle() -> None:
    rng = np.random.default_rng(3)
    a = np.concatenate([rng.uniform(-50.0, 50.0, 1000), [math.pi, -math.pi, 3 * math.pi, 0.0]])
    w = wrap_to_pi(a)
    assert np.all(w > -math.pi) and np.all(w <= math.pi)
    turns = (a - w) / TWO_PI
    np.testing.assert_allclose(turns, np.round(turns), atol=1e-9)
    assert wrap_to_pi(np.array([-math.pi]))[0] == pytest.approx(math.pi, abs=1e-12)


def test_nearest_shifted_moves_each_candidate_by_whole_turns_and_picks_the_nearest_row() -> None:
    rng = np.random.default_rng(5)
    candidates = rng.uniform(-10.0, 10.0, (40, 4, 6))
    candidates[7, 2] = np.nan  # a row without a solution is never chosen
    reference = rng.uniform(-7.0, 7.0, (40, 6))
    best, dist, rows = nearest_shifted(candidates, reference)
    for i in range(40):
        shifted = candidates[i] + TWO_PI * np.rint((reference[i] - candidates[i]) / TWO_PI)
        steps = np.max(np.abs(shifted - reference[i]), axis=1)
        steps[np.isnan(steps)] = np.inf
        assert rows[i] == int(np.argmin(steps)) and dist[i] == pytest.approx(steps.min(), abs=1e-12)
        np.testing.assert_allclose(best[i], shifted[rows[i]], atol=1e-12)
        assert np.all(np.abs(best[i] - reference[i]) <= math.pi + 1e-9)


def test_the_trackers_compiled_copy_agrees_with_the_one_home() -> None:
    """tracking keeps its own scalar copy of the shift (numba caches a kernel against its own file)."""
    rng = np.random.default_rng(8)
    for _ in range(200):
        rows = rng.uniform(-12.0, 12.0, (3, 6))
        prev = rng.uniform(-9.0, 9.0, 6)
        best, dist, row = nearest_shifted(rows[None], prev[None])
        k, step = tracking._nearest_row(rows, prev)
        out = np.empty(6)
        tracking._put(rows[k], prev, out)
        assert k == row[0] and step == pytest.approx(dist[0], abs=1e-12)
        np.testing.assert_allclose(out, best[0], atol=1e-12)
