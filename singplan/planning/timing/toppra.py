"""TOPP-RA's part of timing a move: the joint map handed to it as a dimensionless path
(:class:`TimingPath`) and the fastest path speed profile under the joint velocity, acceleration
(and torque) limits and the TCP speed cap (:func:`toppra_profile`).

TOPP-RA (Pham and Pham, "A new approach to time-optimal path parameterization based on
reachability analysis", IEEE T-RO 2018) finds the fastest path speed profile under joint
velocity and acceleration limits. The path handed to it is the move's joint map sampled at
its reference points, extended by one coordinate ``s = u * L`` (arc length [m]) whose
velocity limit is the programmed TCP speed: that caps the TCP speed and, where joints would
exceed their limits, slows the path instead of leaving it (SEEDS 002's speed scaleback). Along
a chain the joint speed limits are each move's own and the TCP cap follows a clock (time at the
programmed speeds) whose rate bounds the path speed directly: both vary along the path.
The algorithm itself is toppra's, compiled (:mod:`~singplan.planning.timing.reachability`).
"""

from __future__ import annotations

import logging
import math
from dataclasses import dataclass, replace
from functools import cached_property

import numpy as np
import toppra as ta
import toppra.constraint as ta_constraint

from singplan.kinematics.dynamics import PathDynamics, TorqueLimit
from singplan.planning.path.jointmap import JointMap
from singplan.planning.path.spline import not_a_knot
from singplan.planning.timing import reachability
from singplan.planning.timing.profile import Profile
from singplan.planning.timing.records import LimitScale, MoveLimits, TimingError

logging.getLogger("toppra").setLevel(logging.ERROR)  # its retries are not our warnings

_UNLIMITED = 1e9
_CLOCK_SUBSTEPS = 8  # differences per grid interval that find a chain clock's largest rate
_KNOT_GAP = 1e-12  # reference samples closer than this in u are one


def _reference(jmap: JointMap, limits: MoveLimits) -> tuple[np.ndarray, np.ndarray]:
    if limits.trace is not None and limits.clock is None and not jmap.straight:
        # the TCP's travel where the map leaves the path: its dense samples in the reference too,
        # so that TOPP-RA's TCP coordinate follows it (not on a straight joint line: see below; its
        # samples' TCP speed is checked like any, and the limits tightened where it runs over)
        u, q = _reference(jmap, replace(limits, trace=None))
        extra = _apart(limits.trace.u, u)
        if extra.size == 0:
            return u, q
        order = np.argsort(np.concatenate([u, extra]), kind="stable")
        return np.concatenate([u, extra])[order], np.concatenate([q, jmap.evaluate(extra)])[order]
    if jmap.straight:
        # A straight joint line: points graded toward the ends (below) only add round-off, in which
        # a joint that barely moves beside one that moves far made TOPP-RA's instance "not controllable".
        dense = np.linspace(0.0, 1.0, 9)
        return dense, jmap.evaluate(dense)
    u, q = jmap.reference()
    # Where a move starts or ends on a reach boundary (a stretched elbow) a joint goes as the
    # square root of the distance to the end: its path derivative grows without bound there. Points
    # graded toward both ends let the spline and TOPP-RA's grid see it, so the move still stops
    # with every joint at rest instead of the elbow arriving at speed.
    ends = 10.0 ** -np.arange(3.0, 10.0)
    extra = np.setdiff1d(np.concatenate([ends, 1.0 - ends]), u)  # only these need solving
    order = np.argsort(np.concatenate([u, extra]), kind="stable")
    u, q = np.concatenate([u, extra])[order], np.concatenate([q, jmap.evaluate(extra)])[order]
    keep = np.concatenate([[True], np.diff(u) > _KNOT_GAP])
    u, q = u[keep], q[keep]
    if len(u) < 4:  # a spline needs a few points; add interior ones (straight PTP lines)
        dense = np.linspace(0.0, 1.0, 9)
        return dense, jmap.evaluate(dense)
    return u, q


def _apart(points: np.ndarray, u: np.ndarray) -> np.ndarray:
    """The points (sorted) more than ``_KNOT_GAP`` from every sample of u (sorted) and from each other:
    two samples a rounding apart (a trace point beside the map's own) make a degenerate spline interval
    and a TOPP-RA stage of zero width, whose sets come out empty ("not controllable")."""
    points = np.setdiff1d(points, u)
    points = points[np.concatenate([[True], np.diff(points) > _KNOT_GAP])] if points.size else points
    k = np.searchsorted(u, points)
    gap = np.minimum(np.abs(points - u[np.maximum(k - 1, 0)]), np.abs(u[np.minimum(k, len(u) - 1)] - points))
    return points[gap > _KNOT_GAP]


def path_scale(q: np.ndarray, limits: MoveLimits) -> float:
    """The move's size: the largest travel of any joint [rad] or of the TCP [m] along it."""
    travel = float(np.max(np.sum(np.abs(np.diff(q, axis=0)), axis=0), initial=0.0))
    return max(travel, limits.length_m)


@dataclass(frozen=True)
class TimingPath:
    """A move's joint map as TOPP-RA is handed it, built once for its duration bound
    (:mod:`~singplan.planning.timing.bound`) and every tightening pass.

    TOPP-RA works in the squared path speed with absolute tolerances. Along u in [0, 1] a 10 um
    LIN has path derivatives of 1e-6 and path speeds of 1e4 / s, whose squares defeat those
    tolerances ("not controllable"). So the joints (and the TCP's coordinate) are divided by the
    move's size L, and time by ``tau = sqrt(L / a)`` (:meth:`scaled_limits`), the time the
    slowest-accelerating joint needs to cover L: derivatives, path speeds and the duration are
    then all of order one whatever the size of the move, and the result is exact in the original units.
    """

    u: np.ndarray  # (K,) the reference samples' path parameters
    q: np.ndarray  # (K, n) their joints [rad]
    length: float  # L: the largest travel of any joint [rad] or of the TCP [m] (path_scale)
    spline: ta.SplineInterpolator | None  # u -> ((q - q[0]) / L, TCP coordinate / L), (n + 1,); None: L = 0
    grid: np.ndarray  # (G,) TOPP-RA's grid points
    # the TCP coordinate's speed cap [m/s] (the coordinate is the TCP's clock times it); None: uncapped
    tcp_speed_m_s: float | None

    def scaled_limits(self, limits: MoveLimits, scale: LimitScale
                      ) -> tuple[float, np.ndarray, np.ndarray]:
        """tau [s], and the velocity (n + 1,) and acceleration (n + 1,) limits in dimensionless units,
        the joints' and TCP speed's times ``scale`` (velocity, TCP speed, acceleration, torque)."""
        amax = limits.acceleration_rad_s2 * scale.acceleration
        tau = math.sqrt(self.length / float(np.min(amax)))
        tcp = self.tcp_speed_m_s * scale.tcp_speed if self.tcp_speed_m_s is not None else _UNLIMITED
        vmax = np.append(limits.velocity_rad_s * scale.velocity, tcp)
        return (tau, np.minimum(vmax * tau / self.length, _UNLIMITED),
                np.append(amax * tau**2 / self.length, _UNLIMITED))

    @cached_property
    def derivatives(self) -> tuple[np.ndarray, np.ndarray]:
        """The spline's first and second derivatives at the grid points, (G, n + 1) each."""
        assert self.spline is not None
        return (np.ascontiguousarray(self.spline(self.grid, 1), dtype=float),
                np.ascontiguousarray(self.spline(self.grid, 2), dtype=float))


def timing_path(jmap: JointMap, limits: MoveLimits, move_index: int) -> TimingPath:
    """The joint map's reference samples and TOPP-RA's dimensionless path over them.

    Raises TimingError where the joint map has no joint values (no IK solution).
    """
    u, q = _reference(jmap, limits)
    missing = np.flatnonzero(~np.all(np.isfinite(q), axis=1))
    if len(missing):  # a joint map without IK somewhere: never hand NaN to TOPP-RA
        raise TimingError(move_index, float(u[missing[0]]), "no joint values (no inverse kinematics solution)")
    length = path_scale(q, limits)
    if length == 0.0:
        return TimingPath(u, q, 0.0, None, u, None)
    # the TCP's clock (time at programmed speed, whose rate is capped at 1) times a reference speed,
    # so the coordinate keeps the size of an arc length
    # (a chain's clock kinks where its moves' speeds change, which a spline would ring at: there the
    # coordinate is u itself and the clock's rate caps its speed in the varying bounds)
    clock = limits.tcp_clock(u) if limits.clock is None else None
    tcp_speed_m_s = limits.tcp_speed_m_s if clock is not None else None
    extra = clock * tcp_speed_m_s if clock is not None and tcp_speed_m_s else u * length  # no cap: the move's size
    spline = _Spline(u, np.hstack([q - q[0], extra[:, None]]) / length)  # from 0: no digits lost
    return TimingPath(u, q, length, spline, _grid(u), tcp_speed_m_s)


class _Spline(ta.SplineInterpolator):
    """toppra's ``SplineInterpolator(u, waypoints)`` (not-a-knot ends) with its spline made by
    :func:`~singplan.planning.path.spline.not_a_knot`: the same curve and derivatives, bit for bit,
    without scipy's input checks (a few of these a move)."""

    def __init__(self, u: np.ndarray, waypoints: np.ndarray) -> None:
        ta.interpolator.AbstractGeometricPath.__init__(self)
        self.ss_waypoints = np.array(u)
        self._q_waypoints = np.array(waypoints)
        self.cspl = not_a_knot(self.ss_waypoints, self._q_waypoints)
        self.cspld = self.cspl.derivative()
        self.cspldd = self.cspld.derivative()


def toppra_profile(path: TimingPath, limits: MoveLimits, scale: LimitScale,
                    move_index: int) -> Profile:
    """TOPP-RA on the move made dimensionless (:class:`TimingPath`); ``scale`` multiplies the joint
    velocity, TCP speed, acceleration and torque limits (the tightening passes). toppra's algorithm
    and constraints, compiled (:mod:`~singplan.planning.timing.reachability`)."""
    assert path.spline is not None
    tau, vmax_1, amax_1 = path.scaled_limits(limits, scale)
    d1, d2 = path.derivatives
    rows = [reachability.acceleration_rows(path.grid, d1, d2, amax_1)]
    if limits.torque is not None:
        torque = _torque_constraint(limits.torque, path.q[0], path.length, tau, scale.torque)
        rows.append(reachability.toppra_rows(torque, path.spline, path.grid))
    speeds = _velocity_bounds(limits, vmax_1, scale.velocity * tau / path.length, scale.tcp_speed * tau, path.grid)
    result = reachability.solve(path.grid, rows, reachability.velocity_x_bounds(d1, speeds))
    if result.sd is None:
        if limits.torque is not None:
            _check_holding_torque(limits.torque, path.u, path.q, move_index)
        at = None if result.empty_at is None else float(path.grid[result.empty_at])
        where = "" if at is not None else "; TOPP-RA did not say where: the path's steepest point"
        raise TimingError(move_index, at if at is not None else _steepest_at(path.u, path.q, limits.velocity_rad_s),
                          f"TOPP-RA found no feasible time-parameterisation ({result.code.value}; the "
                          f"joint velocity{', acceleration and torque' if limits.torque else ' and acceleration'} "
                          f"limits cannot hold the path there{where})")
    return Profile(path.grid, np.maximum(result.sd, 0.0) / tau)  # du/dt in real time


def _velocity_bounds(limits: MoveLimits, vmax_1: np.ndarray, factor: float, clock_factor: float,
                     grid: np.ndarray) -> np.ndarray:
    """The joint speed limits on the dimensionless path, (n + 1,) (``vmax_1``: joints and the TCP
    clock) or, along a chain of moves, (G, n + 1): each move's own joint limits (x ``factor``), and
    the last coordinate (u itself) capped at ``clock_factor`` over the clock's rate du -> dclock, the
    largest rate on the grid intervals either side of each grid point (TOPP-RA holds a bound at its
    grid points only; where the rate varies between them, as in a corner of woven moves, the
    point's own rate would let the TCP run over its speed)."""
    if limits.velocity_at is None:
        return vmax_1
    rate = _clock_rates(limits, grid)
    clock_cap = clock_factor / np.maximum(rate, 1e-300)
    return np.minimum(np.hstack([limits.velocity_at(grid) * factor, clock_cap[:, None]]), _UNLIMITED)


def _clock_rates(limits: MoveLimits, grid: np.ndarray) -> np.ndarray:
    """The largest rate d clock / du (G,) on the intervals next to each grid point (G,); 0 without a TCP cap."""
    sub = np.linspace(0.0, 1.0, _CLOCK_SUBSTEPS + 1)
    width = np.diff(grid)
    points = grid[:-1, None] + width[:, None] * sub[None, :]  # (G - 1, S + 1)
    clock = limits.tcp_clock(points.ravel())
    if clock is None:
        return np.zeros(len(grid))
    slopes = np.max(np.diff(clock.reshape(points.shape), axis=1), axis=1) * _CLOCK_SUBSTEPS / width  # (G - 1,)
    return np.maximum(np.append(slopes, slopes[-1]), np.insert(slopes, 0, slopes[0]))


def _torque_constraint(limit: TorqueLimit, q0: np.ndarray, length: float, tau_s: float,
                       scale_t: float) -> ta_constraint.JointTorqueConstraint:
    """TOPP-RA's torque constraint on the dimensionless path: |tau| <= limit x scale_t, none on the arc length."""
    bound = np.append(limit.limit_nm * scale_t, _UNLIMITED)
    return ta_constraint.JointTorqueConstraint(PathDynamics(limit, q0, length, tau_s),
                                               np.stack([-bound, bound], axis=1), np.zeros(len(bound)))


def _check_holding_torque(limit: TorqueLimit, u: np.ndarray, q: np.ndarray, move_index: int) -> None:
    """Raise TimingError where merely holding the arm still (gravity) takes more than the torque limit."""
    zero = np.zeros(q.shape[1])
    for k in range(len(q)):
        ratio = np.abs(limit.rnea(q[k], zero, zero)) / limit.limit_nm
        j = int(np.argmax(ratio))
        if ratio[j] > 1.0:
            name = limit.robot.joint_names[j]
            raise TimingError(move_index, float(u[k]), f"holding the arm against gravity takes "
                                                       f"{ratio[j] * limit.limit_nm[j]:.1f} N m at {name}, over its "
                                                       f"limit of {limit.limit_nm[j]:.1f} N m (effort x torque_scale)")


def _steepest_at(u: np.ndarray, q: np.ndarray, vmax: np.ndarray) -> float:
    """The path parameter u of the reference step (K,) (K, n) whose joint slope |dq/du| / vmax is largest."""
    slope = np.max(np.abs(np.diff(q, axis=0)) / vmax, axis=1) / np.diff(u)
    return float(u[int(np.argmax(slope))])


def _grid(u: np.ndarray) -> np.ndarray:
    """Grid points: the reference samples, with long intervals split (at least 100 points)."""
    step = 1.0 / max(100, len(u))
    width = np.diff(u)
    pieces = np.where(width > step, np.ceil(width / step), 1.0).astype(int)  # equal pieces per interval
    if np.all(pieces == 1):
        return u
    interval = np.repeat(np.arange(len(width)), pieces - 1)
    k = np.arange(len(interval)) - np.repeat(np.cumsum(pieces - 1) - (pieces - 1), pieces - 1) + 1
    # k * (width / pieces) + start, as np.linspace computes its points (the grid is bit for bit the same)
    extra = k * (width / pieces)[interval] + u[:-1][interval]
    return np.unique(np.concatenate([u, extra]))
