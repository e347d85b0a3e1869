"""A path speed profile as TOPP-RA gives it: path speeds at grid points, constant path acceleration
between them; where it is at a time, when it reaches a point, and the fewest samples under it.

Between grid points s_i < s_{i+1} with path speeds sd_i, sd_{i+1} the path acceleration is
sdd_i = (sd_{i+1}^2 - sd_i^2) / (2 (s_{i+1} - s_i)) (the squared speed is linear in s), so the
interval takes 2 (s_{i+1} - s_i) / (sd_i + sd_{i+1}) and, tau into it, the path is at
s_i + sd_i tau + sdd_i tau^2 / 2. These formulas live here alone: the timing samples a profile
with them (:class:`Profile`), the duration bound steps along its speed caps with them
(:func:`fewest_samples`). The loops are compiled (a count runs per sample, up to millions).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from singplan.kinematics.compiled import jit


@dataclass(frozen=True)
class Profile:
    """Path speed ``sd`` at the grid points, constant path acceleration between."""

    grid: np.ndarray  # (G,) path parameter u
    sd: np.ndarray  # (G,) du/dt [1/s]

    @property
    def t_nodes(self) -> np.ndarray:
        """(G,) the time at each grid point [s]."""
        return node_times(self.grid, self.sd)

    def u_at(self, t: np.ndarray) -> np.ndarray:
        """Path parameter at times t (K,) [s], exact for the constant-acceleration pieces."""
        return _positions_at(self.grid, self.sd, self.t_nodes, np.asarray(t, dtype=float))


@jit
def node_times(grid: np.ndarray, sd: np.ndarray) -> np.ndarray:  # pragma: no cover - compiled
    """(G,) the time at each grid point [s] of the profile with path speeds sd (G,); inf past a stop."""
    t = np.zeros(len(grid))
    for i in range(len(grid) - 1):
        speed = sd[i] + sd[i + 1]
        t[i + 1] = t[i] + (2.0 * (grid[i + 1] - grid[i]) / speed if speed > 0.0 else math.inf)
    return t


@jit
def _interval(nodes: np.ndarray, value: float) -> int:  # pragma: no cover - compiled
    """The interval [nodes[i], nodes[i + 1]) holding value (the first before it, the last after it)."""
    return min(max(int(np.searchsorted(nodes, value, side="right")) - 1, 0), len(nodes) - 2)


@jit
def _position_at(grid: np.ndarray, sd: np.ndarray, t_node: np.ndarray, i: int,
                 t: float) -> float:  # pragma: no cover - compiled
    """Path parameter at time t [s] in interval i (not past its end)."""
    ds = grid[i + 1] - grid[i]
    sdd = (sd[i + 1] * sd[i + 1] - sd[i] * sd[i]) / (2.0 * ds)
    tau = t - t_node[i]
    return min(grid[i] + sd[i] * tau + 0.5 * sdd * (tau * tau), grid[i + 1])


@jit
def _time_at(grid: np.ndarray, sd: np.ndarray, t_node: np.ndarray, i: int,
             s: float) -> float:  # pragma: no cover - compiled
    """The time [s] the profile reaches path parameter s in interval i (the inverse of :func:`_position_at`)."""
    ds = grid[i + 1] - grid[i]
    w = s - grid[i]
    x = sd[i] * sd[i] + (sd[i + 1] * sd[i + 1] - sd[i] * sd[i]) * w / ds  # the squared speed at s
    return t_node[i] + 2.0 * w / (sd[i] + math.sqrt(max(x, 0.0)))


@jit
def _positions_at(grid: np.ndarray, sd: np.ndarray, t_node: np.ndarray,
                  t: np.ndarray) -> np.ndarray:  # pragma: no cover - compiled
    """:func:`_position_at` of each time t (K,) [s]."""
    out = np.empty(len(t))
    for k in range(len(t)):
        out[k] = _position_at(grid, sd, t_node, _interval(t_node, t[k]), t[k])
    return out


@jit
def fewest_samples(grid: np.ndarray, sd: np.ndarray, period: float,
                   clock_step: float) -> int:  # pragma: no cover - compiled
    """Periods to the end of a path no faster than the profile sd (G,), each period as far as the
    profile goes in ``period`` and at most ``clock_step`` of path parameter; 0 if the profile
    stops the path. ``period`` is in the time unit of ``sd`` (path parameter per unit): the
    duration bound passes speeds in its own scaled time and the period in the same scale.

    Each step starts where the last one ended, at the least time the profile needs to get there
    (:func:`_time_at`): the reach of a step only grows with where it starts, so no path under the
    profile and the clock takes fewer.
    """
    g = len(grid)
    for i in range(g - 1):
        if sd[i] + sd[i + 1] == 0.0:
            return 0  # the profile stops the path: TOPP-RA will say where
    t_node = node_times(grid, sd)
    count, s, t = 0, 0.0, 0.0  # samples so far; where the last one is and the least time to it
    while s < 1.0 - 1e-12:
        count += 1
        target = min(s + clock_step, 1.0)
        t_next = t + period
        reach = 1.0 if t_next >= t_node[g - 1] else _position_at(grid, sd, t_node, _interval(t_node, t_next), t_next)
        if reach <= target:
            s, t = reach, t_next
        else:
            s = target
            t = _time_at(grid, sd, t_node, _interval(grid, s), s)
    return count
