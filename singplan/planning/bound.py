"""A lower bound on the duration :func:`~singplan.planning.timing.time_move` gives a joint map,
cheap enough to rank auto's candidates before any of them is timed.

TOPP-RA solves, on its grid s_0 < ... < s_N, for squared path speeds x_i = sd_i^2 and path
accelerations u_i with x_{i+1} = x_i + 2 (s_{i+1} - s_i) u_i, x_0 = x_N = 0, under
``x_i <= V_i`` (joint and TCP speed limits) and, for every joint j,
``|q_j'(s_i) u_i + q_j''(s_i) x_i| <= a_j`` (Pham and Pham 2018, section III; its interpolation
scheme adds the same constraints at s_{i+1}, which only shrinks the feasible set). Each joint's
acceleration constraint alone bounds u_i by a line in x_i, so:

- forward, x_{i+1} <= min_j max over x in [0, X_i] of (x + 2 ds ub_j(x)) =: X_{i+1} (and <= V_{i+1});
- backward, x_i + 2 ds lb_j(x_i) <= x_{i+1} <= Y_{i+1} gives x_i <= Y_i for every joint whose line
  keeps the left side increasing.

Every feasible profile has x_i <= min(V_i, X_i, Y_i), and TOPP-RA's duration
sum 2 ds / (sd_i + sd_{i+1}) only grows as the speeds fall; the tightening passes lower the
limits and the duration is rounded up to whole periods, which keeps the order. The bound is thus
at most the duration TOPP-RA gives, up to its solver's tolerance (a 1e-6 relative margin).
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

from singplan.planning.timing import MoveLimits, TimingPath

_MARGIN = 1.0 - 1e-6  # TOPP-RA's solver keeps its constraints to about 1e-9 in these units


def duration_bound_s(path: TimingPath, limits: MoveLimits, period_s: float) -> float:
    """No timing of ``path`` under ``limits`` ends sooner than this [s], a whole number of periods.

    0 where no bound is known: a jerk limit or the quintic law (their time laws are checked on the
    samples only), a chain of moves (varying limits), a move that changes nothing.
    """
    if (path.spline is None or limits.jerk_rad_s3 is not None or limits.quintic
            or limits.velocity_at is not None or limits.clock is not None):
        return 0.0
    tau, vmax_1, amax_1 = path.scaled_limits(limits, (1.0, 1.0, 1.0, 1.0))
    d1 = np.ascontiguousarray(path.spline(path.grid, 1), dtype=float)  # (G, n + 1) dq/ds
    d2 = np.ascontiguousarray(path.spline(path.grid, 2), dtype=float)  # (G, n + 1) d2q/ds2
    duration = _reachable_duration(path.grid, d1, d2, vmax_1, amax_1) * tau * _MARGIN
    if not math.isfinite(duration):
        return 0.0  # the relaxed problem has no profile either: let TOPP-RA say where
    return max(1, math.ceil(duration / period_s - 1e-9)) * period_s  # as timing._sample rounds


@njit(cache=True, error_model="numpy")
def _reachable_duration(grid: np.ndarray, d1: np.ndarray, d2: np.ndarray, vmax: np.ndarray,
                        amax: np.ndarray) -> float:  # pragma: no cover - compiled
    """The duration of the fastest speeds min(V, X, Y) of the module's relaxation (dimensionless)."""
    g, m = d1.shape
    cap = np.empty(g)  # V_i, then min(V_i, X_i), then min(V_i, X_i, Y_i)
    for i in range(g):
        cap[i] = np.inf
        for j in range(m):
            if d1[i, j] != 0.0:
                cap[i] = min(cap[i], (vmax[j] / abs(d1[i, j])) ** 2)
    cap[0] = 0.0
    for i in range(g - 1):  # forward: as fast as any joint's acceleration lets x grow
        ds = grid[i + 1] - grid[i]
        reach = cap[i + 1]
        for j in range(m):
            a, b = d1[i, j], d2[i, j]
            if a == 0.0:
                continue
            top = amax[j] if a > 0.0 else -amax[j]  # u <= (top - b x) / a
            reach = min(reach, max(2.0 * ds * top / a, cap[i] + 2.0 * ds * (top - b * cap[i]) / a))
        cap[i + 1] = max(reach, 0.0)
    cap[g - 1] = 0.0
    for i in range(g - 2, -1, -1):  # backward: slow enough to stop in time
        ds = grid[i + 1] - grid[i]
        for j in range(m):
            a, b = d1[i, j], d2[i, j]
            if a == 0.0:
                continue
            low = -amax[j] if a > 0.0 else amax[j]  # u >= (low - b x) / a
            rise = 1.0 - 2.0 * ds * b / a  # x + 2 ds u >= x rise + 2 ds low / a
            if rise > 0.0:
                cap[i] = min(cap[i], (cap[i + 1] - 2.0 * ds * low / a) / rise)
        cap[i] = max(cap[i], 0.0)
    total = 0.0
    for i in range(g - 1):
        total += 2.0 * (grid[i + 1] - grid[i]) / (math.sqrt(cap[i]) + math.sqrt(cap[i + 1]))
    return total
