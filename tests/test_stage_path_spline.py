"""planning/path/spline.py: the not-a-knot spline made without scipy's input checks, against scipy's
CubicSpline itself (the reference) and against the defining conditions of the spline."""

from __future__ import annotations

import numpy as np
import pytest
import toppra as ta
from scipy.interpolate import CubicSpline

from singplan.planning.path.spline import not_a_knot
from singplan.planning.timing.toppra import _Spline


def _points(rng: np.random.Generator) -> tuple[np.ndarray, np.ndarray]:
    n = int(rng.integers(4, 300))
    x = np.cumsum(rng.uniform(0.05, 1.0, n)) * rng.uniform(1e-4, 10.0)
    y = rng.normal(size=(n, int(rng.integers(1, 8)))) * 10 ** rng.uniform(-6, 2)
    return x, y


def test_the_spline_is_scipys_not_a_knot_spline() -> None:
    rng = np.random.default_rng(24)
    for trial in range(300):
        x, y = _points(rng)
        y = y[:, 0] if trial % 3 == 0 else y
        ours, scipys = not_a_knot(x, y), CubicSpline(x, y)
        assert type(ours) is CubicSpline and ours.c.shape == scipys.c.shape and ours.c.flags.c_contiguous
        np.testing.assert_allclose(ours.c, scipys.c, rtol=1e-9, atol=1e-12 * np.abs(scipys.c).max())
        at = np.linspace(x[0] - 0.1, x[-1] + 0.1, 40)
        for nu in (0, 1, 2):
            reference = scipys(at, nu)
            np.testing.assert_allclose(ours(at, nu), reference, rtol=1e-9, atol=1e-12 * np.abs(reference).max())


def test_the_spline_interpolates_and_has_no_knot_at_the_second_and_last_but_one_points() -> None:
    rng = np.random.default_rng(3)
    x, y = _points(rng)
    s = not_a_knot(x, y)
    np.testing.assert_allclose(s(x), y, atol=1e-12 * np.max(np.abs(y)))
    third = s.derivative(3)  # not-a-knot: the third derivative is continuous at x[1] and x[-2]
    eps = 1e-9 * (x[-1] - x[0])
    for k in (1, len(x) - 2):
        np.testing.assert_allclose(third(x[k] - eps), third(x[k] + eps), rtol=1e-6, atol=1e-9 * np.max(np.abs(third.c)))
    for k in (2, len(x) - 3):  # ... and (generally) not at the others
        assert not np.allclose(third(x[k] - eps), third(x[k] + eps), rtol=1e-6)


@pytest.mark.parametrize(("x", "y", "match"), [
    (np.array([0.0, 1.0, 1.0, 2.0, 3.0]), np.zeros((5, 2)), "strictly increasing"),
    (np.array([0.0, 1.0, 2.0, 3.0, 4.0]), np.array([[0.0], [np.nan], [0.0], [1.0], [2.0]]), "finite"),
])
def test_unsound_points_get_scipys_own_error(x: np.ndarray, y: np.ndarray, match: str) -> None:
    with pytest.raises(ValueError, match=match):
        not_a_knot(x, y)


def test_short_inputs_are_scipys_splines() -> None:
    for n in (2, 3):
        x, y = np.arange(float(n)), np.arange(2.0 * n).reshape(n, 2) ** 2
        np.testing.assert_array_equal(not_a_knot(x, y).c, CubicSpline(x, y).c)


def test_the_timing_paths_spline_is_toppras_spline_interpolator() -> None:
    rng = np.random.default_rng(5)
    x, y = _points(rng)
    x = (x - x[0]) / (x[-1] - x[0])
    ours, toppras = _Spline(x, y), ta.SplineInterpolator(x, y)
    grid = np.linspace(0.0, 1.0, 101)
    for order in (0, 1, 2):
        np.testing.assert_allclose(ours(grid, order), toppras(grid, order), rtol=1e-9, atol=1e-9)
    assert ours.dof == toppras.dof and np.array_equal(ours.path_interval, toppras.path_interval)
