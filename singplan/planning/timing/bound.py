"""A lower bound on the duration :func:`~singplan.planning.timing.move.time_move` gives a joint map,
cheap enough to rank auto's candidates before any of them is timed.

**Speeds no timing can exceed.** TOPP-RA solves, on its grid s_0 < ... < s_N, for squared path
speeds x_i = sd_i^2 and path accelerations u_i with x_{i+1} = x_i + 2 (s_{i+1} - s_i) u_i,
x_0 = x_N = 0, under ``x_i <= V_i`` (joint and TCP speed limits) and, for every joint j,
``|q_j'(s_i) u_i + q_j''(s_i) x_i| <= a_j`` and the same at s_{i+1} reached with
x_{i+1} = x_i + 2 ds u_i (Pham and Pham 2018, section III, the interpolation scheme). Each of
these constraints alone bounds u_i by a line in x_i, so:

- forward, x_{i+1} <= min over lines of max over x in [0, X_i] of (x + 2 ds ub(x)) =: X_{i+1};
- backward, x_i + 2 ds lb(x_i) <= x_{i+1} <= Y_{i+1} gives x_i <= Y_i for every line that keeps
  the left side increasing.

Every feasible profile has x_i <= C_i = min(V_i, X_i, Y_i), and between grid points (constant
path acceleration) x is linear in s, so under the line through C_i and C_{i+1}. The tightening
passes only lower the limits and the rounding to whole periods slows the profile uniformly: the
profile a timing's samples are taken from stays under C.

**Samples.** The samples are that profile at every period, so between two of them the path
advances at most as far as C lets it in one period; and an accepted timing's samples advance
the TCP clock (time at the programmed speed) by at most ``TCP_MARGIN`` periods each (the check
of :mod:`~singplan.planning.timing.move`, exact for LIN and CIRC; where the joint map leaves the path
the clock follows the TCP's own travel, never less than the path's). Stepping as far as both allow,
sample after sample, reaches the end in the fewest samples any accepted timing can have (each
step's reach only grows with where it starts): that count of periods is the bound, up to
TOPP-RA's solver tolerance (a 1e-6 relative margin).
"""

from __future__ import annotations

import math

import numpy as np

from singplan.kinematics.compiled import jit
from singplan.planning.timing.profile import fewest_samples
from singplan.planning.timing.ratios import TCP_MARGIN
from singplan.planning.timing.records import UNSCALED, LimitScale, MoveLimits
from singplan.planning.timing.toppra import TimingPath

# TOPP-RA's profile was measured up to 3.3e-8 (relative) over the caps on the public examples (its
# constraint data pass through single precision); tests/test_bound.py holds it under this margin
_MARGIN = 1.0 + 1e-6


def duration_bound_s(path: TimingPath, limits: MoveLimits, period_s: float,
                     scale: LimitScale = UNSCALED, pass_s: float = 0.0) -> float:
    """No timing of ``path`` under ``limits`` ends sooner than this [s], a whole number of periods.

    ``scale``: where a timing pass has tightened the limits to these factors (the later passes
    only tighten further); the samples are still checked against ``limits`` themselves.
    ``pass_s``: that pass's own TOPP-RA duration [s]: the later passes, at tighter limits, take no
    less (TOPP-RA is time-optimal for its constraints), so the bound is at least it, rounded.
    0 where no bound is known: a jerk limit or the quintic law (their time laws are checked on the
    samples only), a chain of moves (varying limits), a move that changes nothing.
    """
    if (path.spline is None or limits.jerk_rad_s3 is not None or limits.quintic
            or limits.velocity_at is not None or limits.clock is not None):
        return 0.0
    tau, vmax_1, amax_1 = path.scaled_limits(limits, scale)
    caps = speed_caps(path, vmax_1, amax_1)  # (G,) C_i, dimensionless
    # the path's time at programmed speed to the end [s] (a trace of the TCP's own travel only adds
    # to it: every step advances its coordinate at least as far as the path's)
    clock_s = limits.length_m / limits.tcp_speed_m_s if limits.tcp_speed_m_s and limits.length_m > 0 else 0.0
    clock_step = TCP_MARGIN * period_s / clock_s * _MARGIN if clock_s > 0 else math.inf
    samples = fewest_samples(path.grid, np.sqrt(caps), period_s / tau * _MARGIN, clock_step)  # the period in tau
    after_pass = max(1, math.ceil(pass_s / _MARGIN / period_s - 1e-9)) if pass_s > 0.0 else 0  # as _sample rounds
    return max(samples, after_pass) * period_s if samples > 0 else 0.0


def speed_caps(path: TimingPath, vmax_1: np.ndarray, amax_1: np.ndarray) -> np.ndarray:
    """C_i (G,): the squared path speed no profile on ``path``'s grid can exceed under the
    dimensionless limits (:meth:`TimingPath.scaled_limits`)."""
    d1, d2 = path.derivatives
    caps = _velocity_caps(d1, vmax_1)
    _forward(path.grid, d1, d2, amax_1, caps)
    _backward(path.grid, d1, d2, amax_1, caps)
    return caps


@jit
def _velocity_caps(d1: np.ndarray, vmax: np.ndarray) -> np.ndarray:  # pragma: no cover - compiled
    """V_i (G,) from every coordinate's speed limit, 0 at the start."""
    g, m = d1.shape
    cap = np.full(g, np.inf)
    for i in range(g):
        for j in range(m):
            if d1[i, j] != 0.0:
                cap[i] = min(cap[i], (vmax[j] / abs(d1[i, j])) ** 2)
    cap[0] = 0.0
    return cap


@jit
def _forward(grid: np.ndarray, d1: np.ndarray, d2: np.ndarray, amax: np.ndarray,
             cap: np.ndarray) -> None:  # pragma: no cover - compiled
    """cap_{i+1} = min(cap_{i+1}, X_{i+1}): as fast as every acceleration line lets x grow."""
    m = d1.shape[1]
    for i in range(len(grid) - 1):
        ds = grid[i + 1] - grid[i]
        reach = cap[i + 1]
        for j in range(2 * m):
            a, b = _line(d1, d2, i, j, ds)
            if a == 0.0:
                continue
            top = amax[j % m] if a > 0.0 else -amax[j % m]  # u <= (top - b x) / a
            reach = min(reach, max(2.0 * ds * top / a, cap[i] + 2.0 * ds * (top - b * cap[i]) / a))
        cap[i + 1] = max(reach, 0.0)


@jit
def _backward(grid: np.ndarray, d1: np.ndarray, d2: np.ndarray, amax: np.ndarray,
              cap: np.ndarray) -> None:  # pragma: no cover - compiled
    """cap_i = min(cap_i, Y_i), from rest at the end: slow enough for every line to stop in time."""
    m = d1.shape[1]
    cap[len(grid) - 1] = 0.0
    for i in range(len(grid) - 2, -1, -1):
        ds = grid[i + 1] - grid[i]
        for j in range(2 * m):
            a, b = _line(d1, d2, i, j, ds)
            if a == 0.0:
                continue
            low = -amax[j % m] if a > 0.0 else amax[j % m]  # u >= (low - b x) / a
            rise = 1.0 - 2.0 * ds * b / a  # x + 2 ds u >= x rise + 2 ds low / a
            if rise > 0.0:
                cap[i] = min(cap[i], (cap[i + 1] - 2.0 * ds * low / a) / rise)
        cap[i] = max(cap[i], 0.0)


@jit
def _line(d1: np.ndarray, d2: np.ndarray, i: int, j: int, ds: float) -> tuple[float, float]:  # pragma: no cover
    """Joint j % m's acceleration at stage i as a u + b x: at s_i (j < m), or at s_{i+1} reached
    with x + 2 ds u (TOPP-RA's interpolation scheme, j >= m)."""
    m = d1.shape[1]
    if j < m:
        return d1[i, j], d2[i, j]
    return d1[i + 1, j - m] + 2.0 * ds * d2[i + 1, j - m], d2[i + 1, j - m]
