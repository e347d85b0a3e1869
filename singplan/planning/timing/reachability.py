"""TOPP-RA's reachability analysis, compiled: the algorithm of toppra's ``TOPPRA`` class with its
Seidel solver (toppra 0.6), step for step, so its controllable sets and profile are toppra's own.

TOPP-RA (Pham and Pham, "A new approach to time-optimal path parameterization based on
reachability analysis", IEEE T-RO 2018) works on a grid s_0 < ... < s_N with the squared path
speed x_i and the path acceleration u_i of each stage, x_{i+1} = x_i + 2 (s_{i+1} - s_i) u_i.
Every constraint is a set of rows ``a_i u + b_i x + c_i <= 0`` and bounds on x_i. Backward from
rest at the end, the controllable set K_i = [lo, hi] of stage i is the range of x_i from which
some admissible u_i reaches K_{i+1} (two 2-variable LPs a stage); forward from rest at the start,
each stage takes the largest admissible u_i that stays controllable (a 1-variable LP).

toppra runs these loops in Python (about 30 us a stage); here they are compiled (numba), with
the same LP solver (Seidel's algorithm with toppra's warm start and tolerances), the same
rows (its interpolation scheme for accelerations: stage i also holds s_{i+1}'s rows, reached with
x_i + 2 delta_i u_i) and the same single-precision rounding of its joint speed bounds, so the
sets and speeds agree with toppra's to round-off (tests/test_reachability.py compares them on
random paths). docs/benchmarks.md says why this is not a library call: the TOPP-RA libraries
on PyPI (copp-py, cmeel-toppra, roboplan-toppra) were measured against toppra and none gives its
results from Python.

The constraints any :class:`toppra.constraint.LinearConstraint` describes (the torque
constraint) are turned into rows by toppra itself (:func:`toppra_rows`), as its solver does.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
import toppra.constraint as ta_constraint
from toppra.algorithm import ParameterizationReturnCode as ReturnCode
from toppra.interpolator import AbstractGeometricPath

from singplan.kinematics.compiled import jit

# toppra's Seidel solver (cy_seidel_solverwrapper.pyx)
_LP_TINY = 1e-10  # a row this close to satisfied, or a direction this close to 0, counts as such
_LP_SMALL = 1e-8  # a parallel row infeasible by more than this makes the LP infeasible
_VAR_BOUND = 1e8  # |u|, |x| at every stage
_LP_INF = 1e10  # the bounds of the 1-variable subproblems
# toppra's constants (toppra.constants) used by its algorithm
_TINY = 1e-8  # the forward pass's step back from the largest next x
_SMALL = 1e-5  # the start's tolerance against the controllable set
_MAX_TRIES = 10  # forward-pass retries with a lower x (toppra.constants.MAX_TRIES)
_MAXSD = 1e8  # the path speed a joint speed constraint allows at most (toppra.constants.JVEL_MAXSD)
_OBJECTIVE_U = 1e-9  # the u weight of the controllable sets' objectives


@dataclass(frozen=True)
class Reachability:
    """TOPP-RA's result on one grid.

    Attributes:
        code: toppra's return code (``Ok``, ``FailUncontrollable``, ``ErrUnknown``).
        sets: (G, 2) the controllable sets [lowest, highest squared path speed] at each grid point;
            NaN where the set came out empty and every stage before it 0.
        sd: (G,) the path speed of the forward pass; None unless ``code`` is ``Ok``.
        empty_at: the grid index where the controllable set first came out empty (the backward
            pass, from the end); None if it never did.
    """

    code: ReturnCode
    sets: np.ndarray  # (G, 2)
    sd: np.ndarray | None  # (G,)
    empty_at: int | None


def velocity_x_bounds(d1: np.ndarray, vmax: np.ndarray) -> np.ndarray:
    """The highest squared path speed (G,) that keeps every coordinate's speed |d1 sd| <= vmax.

    ``d1``: (G, d) path derivatives; ``vmax``: (d,) or, varying along the path, (G, d).
    As toppra's joint speed constraints (``_create_velocity_constraint``) compute it: the bound on
    sd in single precision, capped at 1e8, squared in single precision.
    """
    with np.errstate(divide="ignore", invalid="ignore"):
        ratio = np.where((d1 > 0.0) | (d1 < 0.0), vmax / np.abs(d1), np.inf)  # sign-symmetric as toppra's
    sd = np.minimum(np.min(ratio, axis=1, initial=np.inf), _MAXSD).astype(np.float32)
    return (sd * sd).astype(float)


def acceleration_rows(grid: np.ndarray, d1: np.ndarray, d2: np.ndarray,
                      amax: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Rows a u + b x + c <= 0 (G, 4d) each of |d1 u + d2 x| <= amax (d,) at s_i and at s_{i+1}
    (reached with x + 2 delta u), toppra's interpolation scheme (``canlinear_colloc_to_interpolate``);
    the last stage repeats its own rows."""
    ahead_a = np.empty_like(d1)
    ahead_a[:-1] = d1[1:] + 2 * np.diff(grid).reshape(-1, 1) * d2[1:]
    ahead_a[-1] = d1[-1]
    ahead_b = np.concatenate([d2[1:], d2[-1:]])
    a = np.hstack([d1, -d1, ahead_a, -ahead_a])
    b = np.hstack([d2, -d2, ahead_b, -ahead_b])
    c = np.broadcast_to(-np.tile(amax, 4), a.shape)
    return a, b, np.ascontiguousarray(c)


def toppra_rows(constraint: ta_constraint.LinearConstraint, path: AbstractGeometricPath,
                grid: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """A toppra constraint with the same inequality matrix at every grid point (``identical``: the
    torque constraint) as rows a u + b x + c <= 0 (G, k), computed as toppra's solver does."""
    a, b, c, f, g, ubound, xbound = constraint.compute_constraint_params(path, grid)
    if not constraint.identical or ubound is not None or xbound is not None:
        raise ValueError(f"{type(constraint).__name__}: only rows with a fixed inequality matrix are supported")
    return a.dot(f.T), b.dot(f.T), c.dot(f.T) - g


def solve(grid: np.ndarray, rows: list[tuple[np.ndarray, np.ndarray, np.ndarray]],
          x_high: np.ndarray) -> Reachability:
    """TOPP-RA from rest to rest on ``grid`` (G,) under the rows a u + b x + c <= 0 ((G, k) each)
    and 0 <= x <= x_high (G,) (:func:`velocity_x_bounds`)."""
    count = len(grid)
    width = 2 + sum(r[0].shape[1] for r in rows)  # toppra's two leading rows: the next stage's set
    a, b, c = (np.zeros((count, width)) for _ in range(3))
    column = 2
    for ra, rb, rc in rows:
        k = ra.shape[1]
        a[:, column:column + k], b[:, column:column + k], c[:, column:column + k] = ra, rb, rc
        column += k
    bounds = np.empty((count, 4))  # u low, x low, u high, x high
    bounds[:, 0], bounds[:, 1], bounds[:, 2] = -_VAR_BOUND, 0.0, _VAR_BOUND
    bounds[:, 3] = np.minimum(x_high, _VAR_BOUND)
    sets = np.zeros((count, 2))
    xs = np.zeros(count)
    code, empty_at = _solve(np.ascontiguousarray(grid, dtype=float), a, b, c, bounds, sets, xs)
    return_code = (ReturnCode.Ok, ReturnCode.FailUncontrollable, ReturnCode.ErrUnknown)[code]
    return Reachability(return_code, sets, np.sqrt(xs) if code == 0 else None, None if empty_at < 0 else empty_at)


@jit
def _solve(grid: np.ndarray, a: np.ndarray, b: np.ndarray, c: np.ndarray, bounds: np.ndarray,
           sets: np.ndarray, xs: np.ndarray) -> tuple[int, int]:  # pragma: no cover - compiled
    """toppra's ``compute_parameterization(0, 0)``: the sets (G, 2) and squared speeds xs (G,) filled;
    (0 ok / 1 uncontrollable / 2 forward pass failed, the stage where a set emptied or -1)."""
    n = len(grid) - 1
    deltas = grid[1:] - grid[:-1]
    state = _lp_state(a.shape[1])
    for i in range(n - 1, -1, -1):  # the controllable sets, from rest at the end (sets[n] = 0)
        high = _stage(i, deltas, a, b, c, bounds, state, _OBJECTIVE_U, -1.0, math.nan, math.nan,
                      sets[i + 1, 0], sets[i + 1, 1])[1]
        low = _stage(i, deltas, a, b, c, bounds, state, -_OBJECTIVE_U, 1.0, math.nan, math.nan,
                     sets[i + 1, 0], sets[i + 1, 1])[1]
        sets[i, 0] = 0.0 if low < 0.0 else low
        sets[i, 1] = high
        if math.isnan(sets[i, 0]) or math.isnan(sets[i, 1]):
            return 1, i
    if sets[0, 0] > _SMALL or sets[0, 1] + _SMALL < 0.0:  # the start at rest is not controllable
        return 1, -1
    xs[0] = 0.0
    tries = 0
    i = 0
    while i < n:  # forward: the largest controllable step
        u = _stage(i, deltas, a, b, c, bounds, state, -2.0 * deltas[i], -1.0, xs[i], xs[i],
                   sets[i + 1, 0], sets[i + 1, 1])[0]
        if math.isnan(u):
            if tries < _MAX_TRIES:
                xs[i] = max(xs[i] - _TINY, 0.999 * xs[i])
                tries += 1
                continue
            xs[i + 1:] = math.nan
            return 2, -1
        tries = 0
        x_next = xs[i] + 2.0 * deltas[i] * u
        x_next = max(x_next - _TINY, 0.9999 * x_next)
        xs[i + 1] = min(sets[i + 1, 1], max(sets[i + 1, 0], x_next))
        i += 1
    return 0, -1


@jit
def _lp_state(width: int) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray, np.ndarray]:  # pragma: no cover
    """The Seidel solver's working arrays: warm-start rows of the upper and lower solvers (2,) each,
    the row order (width,), the 1-variable subproblem's rows (width + 4,) x 2."""
    return (np.zeros(2, dtype=np.int64), np.zeros(2, dtype=np.int64), np.zeros(width, dtype=np.int64),
            np.zeros(width + 4), np.zeros(width + 4))


@jit
def _stage(i: int, deltas: np.ndarray, a: np.ndarray, b: np.ndarray, c: np.ndarray, bounds: np.ndarray,
           state: tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray, np.ndarray], g0: float, g1: float,
           x_min: float, x_max: float, x_next_min: float,
           x_next_max: float) -> tuple[float, float]:  # pragma: no cover - compiled
    """toppra's ``seidelWrapper.solve_stagewise_optim``: minimise g0 u + g1 x at stage i with
    x_min <= x <= x_max and x_next_min <= x + 2 delta_i u <= x_next_max (NaN: no such bound);
    (u, x), NaN when infeasible. With x_min == x_max, a 1-variable LP in u."""
    up, down, order, a1, b1 = state
    n = len(deltas)
    low0, low1, high0, high1 = bounds[i, 0], bounds[i, 1], bounds[i, 2], bounds[i, 3]
    if not math.isnan(x_min):
        low1 = low1 if low1 > x_min else x_min
    if not math.isnan(x_max):
        high1 = high1 if high1 < x_max else x_max
    if i < n and not math.isnan(x_next_min):
        a[i, 0], b[i, 0], c[i, 0] = -2.0 * deltas[i], -1.0, x_next_min
    else:
        a[i, 0], b[i, 0], c[i, 0] = 0.0, 0.0, -1.0
    if i < n and not math.isnan(x_next_max):
        a[i, 1], b[i, 1], c[i, 1] = 2.0 * deltas[i], 1.0, -x_next_max
    else:
        a[i, 1], b[i, 1], c[i, 1] = 0.0, 0.0, -1.0
    v0, v1 = -g0, -g1
    if x_min == x_max:
        width = a.shape[1]
        for k in range(width):
            b1[k] = b[i, k] * x_min + c[i, k]
        ok, u, active = _lp1d(v0, width, a[i], b1, low0, high0)
        if not ok:
            return math.nan, math.nan
        if g1 > 0:
            up[0] = active
        else:
            down[0] = active
        return u, x_min
    warm = up if g1 > 0 else down
    ok, u, x, row0, row1 = _lp2d(v0, v1, a[i], b[i], c[i], low0, low1, high0, high1, warm, order, a1, b1)
    if not ok:
        return math.nan, math.nan
    warm[0], warm[1] = row0, row1
    return u, x


@jit
def _lp1d(v0: float, rows: int, a: np.ndarray, b: np.ndarray, low: float,
          high: float) -> tuple[bool, float, int]:  # pragma: no cover - compiled
    """Maximise v0 x subject to a x + b <= 0 (the first ``rows``) and low <= x <= high: (feasible, x,
    the active row: -1 low, -2 high). toppra's ``cy_solve_lp1d``."""
    cur_min, active_min, cur_max, active_max = low, -1, high, -2
    for k in range(rows):
        if a[k] > _LP_TINY:
            x = -b[k] / a[k]
            if x < cur_max:
                cur_max, active_max = x, k
        elif a[k] < -_LP_TINY:
            x = -b[k] / a[k]
            if x > cur_min:
                cur_min, active_min = x, k
    if cur_min > cur_max:
        return False, math.nan, 0
    if abs(v0) < _LP_TINY or v0 < 0:
        return True, cur_min, active_min
    return True, cur_max, active_max


@jit
def _lp2d(v0: float, v1: float, a: np.ndarray, b: np.ndarray, c: np.ndarray, low0: float, low1: float,
          high0: float, high1: float, warm: np.ndarray, order: np.ndarray, a1: np.ndarray,
          b1: np.ndarray) -> tuple[bool, float, float, int, int]:  # pragma: no cover - compiled
    """Maximise v0 u + v1 x subject to a u + b x + c <= 0 and the box, by Seidel's algorithm with the
    rows in ``warm`` (last stage's active rows) tried first: (feasible, u, x, the two active rows;
    -1..-4 the box's u low, u high, x low, x high). toppra's ``cy_solve_lp2d``."""
    rows = len(a)
    if low0 > high0 or low1 > high1:
        return False, math.nan, math.nan, 0, 0
    cur0, row0 = (high0, -2) if v0 > _LP_TINY else (low0, -1)
    cur1, row1 = (high1, -4) if v1 > _LP_TINY else (low1, -3)
    if 0 <= warm[0] < rows and 0 <= warm[1] < rows and warm[0] != warm[1]:
        order[0], order[1] = warm[1], warm[0]
        filled = 2
        for k in range(rows):
            if k != warm[0] and k != warm[1]:
                order[filled] = k
                filled += 1
    else:
        for k in range(rows):
            order[k] = k
    for k in range(rows):
        r = order[k]
        if a[r] * cur0 + b[r] * cur1 + c[r] < _LP_TINY:
            continue
        row0 = r
        norm = a[r] * a[r] + b[r] * b[r]
        origin0 = -a[r] * c[r] / norm  # the origin projected on the row's line
        origin1 = -b[r] * c[r] / norm
        tan0, tan1 = -b[r], a[r]  # along the line
        for j in range(k + 4):  # the rows before it and the box, on the line
            if j == k:
                aj, bj, cj = -1.0, 0.0, low0
            elif j == k + 1:
                aj, bj, cj = 1.0, 0.0, -high0
            elif j == k + 2:
                aj, bj, cj = 0.0, -1.0, low1
            elif j == k + 3:
                aj, bj, cj = 0.0, 1.0, -high1
            else:
                aj, bj, cj = a[order[j]], b[order[j]], c[order[j]]
            denom = tan0 * aj + tan1 * bj
            if denom > _LP_TINY:
                a1[j], b1[j] = 1.0, (cj + origin1 * bj + origin0 * aj) / denom
            elif denom < -_LP_TINY:
                a1[j], b1[j] = -1.0, -(cj + origin1 * bj + origin0 * aj) / denom
            else:  # parallel to the row
                if cj + origin1 * bj + origin0 * aj > _LP_SMALL:
                    return False, math.nan, math.nan, 0, 0
                a1[j], b1[j] = 0.0, -1.0
        ok, t, active = _lp1d(tan0 * v0 + tan1 * v1, k + 4, a1, b1, -_LP_INF, _LP_INF)
        if not ok or active < 0:  # active < 0: the subproblem's own bounds (toppra: infeasible)
            return False, math.nan, math.nan, 0, 0
        cur0, cur1 = origin0 + t * tan0, origin1 + t * tan1
        row1 = order[active] if active < k else k - active - 1  # k..k+3: the box, -1..-4
    return True, cur0, cur1, row0, row1
