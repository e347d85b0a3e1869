"""Cubic splines through a move's samples, made without scipy's per-call input checks.

A long program makes a few splines a move (the timing path of every candidate, the start of every
axis solve), and scipy's :class:`~scipy.interpolate.CubicSpline` spends most of its 0.2 ms on
validating and converting its inputs, not on the spline. :func:`not_a_knot` forms the same
spline (the same tridiagonal system, solved by the same LAPACK ``gtsv``, and the same Hermite
coefficients, in the same order of operations: equal to scipy 1.17's bit for bit) for inputs the
planner has already made sound: finite samples at strictly increasing parameters. Anything else
is handed to scipy, whose error then names the problem.
"""

from __future__ import annotations

import numpy as np
from scipy.interpolate import CubicSpline
from scipy.linalg import LinAlgError, get_lapack_funcs

_GTSV = get_lapack_funcs(("gtsv",), (np.zeros((3, 4)), np.zeros((4, 1))))[0]


def not_a_knot(x: np.ndarray, y: np.ndarray) -> CubicSpline:
    """The cubic spline through the points (x (N,), y (N, ...)) with not-a-knot ends, along axis 0:
    ``CubicSpline(x, y)``."""
    x = np.asarray(x, dtype=np.float64)
    y = np.asarray(y, dtype=np.float64)
    dx = np.diff(x)
    if x.ndim != 1 or len(x) < 4 or y.shape[:1] != x.shape or not (np.all(dx > 0) and np.all(np.isfinite(y))
                                                                    and np.all(np.isfinite(x))):
        return CubicSpline(x, y)
    dxr = dx.reshape((len(dx),) + (1,) * (y.ndim - 1))
    slope = np.diff(y, axis=0) / dxr
    s = _knot_slopes(x, dx, dxr, slope, y.shape)
    t = (s[:-1] + s[1:] - 2 * slope) / dxr
    c = np.stack((t / dxr, (slope - s[:-1]) / dxr - t, s[:-1], y[:-1]))
    return CubicSpline.construct_fast(np.ascontiguousarray(c), np.ascontiguousarray(x))


def _knot_slopes(x: np.ndarray, dx: np.ndarray, dxr: np.ndarray, slope: np.ndarray, shape: tuple[int, ...]
                ) -> np.ndarray:
    """The spline's slopes at the points (N, ...): the tridiagonal system of a C2 cubic with
    not-a-knot ends (de Boor, A Practical Guide to Splines, IV)."""
    n = len(x)
    A = np.zeros((3, n))  # banded: upper, main and lower diagonals
    b = np.empty((n, *shape[1:]))
    A[1, 1:-1] = 2 * (dx[:-1] + dx[1:])
    A[0, 2:] = dx[:-1]
    A[-1, :-2] = dx[1:]
    b[1:-1] = 3 * (dxr[1:] * slope[:-1] + dxr[:-1] * slope[1:])
    A[1, 0] = dx[1]
    A[0, 1] = x[2] - x[0]
    d = x[2] - x[0]
    b[0] = ((dxr[0] + 2 * d) * dxr[1] * slope[0] + dxr[0] ** 2 * slope[1]) / d
    A[1, -1] = dx[-2]
    A[-1, -2] = x[-1] - x[-3]
    d = x[-1] - x[-3]
    b[-1] = (dxr[-1] ** 2 * slope[-2] + (2 * d + dxr[-1]) * dxr[-2] * slope[-1]) / d
    _, _, _, s, info = _GTSV(A[2, :-1], A[1, :], A[0, 1:], b.reshape(n, -1), True, True, True, True)
    if info > 0:
        raise LinAlgError("singular matrix")
    return np.asarray(s).reshape(b.shape)
