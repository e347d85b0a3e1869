"""The jerk limit (or the quintic PTP law) on a move timed at its acceleration limits: the time laws
of :mod:`~singplan.planning.timing.laws` sampled, stretched uniformly until every limit holds on the
samples (jerk by third differences, seams included), and the one that ends soonest kept; the move
records the acceleration-limited duration so the time the jerk limit costs can be reported."""

from __future__ import annotations

import logging
import math
from collections.abc import Callable
from dataclasses import replace

import numpy as np

from singplan.kinematics.dynamics import move_torque_ratio
from singplan.planning.path.jointmap import JointMap
from singplan.planning.path.spline import not_a_knot
from singplan.planning.timing.laws import QuinticLaw, SCurveLaw, SmoothedLaw, quintic_duration
from singplan.planning.timing.profile import Profile
from singplan.planning.timing.ratios import (
    ACCEL_MARGIN,
    JERK_MARGIN,
    SPEED_MARGIN,
    TCP_MARGIN,
    TORQUE_MARGIN,
    end_step_ratio,
    jerk_ratio,
    sample_ratios,
)
from singplan.planning.timing.records import MoveLimits, TimedMove, TimingError, check_move_samples

logger = logging.getLogger(__name__)

_STRETCH_PASSES = 8
_MAX_STRETCH = 100.0  # a law that needs more is given up (exit 3), before it could exhaust the sample allowance
# Smoothing windows tried, in multiples of amax / jmax (the time a jerk-limited drive needs to
# build up full acceleration): short ones keep the move fast where the joint map is straight,
# long ones help where the joint map curves (near singular zones) and uniform stretching costs more.
_WINDOW_FACTORS = (0.5, 1.0, 2.0, 4.0, 8.0)
_S_CURVE_JERKS = (1.0, 0.5, 0.25)
TimeLaw = QuinticLaw | SmoothedLaw | SCurveLaw  # S-curve candidates: path jerk x these (curved joint maps need less)


def smoothed(jmap: JointMap, path_q: np.ndarray, optimal: TimedMove, profile: Profile, limits: MoveLimits,
             period_s: float, move_index: int, max_samples: int) -> TimedMove:
    """The move under its jerk limit or the quintic law: the soonest-ending law that keeps every limit
    on the samples, from the acceleration-limited samples ``optimal`` and their ``profile``
    (``path_q``: the joint map's reference samples, whose ends the quintic law runs between)."""
    laws: list[TimeLaw]
    if limits.quintic:
        laws = [QuinticLaw(quintic_duration(np.abs(path_q[-1] - path_q[0]), limits.velocity_rad_s,
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
                                          f"output samples after {_STRETCH_PASSES} stretches of the time law (a corner "
                                          "of the path, such as a triangle weave's, needs unbounded jerk: weave "
                                          "pattern sine, a blend, or no limits.jerk there)")
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


def _surrogate(optimal: TimedMove) -> Callable[[np.ndarray], np.ndarray]:
    """A cubic spline in u through the acceleration-limited samples: the joint map, cheaply."""
    keep = np.concatenate([[True], np.diff(optimal.u) > 0])
    if np.count_nonzero(keep) < 4:
        return lambda u: np.array([np.interp(u, optimal.u[keep], qj) for qj in optimal.q[keep].T]).T
    spline = not_a_knot(optimal.u[keep], optimal.q[keep])
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
    accel_like = max(accel / ACCEL_MARGIN, end_step_ratio(q, period_s, limits.acceleration_rad_s2))
    worst = max(speed / SPEED_MARGIN, limits.tcp_step_ratio(u, q, period_s) / TCP_MARGIN, math.sqrt(accel_like),
                (jerk / JERK_MARGIN) ** (1.0 / 3.0), math.sqrt(torque / TORQUE_MARGIN))
    duration = (len(u) - 1) * period_s
    return TimedMove(u, q, duration, speed, accel, torque, jerk), worst
