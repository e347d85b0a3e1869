"""Jerk-limited time laws of one move (``limits.jerk``) and SEEDS 003's quintic PTP law.

TOPP-RA (:mod:`~singplan.planning.timing.toppra`) has no jerk constraint: its path acceleration is bang-bang, so joint
accelerations jump within one sample. A time law here is a monotone u(t) from rest (u = 0)
to rest (u = 1) whose acceleration is zero at both ends and whose jerk is bounded:

- :class:`SmoothedLaw`: TOPP-RA's acceleration-limited u(t) averaged over a sliding window of
  w seconds, u_w(t) = (1/w) * integral of u over [t - w, t]. This is the S-curve construction of
  jerk-limited drives (a box filter on the velocity): the path is unchanged, the duration grows
  by w, path speed never exceeds the unfiltered one's maximum, and the path jerk becomes the
  difference of two path accelerations over w (bounded), instead of a jump.
- :class:`SCurveLaw`: the time-optimal seven-phase rest-to-rest profile of u under path speed,
  acceleration and jerk limits (what Ruckig computes for one axis), with TOPP-RA's peak path
  speed and acceleration: the optimum of a PTP, a fast candidate for straight-ish LINs.
- :class:`QuinticLaw`: u = 10 r^3 - 15 r^4 + 6 r^5 with r = t / T (SEEDS 003).

Joint jerk is q''' = f' u''' + 3 f'' u' u'' + f''' u'^3 for the joint map f(u): near a singular
zone the last terms dominate whatever the law. So :mod:`~singplan.planning.timing.smoothing`
stretches a law uniformly in time by k (joint speed scales by 1/k, acceleration by 1/k^2, jerk
by 1/k^3) until the output samples keep every limit, and picks the window that ends soonest.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np


@dataclass(frozen=True)
class SmoothedLaw:
    """TOPP-RA's piecewise constant-acceleration profile (times ``t_nodes``, path ``grid``, path
    speeds ``sd``) averaged over ``window_s``."""

    t_nodes: np.ndarray  # (G,) [s]
    grid: np.ndarray  # (G,) path parameter u at t_nodes
    sd: np.ndarray  # (G,) du/dt at t_nodes
    window_s: float

    @property
    def duration_s(self) -> float:
        return float(self.t_nodes[-1]) + self.window_s

    def u_at(self, t: np.ndarray) -> np.ndarray:
        """u_w(t) = (U(t) - U(t - w)) / w, with U the integral of u (u = 0 before 0, 1 after the end)."""
        return (self._integral(t) - self._integral(t - self.window_s)) / self.window_s

    def _integral(self, t: np.ndarray) -> np.ndarray:
        """Integral of u from 0 to t, exact for the constant-acceleration pieces."""
        nodes, end = self.t_nodes, float(self.t_nodes[-1])
        dt = np.diff(nodes)
        sdd = np.divide(np.diff(self.sd), dt, out=np.zeros_like(dt), where=dt > 0)
        piece = self.grid[:-1] * dt + self.sd[:-1] * dt**2 / 2.0 + sdd * dt**3 / 6.0
        cumulative = np.concatenate([[0.0], np.cumsum(piece)])
        tc = np.clip(t, 0.0, end)
        i = np.clip(np.searchsorted(nodes, tc, side="right") - 1, 0, len(nodes) - 2)
        tau = tc - nodes[i]
        inside = cumulative[i] + self.grid[i] * tau + self.sd[i] * tau**2 / 2.0 + sdd[i] * tau**3 / 6.0
        return inside + np.maximum(t - end, 0.0)  # at rest on u = 1 after the end


@dataclass(frozen=True)
class QuinticLaw:
    """u = 10 r^3 - 15 r^4 + 6 r^5, r = t / duration_s (SEEDS 003): zero speed and acceleration at both ends."""

    duration_s: float

    def u_at(self, t: np.ndarray) -> np.ndarray:
        r = np.clip(t / self.duration_s, 0.0, 1.0)
        return r**3 * (10.0 + r * (-15.0 + 6.0 * r))


@dataclass(frozen=True)
class SCurveLaw:
    """The time-optimal rest-to-rest move of u from 0 to 1 under path speed, acceleration and jerk
    limits (the seven-phase S-curve of jerk-limited drives, Ruckig's kind for one axis).

    For a PTP (a straight joint line) it is the exact optimum of the synchronised move; for other
    moves the limits come from TOPP-RA's profile and the samples decide (timing.py).
    """

    speed: float  # du/dt
    accel: float  # d2u/dt2
    jerk: float  # d3u/dt3

    def _phases(self) -> list[tuple[float, float]]:
        """(duration [s], jerk) of the seven phases."""
        v, a, j = self.speed, self.accel, self.jerk
        if v * (v / a + a / j if v * j >= a * a else 2.0 * np.sqrt(v / j)) > 1.0:  # no cruise: lower the peak
            v = a * (-a / j + np.sqrt(a * a / (j * j) + 4.0 / a)) / 2.0
            if v * j < a * a:
                v = float(np.cbrt(j / 4.0))
        ramp, hold = (a / j, v / a - a / j) if v * j >= a * a else (float(np.sqrt(v / j)), 0.0)
        cruise = max(0.0, 1.0 / v - (2.0 * ramp + hold))
        return [(ramp, j), (hold, 0.0), (ramp, -j), (cruise, 0.0), (ramp, -j), (hold, 0.0), (ramp, j)]

    @property
    def duration_s(self) -> float:
        return float(sum(d for d, _ in self._phases()))

    def u_at(self, t: np.ndarray) -> np.ndarray:
        phases = self._phases()
        starts = np.concatenate([[0.0], np.cumsum([d for d, _ in phases])])
        state = [(0.0, 0.0, 0.0)]  # (u, du/dt, d2u/dt2) at each phase start, integrated exactly
        for d, j in phases:
            p, v, a = state[-1]
            state.append((p + v * d + a * d**2 / 2.0 + j * d**3 / 6.0, v + a * d + j * d**2 / 2.0, a + j * d))
        tc = np.clip(t, 0.0, starts[-1])
        i = np.clip(np.searchsorted(starts, tc, side="right") - 1, 0, len(phases) - 1)
        tau = tc - starts[i]
        p0, v0, a0 = (np.array([s[k] for s in state[:-1]])[i] for k in range(3))
        jerk = np.array([j for _, j in phases])[i]
        return (p0 + v0 * tau + a0 * tau**2 / 2.0 + jerk * tau**3 / 6.0) / state[-1][0]  # 1 at the end


# Peaks of the quintic's derivatives for a unit step over unit time: speed 15/8 at r = 1/2,
# acceleration 10/sqrt(3) at r = 1/2 -+ sqrt(3)/6, jerk 60 at both ends.
QUINTIC_PEAKS = (1.875, 10.0 / np.sqrt(3.0), 60.0)


def quintic_duration(travel_rad: np.ndarray, vmax: np.ndarray, amax: np.ndarray,
                     jmax: np.ndarray | None) -> float:
    """The shortest quintic for joint travels (n,) within speed, acceleration and (optional) jerk limits."""
    speed, accel, jerk = QUINTIC_PEAKS
    need = [speed * travel_rad / vmax, np.sqrt(accel * travel_rad / amax)]
    if jmax is not None:
        need.append(np.cbrt(jerk * travel_rad / jmax))
    return float(np.max(need))
