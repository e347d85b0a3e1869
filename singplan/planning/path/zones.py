"""Singular zones along a path.

Per sample, the signed distances of :mod:`singplan.kinematics.configuration` (wrist and elbow angles
[rad], shoulder distance [m]). A zone of one kind is a maximal run of the path where its
|distance| is under the task's threshold and whose closest approach comes within
:data:`SINGULAR_REACH` of the singularity (10 deg, 66.7 mm: a run under a wide threshold that stays
further off needs no crossing); its entry and exit (SEEDS 000's points 48 and 50)
are interpolated between samples. Each zone also records where the path comes closest to
the singularity and how close, refined between samples by zooming in on a vectorised grid.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass

import numpy as np

from singplan.kinematics.configuration import distances_batch, labels_from_distances
from singplan.kinematics.robot import Robot

KINDS = ("wrist", "shoulder", "elbow")
KIND_INDEX = {kind: i for i, kind in enumerate(KINDS)}  # columns of the signed distances
# A crossing passes near its singularity: a segment marked crossing holds a sample this close (an
# independent checker's measure: wrist and elbow 15 deg, shoulder 100 mm) ...
NEAR_SINGULAR = {"wrist": math.radians(15.0), "shoulder": 0.10, "elbow": math.radians(15.0)}
# ... and a zone is a singular zone only where its closest approach is within two thirds of that: under
# a wide threshold (up to 90 deg, 1000 mm) a stretch that stays further from every singularity needs
# no crossing, and one that comes this close keeps a sample within NEAR_SINGULAR around its closest point
SINGULAR_REACH = {kind: value * 2.0 / 3.0 for kind, value in NEAR_SINGULAR.items()}
# closest-point search: 17 points a round, 4 rounds narrow two sample intervals 8**4-fold
# (to ~0.5 um of path on the 2 mm grid); each point costs an exact IK of all branches
_ZOOM = (17, 4)


@dataclass(frozen=True)
class Zone:
    """A singular zone of one move, in the move's path parameter u in [0, 1].

    Attributes:
        kind: "wrist" | "shoulder" | "elbow".
        u_entry, u_exit: where |distance| crosses the threshold (0 / 1 if the move starts / ends inside).
        u_closest: where |distance| is smallest.
        min_distance: smallest |distance| [rad for wrist/elbow, m for shoulder].
        threshold: the detection threshold, same unit.
        window: the stretch [u0, u1] the crossing's joint-map part replaced, where a method
            crossed the zone (it may start before the entry or end after the exit, e.g. the
            wrist-joint blend window); None where no crossing was made.
    """

    kind: str
    u_entry: float
    u_exit: float
    u_closest: float
    min_distance: float
    threshold: float
    window: tuple[float, float] | None = None

    @property
    def span(self) -> tuple[float, float]:
        """The stretch of u its crossing segment covers: the window, else the zone itself."""
        return self.window if self.window is not None else (self.u_entry, self.u_exit)

    @property
    def unit(self) -> str:
        return "m" if self.kind == "shoulder" else "rad"

    def describe_distance(self, value: float | None = None) -> str:
        v = self.min_distance if value is None else value
        return f"{v * 1e3:.3f} mm" if self.kind == "shoulder" else f"{math.degrees(v):.4f} deg"


def distances_along(robot: Robot, q: np.ndarray) -> tuple[np.ndarray, list[str]]:
    """Signed (wrist, shoulder, elbow) distances (N, 3) and labels at joint samples q (N, n)."""
    d = distances_batch(robot, q)
    return d, labels_from_distances(d)


DistanceFunction = Callable[[np.ndarray, int], np.ndarray]  # (u (M,), kind index) -> |distance| (M,)


def find_zones(u: np.ndarray, dist: np.ndarray, thresholds: np.ndarray,
               abs_distance_at: DistanceFunction | None = None, continued: str | None = None) -> list[Zone]:
    """Zones from sampled distances; ``abs_distance_at(u, index)`` refines the closest point.

    ``continued``: the samples start inside a zone of this kind already measured (the rest of
    a crossed zone), so a zone of that kind open at the first sample is not refined again.
    """
    d = np.abs(dist)  # (N, 3)
    inside = np.zeros((len(u) + 2, 3), dtype=np.int8)
    inside[1:-1] = d < thresholds
    edges = np.diff(inside, axis=0)  # +1 where a run of samples inside starts, -1 after it ends
    start_k, start_i = np.nonzero(edges == 1)
    stop_k, stop_i = np.nonzero(edges == -1)
    zones = []
    for i, kind in enumerate(KINDS):
        for start, stop in zip(start_k[start_i == i].tolist(), stop_k[stop_i == i].tolist(), strict=True):
            refine = None if kind == continued and start == 0 else abs_distance_at
            zone = _zone(kind, u, d[:, i], thresholds[i], start, stop - 1, refine, i)
            if zone.min_distance < SINGULAR_REACH[kind] or (kind == continued and start == 0):
                zones.append(zone)
    return sorted(zones, key=lambda z: z.u_entry)


def _crossing_u(u: np.ndarray, d: np.ndarray, thr: float, a: int, b: int) -> float:
    """Where |distance| reaches thr between samples a and b (linear in u)."""
    if d[a] == d[b]:
        return float(u[a])
    t = (thr - d[a]) / (d[b] - d[a])
    return float(u[a] + min(1.0, max(0.0, t)) * (u[b] - u[a]))


def _zone(kind: str, u: np.ndarray, d: np.ndarray, thr: float, start: int, end: int,
          refine: DistanceFunction | None, index: int) -> Zone:
    u_entry = 0.0 if start == 0 else _crossing_u(u, d, thr, start - 1, start)
    u_exit = 1.0 if end == len(u) - 1 else _crossing_u(u, d, thr, end, end + 1)
    k = start + int(np.argmin(d[start:end + 1]))
    u_best, d_best = float(u[k]), float(d[k])
    if refine is not None:
        lo, hi = float(u[max(k - 1, 0)]), float(u[min(k + 1, len(u) - 1)])
        u_ref, d_ref = _zoom_min(lambda x: refine(x, index), lo, hi, *_ZOOM)
        if d_ref < d_best:
            u_best, d_best = u_ref, d_ref
    return Zone(kind, u_entry, u_exit, u_best, d_best, float(thr))


def _zoom_min(f: Callable[[np.ndarray], np.ndarray], lo: float, hi: float, points: int,
              levels: int) -> tuple[float, float]:
    """Minimum of f on [lo, hi]: evaluate a grid, zoom on the best cell, repeat (f is vectorised)."""
    best_u, best_d = lo, math.inf
    unit = np.linspace(0.0, 1.0, points)
    for _ in range(levels):
        grid = lo + (hi - lo) * unit
        values = f(grid)
        k = int(np.argmin(values))
        if values[k] < best_d:
            best_u, best_d = float(grid[k]), float(values[k])
        step = (hi - lo) / (points - 1)
        lo, hi = max(lo, grid[k] - step), min(hi, grid[k] + step)
    return best_u, best_d
