"""What timing is handed and hands back: the limits of one move (:class:`MoveLimits`, with the TCP's
own travel :class:`TcpTrace`), the scales a tightening pass puts on them (:class:`LimitScale`), the
timed samples (:class:`TimedMove`), a timing that stopped because it cannot win (:class:`Outrun`),
the failure (:class:`TimingError`), and the check of a move's samples against the task's allowance."""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass

import numpy as np

from singplan.errors import BudgetError, PlanningError
from singplan.kinematics.dynamics import TorqueLimit
from singplan.kinematics.robot import Robot
from singplan.task.schema import MAX_OUTPUT_SAMPLES, TASK_MEMORY_MB


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


@dataclass(frozen=True)
class LimitScale:
    """Factors a tightening pass puts on a move's limits (1: the limit itself); each pass only lowers them.

    Separate factors: on a chain of moves a TCP-speed slip on one move must not slow a PTP's joints.
    """

    velocity: float = 1.0  # the joint speed limits
    tcp_speed: float = 1.0  # the programmed TCP speed
    acceleration: float = 1.0  # the joint acceleration limits
    torque: float = 1.0  # the torque limits


UNSCALED = LimitScale()
# Given the scales a failed pass tightened the limits to and that pass's own duration [s] (TOPP-RA's,
# before rounding; the later passes, at tighter limits, take no less: on a fixed grid TOPP-RA's
# profile is the greatest feasible one at every grid point (Pham and Pham 2018, "A new approach to
# time-optimal path parameterization based on reachability analysis", IEEE T-RO), and
# tighter limits only shrink the feasible set): a bound [s] that shows the timing cannot win what
# it is compared with (auto's best so far), or None to go on
GiveUp = Callable[[LimitScale, float], float | None]


@dataclass(frozen=True)
class Outrun:
    """A timing that stopped after a pass: at its tightened limits no timing of the move ends before
    ``at_least_s`` [s], and that cannot beat what it is compared with (:data:`GiveUp`)."""

    at_least_s: float


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


def check_move_samples(move_index: int, count: int, remaining: int, duration_s: float, period_s: float) -> None:
    """Refuse a timed move whose exact sample count is over what is left of the task's allowance
    (:mod:`singplan.planning.orchestration.budget` estimated the task before planning)."""
    if count <= remaining:
        return
    raise BudgetError(f"moves[{move_index}]", f"move {move_index} lasts {duration_s:.1f} s: {count} samples at "
                      f"{period_s:g} s, but only {max(remaining, 0)} of the task's output samples are left (the "
                      f"cap is {MAX_OUTPUT_SAMPLES} for all moves together, less if the memory budget of "
                      f"{TASK_MEMORY_MB:.0f} MB is reached first); raise output.period or the speeds, or split the "
                      f"task", move_index, count, remaining)
