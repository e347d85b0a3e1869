"""Time-parameterisation of one move (or one chain of moves joined by fly-by corners,
:mod:`singplan.planning.chain`) with TOPP-RA, and resampling at the controller period.

TOPP-RA (Pham and Pham, "A new approach to time-optimal path parameterization based on
reachability analysis", IEEE T-RO 2018) finds the fastest path speed profile under joint
velocity and acceleration limits. The path handed to it is the move's joint map sampled at
its reference points, extended by one coordinate ``s = u * L`` (arc length [m]) whose
velocity limit is the programmed TCP speed: that caps the TCP speed and, where joints would
exceed their limits, slows the path instead of leaving it (SEEDS 002's speed scaleback). Along
a chain the joint speed limits are each move's own and the TCP cap follows a clock (time at the
programmed speeds) whose rate bounds the path speed directly: both vary along the path.

The output samples are uniform at the period from t = 0. The duration is rounded up to whole
periods by slowing the profile uniformly. Each sample's joints come from the joint map's own
``evaluate(u)`` (exact IK, or the crossing's definition), never from the spline, so every
sample is on the path. Limits are then checked on the samples with the same finite
differences a checker uses, and the profile is tightened where TOPP-RA's grid let them slip.
Both end steps are held within amax * period^2 / 2 (a start from rest, an arrival at rest), so
a seam between two moves stays within the acceleration limit whatever its neighbours do.

With a jerk limit (or the quintic PTP law) the acceleration-limited result is the reference:
jerk.py's time laws are sampled, stretched uniformly until every limit holds on the samples
(jerk by third differences, seams included), and the one that ends soonest is kept; the move
records the acceleration-limited duration so the time the jerk limit costs can be reported.
"""

from __future__ import annotations

import logging
import math
from collections.abc import Callable
from dataclasses import dataclass, replace
from functools import cached_property

import numpy as np
import toppra as ta
import toppra.constraint as ta_constraint
from scipy.interpolate import CubicSpline

from singplan.errors import PlanningError
from singplan.kinematics.dynamics import PathDynamics, TorqueLimit, move_torque_ratio
from singplan.kinematics.robot import Robot
from singplan.planning import reachability
from singplan.planning.budget import check_move_samples
from singplan.planning.jerk import QuinticLaw, SCurveLaw, SmoothedLaw, jerk_ratio, quintic_duration
from singplan.planning.jointmap import JointMap
from singplan.planning.profile import Profile

logger = logging.getLogger(__name__)
logging.getLogger("toppra").setLevel(logging.ERROR)  # its retries are not our warnings

_UNLIMITED = 1e9
_TIGHTEN_PASSES = 8
_SPEED_MARGIN = 0.999  # ratios the samples must stay under
_ACCEL_MARGIN = 0.995
TCP_MARGIN = 0.999  # an accepted sample step covers at most this many periods of the TCP clock (bound.py)
_TORQUE_MARGIN = 0.995
_JERK_MARGIN = 0.995
_STRETCH_PASSES = 8
_MAX_STRETCH = 100.0  # a law that needs more is given up (exit 3), before it could exhaust the sample allowance
# Smoothing windows tried, in multiples of amax / jmax (the time a jerk-limited drive needs to
# build up full acceleration): short ones keep the move fast where the joint map is straight,
# long ones help where the joint map curves (near singular zones) and uniform stretching costs more.
_WINDOW_FACTORS = (0.5, 1.0, 2.0, 4.0, 8.0)
_S_CURVE_JERKS = (1.0, 0.5, 0.25)
TimeLaw = QuinticLaw | SmoothedLaw | SCurveLaw  # S-curve candidates: path jerk x these (curved joint maps need less)
_CLOCK_SUBSTEPS = 8  # differences per grid interval that find a chain clock's largest rate
# an overshoot this large means a jump in the joint map, not TOPP-RA's grid: tightening cannot help.
# (A joint map that curves sharply between its reference samples, as exact's crossing right at a
# wrist hit does, overshoots 4-7x on the first pass and is timed within the limits by tightening;
# a jump of one degree between two 4 ms samples at 10 rad/s^2 is x109.)
_DISCONTINUOUS = 10.0


class TimingError(PlanningError):
    """A move cannot be timed within the limits; ``u`` is the path parameter where.

    The planner names the move's kind and turns ``u`` into a point on the path.
    """

    def __init__(self, move: int, u: float, reason: str, kind: str = "", where: str = "") -> None:
        self.move = move
        self.u = u
        self.reason = reason
        where = where or f"u = {u:.6f} along the move"
        super().__init__(f"move {move}{f' ({kind})' if kind else ''}: {reason} at {where}")


Scale = tuple[float, float, float, float]  # factors on the joint speed, TCP speed, acceleration and torque limits
# given the scales a failed pass tightened the limits to and that pass's own duration [s] (TOPP-RA's,
# before rounding; the later passes, at tighter limits, take no less: on a fixed grid TOPP-RA's
# profile is the greatest feasible one at every grid point (Pham and Pham 2018, "A new approach to
# time-optimal path parameterization based on reachability analysis", IEEE T-RO), and
# tighter limits only shrink the feasible set): a bound [s] that shows the timing cannot win what
# it is compared with (auto's best so far), or None to go on
GiveUp = Callable[[Scale, float], float | None]


class Outrun(Exception):  # noqa: N818 - not an error: the timing stopped because it cannot win
    """time_move stopped after a pass: at its tightened limits no timing of the move ends before
    ``at_least_s`` [s], and that cannot beat what it is compared with."""

    def __init__(self, at_least_s: float) -> None:
        super().__init__(f"no timing ends before {at_least_s:.3f} s")
        self.at_least_s = at_least_s


@dataclass(frozen=True)
class TimedMove:
    """A move sampled at the controller period.

    Attributes:
        u: path parameter of each sample, shape (K + 1,), from 0 to 1.
        q: joint values [rad], shape (K + 1, n); first and last samples at rest.
        duration_s: K * period.
        speed_ratio, accel_ratio: largest |qd| / limit and |qdd| / limit on the samples.
        torque_ratio: largest |tau| / limit on the samples (0 when the move has no torque limit).
        jerk_ratio: largest jerk / limit on the samples, seams with a resting neighbour included
            (0 without a jerk limit).
        optimal_duration_s: the acceleration-limited (TOPP-RA) duration; ``duration_s`` is longer by
            what the jerk limit or the quintic law costs. None: the same as ``duration_s``.
        blend_from: the sample where the move's fly-by corner starts (its last sample on the move's
            path); the samples after it are the corner's, their ``u`` the move's end. None: the move
            ends at rest on its target.
    """

    u: np.ndarray  # (K+1,)
    q: np.ndarray  # (K+1, n)
    duration_s: float
    speed_ratio: float
    accel_ratio: float
    torque_ratio: float = 0.0
    jerk_ratio: float = 0.0
    optimal_duration_s: float | None = None
    blend_from: int | None = None


@dataclass(frozen=True)
class TcpTrace:
    """How far the TCP itself travels along a joint map that leaves its path (a crossing that
    deviates in position: axis at the shoulder or elbow, the baselines), so that the programmed
    speed caps the TCP and not only the path parameter.

    ``s_m`` is the distance the timing's TCP coordinate covers from u = 0: over each step of the
    dense samples the longer of the path's own advance (u step x length) and the TCP's chord, so
    the path parameter never runs ahead of the programmed speed either, and where the joint map
    stays on the path the coordinate is the path's arc length as without a trace.
    """

    robot: Robot
    u: np.ndarray  # (K,) increasing, 0 .. 1
    s_m: np.ndarray  # (K,) the TCP coordinate [m] at u

    def at(self, u: np.ndarray) -> np.ndarray:
        """The TCP coordinate [m] at u (N,), interpolated between the dense samples."""
        return np.interp(u, self.u, self.s_m)

    def steps_m(self, q: np.ndarray) -> np.ndarray:
        """The TCP's chord [m] between consecutive joint samples q (K + 1, n): (K,)."""
        return np.linalg.norm(np.diff(self.robot.tcp_positions(q), axis=0), axis=1)


@dataclass(frozen=True)
class MoveLimits:
    """Limits one move is timed under."""

    velocity_rad_s: np.ndarray  # (n,) already scaled
    acceleration_rad_s2: np.ndarray  # (n,)
    length_m: float  # 0 for PTP or a pure reorientation: no TCP speed cap
    tcp_speed_m_s: float | None  # the programmed TCP speed (moves joined by fly-by corners: the fastest)
    torque: TorqueLimit | None = None  # limits.torque_scale: TOPP-RA's torque constraint, checked on the samples
    jerk_rad_s3: np.ndarray | None = None  # (n,) limits.jerk, checked on the samples; None: not limited
    quintic: bool = False  # time the move by SEEDS 003's quintic law (PTP: the joint map is a straight line)
    # moves joined by fly-by corners: the time [s] the TCP needs at the programmed speeds to reach
    # each path parameter (N,) -> (N,); None: u * length_m / tcp_speed_m_s
    clock: Callable[[np.ndarray], np.ndarray] | None = None
    # moves joined by fly-by corners: each move's own joint speed limits, (N,) u -> (N, n); None:
    # velocity_rad_s everywhere (which is then the largest of them)
    velocity_at: Callable[[np.ndarray], np.ndarray] | None = None
    # a LIN / CIRC whose joint map leaves the path: the TCP's own travel (None: u * length_m)
    trace: TcpTrace | None = None

    def step_velocities(self, u: np.ndarray) -> np.ndarray:
        """Joint speed limits [rad/s] of the steps between samples at u (K + 1,): (K, n), or (n,)
        where they do not vary."""
        return self.velocity_at(0.5 * (u[:-1] + u[1:])) if self.velocity_at is not None else self.velocity_rad_s

    def tcp_clock(self, u: np.ndarray) -> np.ndarray | None:
        """The time [s] the TCP needs at its programmed speed to reach each u (N,); None: no TCP speed cap."""
        if self.clock is not None:
            return self.clock(u)
        if not self.tcp_speed_m_s or self.length_m <= 0:
            return None
        if self.trace is not None:
            return self.trace.at(u) / self.tcp_speed_m_s
        return u * (self.length_m / self.tcp_speed_m_s)

    def tcp_step_ratio(self, u: np.ndarray, q: np.ndarray, period_s: float) -> float:
        """Largest TCP speed over its cap between samples (u (K + 1,), q (K + 1, n)): from the TCP's
        clock, and where the joint map leaves the path from the samples' own TCP chords too (what a
        checker measures; the clock interpolates between the trace's samples)."""
        clock = self.tcp_clock(u)
        if clock is None or len(u) < 2:
            return 0.0
        ratio = float(np.max(np.diff(clock)) / period_s)
        if self.trace is not None and self.clock is None and self.tcp_speed_m_s:
            ratio = max(ratio, float(np.max(self.trace.steps_m(q))) / (period_s * self.tcp_speed_m_s))
        return ratio


_TRACE_STEP_M = 2.5e-4  # the trace's samples inside a part that leaves the path: every 0.25 mm of path ...
_TRACE_STEP_RAD = math.radians(0.25)  # ... and 0.25 deg of any joint
_TRACE_MIN, _TRACE_MAX = 64, 20_000  # samples a part, at least and at most


def tcp_trace(jmap: JointMap, length_m: float) -> TcpTrace | None:
    """The TCP's own travel along a LIN / CIRC joint map (:class:`TcpTrace`), where it has parts
    that leave the path and its TCP runs ahead of the path somewhere; None where the path's arc
    length bounds the TCP's (every part keeps the position, or the parts off it run no faster)."""
    off = jmap.off_path_parts
    if not off or length_m <= 0.0:
        return None
    u_ref, _ = jmap.reference()
    dense = [u_ref]
    for part in off:
        travel = float(np.max(np.sum(np.abs(np.diff(part.q, axis=0)), axis=0), initial=0.0))
        count = max(_TRACE_MIN, math.ceil((part.u1 - part.u0) * length_m / _TRACE_STEP_M),
                    math.ceil(travel / _TRACE_STEP_RAD))
        dense.append(np.linspace(part.u0, part.u1, min(count, _TRACE_MAX) + 1))
    u = np.unique(np.concatenate(dense))
    path_m = np.diff(u) * length_m
    tcp_m = np.linalg.norm(np.diff(jmap.robot.tcp_positions(jmap.evaluate(u)), axis=0), axis=1)
    if np.all(tcp_m <= path_m * (1.0 + 1e-9) + 1e-12):
        return None  # the TCP never runs ahead of the path (an axis part that keeps to it): as without a trace
    return TcpTrace(jmap.robot, u, np.concatenate([[0.0], np.cumsum(np.maximum(path_m, tcp_m))]))


def _reference(jmap: JointMap, limits: MoveLimits) -> tuple[np.ndarray, np.ndarray]:
    if limits.trace is not None and limits.clock is None and not jmap.straight:
        # the TCP's travel where the map leaves the path: its dense samples in the reference too,
        # so that TOPP-RA's TCP coordinate follows it (not on a straight joint line: see below; its
        # samples' TCP speed is checked like any, and the limits tightened where it runs over)
        u, q = _reference(jmap, replace(limits, trace=None))
        extra = np.setdiff1d(limits.trace.u, u)
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
    keep = np.concatenate([[True], np.diff(u) > 1e-12])
    u, q = u[keep], q[keep]
    if len(u) < 4:  # a spline needs a few points; add interior ones (straight PTP lines)
        dense = np.linspace(0.0, 1.0, 9)
        return dense, jmap.evaluate(dense)
    return u, q


def path_scale(q: np.ndarray, limits: MoveLimits) -> float:
    """The move's size: the largest travel of any joint [rad] or of the TCP [m] along it."""
    travel = float(np.max(np.sum(np.abs(np.diff(q, axis=0)), axis=0), initial=0.0))
    return max(travel, limits.length_m)


@dataclass(frozen=True)
class TimingPath:
    """A move's joint map as TOPP-RA is handed it, built once for its duration bound
    (:mod:`~singplan.planning.bound`) and every tightening pass.

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

    def scaled_limits(self, limits: MoveLimits, scale: Scale
                      ) -> tuple[float, np.ndarray, np.ndarray]:
        """tau [s], and the velocity (n + 1,) and acceleration (n + 1,) limits in dimensionless units,
        the joints' and TCP speed's times ``scale`` (velocity, TCP speed, acceleration, torque)."""
        scale_v, scale_c, scale_a, _ = scale
        amax = limits.acceleration_rad_s2 * scale_a
        tau = math.sqrt(self.length / float(np.min(amax)))
        tcp = self.tcp_speed_m_s * scale_c if self.tcp_speed_m_s is not None else _UNLIMITED
        vmax = np.append(limits.velocity_rad_s * scale_v, tcp)
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
    spline = ta.SplineInterpolator(u, np.hstack([q - q[0], extra[:, None]]) / length)  # from 0: no digits lost
    return TimingPath(u, q, length, spline, _grid(u), tcp_speed_m_s)


def _toppra_profile(path: TimingPath, limits: MoveLimits, scale: Scale,
                    move_index: int) -> Profile:
    """TOPP-RA on the move made dimensionless (:class:`TimingPath`); ``scale`` multiplies the joint
    velocity, TCP speed, acceleration and torque limits (the tightening passes). toppra's algorithm
    and constraints, compiled (:mod:`~singplan.planning.reachability`)."""
    scale_v, scale_c, _, scale_t = scale
    assert path.spline is not None
    tau, vmax_1, amax_1 = path.scaled_limits(limits, scale)
    d1, d2 = path.derivatives
    rows = [reachability.acceleration_rows(path.grid, d1, d2, amax_1)]
    if limits.torque is not None:
        torque = _torque_constraint(limits.torque, path.q[0], path.length, tau, scale_t)
        rows.append(reachability.toppra_rows(torque, path.spline, path.grid))
    speeds = _velocity_bounds(limits, vmax_1, scale_v * tau / path.length, scale_c * tau, path.grid)
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


def _sample(profile: Profile, period_s: float, move_index: int, max_samples: int) -> tuple[np.ndarray, float]:
    duration = float(profile.t_nodes[-1])
    count = max(1, math.ceil(duration / period_s - 1e-9))
    check_move_samples(move_index, count, max_samples, duration, period_s)  # before the samples are allocated
    stretch = count * period_s / duration if duration > 0 else 1.0
    t = np.arange(count + 1) * period_s / stretch
    u = np.maximum.accumulate(np.clip(profile.u_at(t), 0.0, 1.0))
    u[0], u[-1] = 0.0, 1.0
    return u, count * period_s


def difference_ratios(q: np.ndarray, period_s: float, vmax: np.ndarray, amax: np.ndarray
                      ) -> tuple[np.ndarray, np.ndarray]:
    """Of samples q (K+1, n), K >= 1: each step's largest |qd| / vmax (K,) and each inner sample's
    largest |qdd| / amax (K-1,), by forward differences (the checker's definition); ``vmax`` (n,)
    or one row a step (K, n)."""
    qd = np.diff(q, axis=0) / period_s
    return np.max(np.abs(qd) / vmax, axis=1), np.max(np.abs(np.diff(qd, axis=0)) / period_s / amax, axis=1)


def sample_ratios(q: np.ndarray, period_s: float, vmax: np.ndarray, amax: np.ndarray) -> tuple[float, float]:
    """Largest |qd|/vmax and |qdd|/amax by finite differences of samples q (K+1, n)."""
    if len(q) < 2:
        return 0.0, 0.0
    speed, accel = difference_ratios(q, period_s, vmax, amax)
    return float(np.max(speed)), float(np.max(accel, initial=0.0))


def end_step_ratio(q: np.ndarray, period_s: float, amax: np.ndarray) -> float:
    """Largest first or last step of samples q (K+1, n) over amax * period^2 / 2.

    A move starts and ends at rest; from rest, an acceleration within amax covers at most
    amax * period^2 / 2 in one period. Keeping both end steps under that bound keeps the second
    difference across any seam (the end of one move, the start of the next, both at rest on the
    shared sample) within amax whatever the neighbouring move does, and each end "at rest" as
    the checker defines it (a step no longer than amax * period^2).
    """
    if len(q) < 2:
        return 0.0
    steps = np.maximum(np.abs(q[1] - q[0]), np.abs(q[-1] - q[-2]))
    return float(np.max(2.0 * steps / (amax * period_s**2)))


def time_move(jmap: JointMap, limits: MoveLimits, period_s: float, move_index: int,
              max_samples: int, path: TimingPath | None = None, give_up: GiveUp | None = None) -> TimedMove:
    """Fastest uniform sampling of the move within the limits, every sample on the path.

    ``max_samples``: what is left of the task's allowance of output samples (bad input if over).
    ``path``: the joint map's :func:`timing_path`, where the caller already made it.
    ``give_up``: asked after each pass that tightens the limits; where it gives a bound, the
    timing stops there (:class:`Outrun`).
    """
    path = path if path is not None else timing_path(jmap, limits, move_index)
    if path.spline is None:
        logger.info("move %d changes nothing: one period at rest", move_index)
        return TimedMove(np.array([0.0, 1.0]), path.q[[0, -1]], period_s, 0.0, 0.0)
    optimal, profile = _optimal(jmap, path, limits, period_s, move_index, max_samples, give_up)
    if limits.jerk_rad_s3 is None and not limits.quintic:
        return optimal
    laws: list[TimeLaw]
    if limits.quintic:
        laws = [QuinticLaw(quintic_duration(np.abs(path.q[-1] - path.q[0]), limits.velocity_rad_s,
                                            limits.acceleration_rad_s2, limits.jerk_rad_s3))]
    else:
        assert limits.jerk_rad_s3 is not None
        rise_s = float(np.min(limits.acceleration_rad_s2) / np.min(limits.jerk_rad_s3))
        laws = [SmoothedLaw(profile.t_nodes, profile.grid, profile.sd, rise_s * f) for f in _WINDOW_FACTORS]
        laws += _s_curves(profile, limits)
    # The search runs on a spline through the acceleration-limited samples (the joint map's own
    # evaluation costs an IK solve per sample); the chosen laws are then sampled on the joint map itself.
    surrogate = _surrogate(optimal)
    trial = [(law, _stretched(surrogate, limits, law, 1.0, period_s, move_index, max_samples)) for law in laws]
    best = None
    for law, tm in sorted(trial, key=lambda lt: lt[1].duration_s if lt[1] is not None else math.inf):
        start = tm.duration_s / law.duration_s if tm is not None else 1.0
        best = _stretched(jmap.evaluate, limits, law, start, period_s, move_index, max_samples)
        if best is not None:
            break
    if best is None:  # named where the acceleration-limited samples jerk most
        steps = np.abs(np.diff(optimal.q, n=3, axis=0)) / (limits.jerk_rad_s3 if limits.jerk_rad_s3 is not None
                                                            else limits.acceleration_rad_s2)
        at = float(optimal.u[int(np.argmax(np.max(steps, axis=1))) + 1]) if len(steps) else 0.5
        raise TimingError(move_index, at, "could not keep the joint speed, acceleration and jerk limits on the "
                                          f"output samples after {_STRETCH_PASSES} stretches of the time law")
    logger.info("move %d: %.3f s jerk-limited, %.3f s acceleration-limited", move_index, best.duration_s,
                optimal.duration_s)
    return replace(best, optimal_duration_s=optimal.duration_s)


def _s_curves(profile: Profile, limits: MoveLimits) -> list[SCurveLaw]:
    """S-curves in u with TOPP-RA's peak path speed and acceleration, and the path jerk the joint
    limits allow where the joint map is straight (the exact optimum of a PTP) or less."""
    assert limits.jerk_rad_s3 is not None
    speed = float(np.max(profile.sd))
    accel = float(np.max(np.abs(np.diff(profile.sd)) / np.diff(profile.t_nodes), initial=0.0))
    if not (speed > 0.0 and accel > 0.0 and math.isfinite(accel)):
        return []
    jerk = accel * float(np.min(limits.jerk_rad_s3 / limits.acceleration_rad_s2))
    return [SCurveLaw(speed, accel, jerk * f) for f in _S_CURVE_JERKS]


def _optimal(jmap: JointMap, path: TimingPath, limits: MoveLimits, period_s: float, move_index: int,
             max_samples: int, give_up: GiveUp | None) -> tuple[TimedMove, Profile]:
    """The acceleration-limited samples (TOPP-RA, tightened until the samples keep the limits) and their profile."""
    # separate scales: on a chain of moves a TCP-speed slip on one move must not slow a PTP's joints
    scale_v = scale_c = scale_a = scale_t = 1.0
    for passes_left in range(_TIGHTEN_PASSES - 1, -1, -1):
        profile = _toppra_profile(path, limits, (scale_v, scale_c, scale_a, scale_t), move_index)
        u, duration = _sample(profile, period_s, move_index, max_samples)
        q = jmap.evaluate(u)
        speed, accel = sample_ratios(q, period_s, limits.step_velocities(u), limits.acceleration_rad_s2)
        torque, torque_at = move_torque_ratio(limits.torque, q, period_s) if limits.torque else (0.0, 0)
        worst_c = limits.tcp_step_ratio(u, q, period_s) / TCP_MARGIN
        worst_v = speed / _SPEED_MARGIN
        worst_a = max(accel / _ACCEL_MARGIN,
                      end_step_ratio(q, period_s, limits.acceleration_rad_s2))  # may reach its bound exactly
        worst_t = torque / _TORQUE_MARGIN
        if worst_v <= 1.0 and worst_c <= 1.0 and worst_a <= 1.0 and worst_t <= 1.0:
            return TimedMove(u, q, duration, speed, accel, torque), profile
        if max(worst_v, worst_c) > _DISCONTINUOUS or worst_a > _DISCONTINUOUS:
            break  # not a grid effect: the joint map jumps somewhere; tightening cannot help
        logger.debug("move %d: samples at x%.4f speed, x%.4f TCP speed, x%.4f accel, x%.4f torque; tightening",
                     move_index, speed, worst_c * _SPEED_MARGIN, accel, torque)
        scale_v *= 0.998 / worst_v if worst_v > 1.0 else 1.0
        scale_c *= 0.998 / worst_c if worst_c > 1.0 else 1.0
        scale_a *= 0.995 / worst_a if worst_a > 1.0 else 1.0
        if worst_t > 1.0:
            scale_t *= 0.995 / worst_t
        # later passes only tighten further (after the last one the timing fails: not an outrun)
        scale = (scale_v, scale_c, scale_a, scale_t)
        at_least_s = give_up(scale, float(profile.t_nodes[-1])) if give_up and passes_left else None
        if at_least_s is not None:
            raise Outrun(at_least_s)
    ends = end_step_ratio(q, period_s, limits.acceleration_rad_s2)
    worst_k = (torque_at if worst_t > max(worst_v, worst_c, worst_a)
               else worst_sample(q, period_s, limits.velocity_rad_s, limits.acceleration_rad_s2))
    raise TimingError(move_index, float(u[worst_k]),
                      f"could not keep the joint limits on the output samples (speed x{speed:.3f}, "
                      f"acceleration x{accel:.3f}, end steps x{ends:.3f}"
                      f"{f', torque x{torque:.3f}' if limits.torque else ''} after tightening)")


def worst_sample(q: np.ndarray, period_s: float, vmax: np.ndarray, amax: np.ndarray) -> int:
    """The sample of q (K, n), at rest before and after, whose speed or acceleration is furthest over its limit
    (end steps included)."""
    # speed: step k -> k+1 of the padded samples; accel: at q[k]
    speed, accel = difference_ratios(np.concatenate([q[:1], q, q[-1:]]), period_s, vmax, amax)
    accel[[0, -1]] *= 2.0  # an end step's bound is amax * period^2 / 2 (end_step_ratio)
    over = np.maximum(accel, np.maximum(speed[:-1], speed[1:]))
    return int(np.argmax(over))


def _surrogate(optimal: TimedMove) -> Callable[[np.ndarray], np.ndarray]:
    """A cubic spline in u through the acceleration-limited samples: the joint map, cheaply."""
    keep = np.concatenate([[True], np.diff(optimal.u) > 0])
    if np.count_nonzero(keep) < 4:
        return lambda u: np.array([np.interp(u, optimal.u[keep], qj) for qj in optimal.q[keep].T]).T
    spline = CubicSpline(optimal.u[keep], optimal.q[keep], axis=0)
    return lambda u: np.asarray(spline(u))


def _stretched(evaluate: Callable[[np.ndarray], np.ndarray], limits: MoveLimits, law: TimeLaw, stretch: float,
               period_s: float, move_index: int, max_samples: int) -> TimedMove | None:
    """The law stretched uniformly in time by the least factor whose samples keep every limit (None: not found).

    Stretching by k divides joint speeds by k, accelerations by k^2 and jerks by k^3; the first
    pass measures the law stretched by ``stretch``, the next ones aim at the factor the worst ratio asks for.
    """
    kept = None
    for attempt in range(_STRETCH_PASSES):
        count = max(3, math.ceil(stretch * law.duration_s / period_s - 1e-9))
        check_move_samples(move_index, count, max_samples, stretch * law.duration_s, period_s)
        u = np.maximum.accumulate(np.clip(law.u_at(np.arange(count + 1) * (law.duration_s / count)), 0.0, 1.0))
        u[0], u[-1] = 0.0, 1.0
        tm, worst = _measured(u, evaluate(u), limits, period_s)
        if worst <= 1.0:
            kept = tm if kept is None or tm.duration_s < kept.duration_s else kept
            if attempt > 0:
                return kept
        elif kept is not None:
            return kept
        stretch = count * period_s / law.duration_s * worst * (1.0005 if worst > 1.0 else 1.0)
        if not stretch <= _MAX_STRETCH:  # NaN too: not a law's jerk but a joint map that jumps
            return kept
    return kept


def _measured(u: np.ndarray, q: np.ndarray, limits: MoveLimits, period_s: float) -> tuple[TimedMove, float]:
    """The samples as a TimedMove, and the time stretch they need (<= 1: every limit kept)."""
    speed, accel = sample_ratios(q, period_s, limits.step_velocities(u), limits.acceleration_rad_s2)
    torque = move_torque_ratio(limits.torque, q, period_s)[0] if limits.torque else 0.0
    jerk = jerk_ratio(q, period_s, limits.jerk_rad_s3) if limits.jerk_rad_s3 is not None else 0.0
    accel_like = max(accel / _ACCEL_MARGIN, end_step_ratio(q, period_s, limits.acceleration_rad_s2))
    worst = max(speed / _SPEED_MARGIN, limits.tcp_step_ratio(u, q, period_s) / TCP_MARGIN, math.sqrt(accel_like),
                (jerk / _JERK_MARGIN) ** (1.0 / 3.0), math.sqrt(torque / _TORQUE_MARGIN))
    duration = (len(u) - 1) * period_s
    return TimedMove(u, q, duration, speed, accel, torque, jerk), worst
