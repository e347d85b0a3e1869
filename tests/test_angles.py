"""Angle wrapping and whole-turn shifts: the one home (kinematics.angles), numpy forms and compiled kernels."""

from __future__ import annotations

import hashlib
import math
from pathlib import Path

import numpy as np
import pytest

from singplan.kinematics import angles, compiled, configuration
from singplan.kinematics.angles import (
    TWO_PI,
    nearest_row,
    nearest_shifted,
    row_step,
    shift_row_into,
    shifted_toward,
    wrap,
    wrap_deg,
    wrap_to_pi,
)
from singplan.kinematics.closedform import opw
from singplan.planning.path import tracking


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


def test_the_compiled_row_kernels_agree_with_the_numpy_forms() -> None:
    """The scalar kernels the tracker and the closed forms call give nearest_shifted's and wrap_to_pi's figures."""
    rng = np.random.default_rng(8)
    for _ in range(200):
        rows = rng.uniform(-12.0, 12.0, (3, 6))
        prev = rng.uniform(-9.0, 9.0, 6)
        best, dist, row = nearest_shifted(rows[None], prev[None])
        k, step = nearest_row(rows, prev)
        out = np.empty(6)
        shift_row_into(rows[k], prev, out)
        assert k == row[0] and step == pytest.approx(dist[0], abs=1e-12)
        assert row_step(rows[k], prev) == step
        np.testing.assert_allclose(out, best[0], atol=1e-12)
        np.testing.assert_allclose(out, shifted_toward(rows[k], prev), atol=0.0)
    a = np.concatenate([rng.uniform(-40.0, 40.0, 500), [math.pi, -math.pi, 0.0, 5 * math.pi]])
    np.testing.assert_array_equal(np.array([wrap(x) for x in a]), wrap_to_pi(a))


def test_a_row_with_nan_is_never_nearest_and_all_nan_rows_give_inf() -> None:
    rows = np.array([[np.nan, 0.0], [3.0, 3.0]])
    assert nearest_row(rows, np.zeros(2)) == (1, 3.0)
    assert nearest_row(np.full((2, 2), np.nan), np.zeros(2))[1] == math.inf


def test_wrap_deg_lands_in_the_half_open_interval() -> None:
    a = np.array([-180.0, 180.0, 540.0, -540.0, 0.0, 359.0, -359.0, 1e-20, -1e-20])
    np.testing.assert_allclose(wrap_deg(a), [180.0, 180.0, 180.0, 180.0, 0.0, -1.0, 1.0, 1e-20, -1e-20], atol=1e-12)
    assert wrap_deg(np.array([1e-20]))[0] > 0.0  # the mod form this replaced gave 0 here


def test_kernels_are_cached_under_the_digest_of_angles_py() -> None:
    """numba checks a cached kernel against its own file only: the callers of the angles kernels
    (here the tracker's loop) are cached under a name that changes with angles.py."""
    source = Path(compiled.__file__).with_name("angles.py").read_bytes()
    assert hashlib.sha256(source).hexdigest()[:12] == compiled.SHARED_DIGEST
    for kernel in (tracking._follow, configuration._opw_distances, opw.branches, nearest_row):
        assert kernel.py_func.__qualname__.endswith(f"__{compiled.SHARED_DIGEST}")
    nearest_shifted(np.zeros((1, 1, 6)), np.zeros((1, 6)))  # compiled or loaded: its cache files exist
    folder = Path(angles._nearest_rows.stats.cache_path)
    assert list(folder.glob(f"angles._nearest_rows__{compiled.SHARED_DIGEST}-*.nbi"))
