"""Time-parameterisation of one move (or one chain of moves joined by fly-by corners,
:mod:`singplan.planning.orchestration.chain`), resampled at the controller period.

The fastest path speed profile comes from TOPP-RA (:mod:`~singplan.planning.timing.toppra`). The
output samples are uniform at the period from t = 0. The duration is rounded up to whole
periods by slowing the profile uniformly. Each sample's joints come from the joint map's own
``evaluate(u)`` (exact IK, or the crossing's definition), never from the spline, so every
sample is on the path. Limits are then checked on the samples with the same finite
differences a checker uses (:mod:`~singplan.planning.timing.ratios`), and the profile is tightened
where TOPP-RA's grid let them slip. Both end steps are held within amax * period^2 / 2 (a start
from rest, an arrival at rest), so a seam between two moves stays within the acceleration limit
whatever its neighbours do.

With a jerk limit (or the quintic PTP law) the acceleration-limited result is the reference of
:mod:`~singplan.planning.timing.smoothing`.
"""

from __future__ import annotations

import logging
import math
from typing import overload

import numpy as np

from singplan.kinematics.dynamics import move_torque_ratio
from singplan.planning.path.jointmap import JointMap
from singplan.planning.timing.profile import Profile
from singplan.planning.timing.ratios import (
    ACCEL_MARGIN,
    SPEED_MARGIN,
    TCP_MARGIN,
    TORQUE_MARGIN,
    end_step_ratio,
    sample_ratios,
    worst_sample,
)
from singplan.planning.timing.records import (
    UNSCALED,
    GiveUp,
    LimitScale,
    MoveLimits,
    Outrun,
    TimedMove,
    TimingError,
    check_move_samples,
)
from singplan.planning.timing.smoothing import smoothed
from singplan.planning.timing.toppra import TimingPath, timing_path, toppra_profile

logger = logging.getLogger(__name__)

_TIGHTEN_PASSES = 8
_CLOCK_SUBSTEPS = 8  # differences per grid interval that find a chain clock's largest rate
# an overshoot this large means a jump in the joint map, not TOPP-RA's grid: tightening cannot help.
# (A joint map that curves sharply between its reference samples, as exact's crossing right at a
# wrist hit does, overshoots 4-7x on the first pass and is timed within the limits by tightening;
# a jump of one degree between two 4 ms samples at 10 rad/s^2 is x109.)
_DISCONTINUOUS = 10.0


@overload
def time_move(jmap: JointMap, limits: MoveLimits, period_s: float, move_index: int, max_samples: int,
              path: TimingPath | None = None, give_up: None = None) -> TimedMove: ...


@overload
def time_move(jmap: JointMap, limits: MoveLimits, period_s: float, move_index: int, max_samples: int,
              path: TimingPath | None, give_up: GiveUp) -> TimedMove | Outrun: ...


def time_move(jmap: JointMap, limits: MoveLimits, period_s: float, move_index: int,
              max_samples: int, path: TimingPath | None = None, give_up: GiveUp | None = None) -> TimedMove | Outrun:
    """Fastest uniform sampling of the move within the limits, every sample on the path.

    ``max_samples``: what is left of the task's allowance of output samples (bad input if over).
    ``path``: the joint map's :func:`~singplan.planning.timing.toppra.timing_path`, where the caller
    already made it. ``give_up``: asked after each pass that tightens the limits; where it gives a
    bound, the timing stops there and returns :class:`~singplan.planning.timing.records.Outrun`
    (only ever with a ``give_up``).
    """
    path = path if path is not None else timing_path(jmap, limits, move_index)
    if path.spline is None:
        logger.info("move %d changes nothing: one period at rest", move_index)
        return TimedMove(np.array([0.0, 1.0]), path.q[[0, -1]], period_s, 0.0, 0.0)
    found = _optimal(jmap, path, limits, period_s, move_index, max_samples, give_up)
    if isinstance(found, Outrun) or (limits.jerk_rad_s3 is None and not limits.quintic):
        return found if isinstance(found, Outrun) else found[0]
    optimal, profile = found
    return smoothed(jmap, path.q, optimal, profile, limits, period_s, move_index, max_samples)


def _optimal(jmap: JointMap, path: TimingPath, limits: MoveLimits, period_s: float, move_index: int,
             max_samples: int, give_up: GiveUp | None) -> tuple[TimedMove, Profile] | Outrun:
    """The acceleration-limited samples (TOPP-RA, tightened until the samples keep the limits) and their
    profile, or where ``give_up`` shows after a pass that the timing cannot win, :class:`Outrun`."""
    scale = UNSCALED
    for passes_left in range(_TIGHTEN_PASSES - 1, -1, -1):
        profile = toppra_profile(path, limits, scale, move_index)
        u, duration = _sample(profile, period_s, move_index, max_samples)
        q = jmap.evaluate(u)
        speed, accel = sample_ratios(q, period_s, limits.step_velocities(u), limits.acceleration_rad_s2)
        torque, torque_at = move_torque_ratio(limits.torque, q, period_s) if limits.torque else (0.0, 0)
        worst_c = limits.tcp_step_ratio(u, q, period_s) / TCP_MARGIN
        worst_v = speed / SPEED_MARGIN
        worst_a = max(accel / ACCEL_MARGIN,
                      end_step_ratio(q, period_s, limits.acceleration_rad_s2))  # may reach its bound exactly
        worst_t = torque / TORQUE_MARGIN
        if worst_v <= 1.0 and worst_c <= 1.0 and worst_a <= 1.0 and worst_t <= 1.0:
            return TimedMove(u, q, duration, speed, accel, torque), profile
        if max(worst_v, worst_c) > _DISCONTINUOUS or worst_a > _DISCONTINUOUS:
            break  # not a grid effect: the joint map jumps somewhere; tightening cannot help
        logger.debug("move %d: samples at x%.4f speed, x%.4f TCP speed, x%.4f accel, x%.4f torque; tightening",
                     move_index, speed, worst_c * SPEED_MARGIN, accel, torque)
        scale = _tightened(scale, worst_v, worst_c, worst_a, worst_t)
        # later passes only tighten further (after the last one the timing fails: not an outrun)
        at_least_s = give_up(scale, float(profile.t_nodes[-1])) if give_up and passes_left else None
        if at_least_s is not None:
            return Outrun(at_least_s)
    ends = end_step_ratio(q, period_s, limits.acceleration_rad_s2)
    worst_k = (torque_at if worst_t > max(worst_v, worst_c, worst_a)
               else worst_sample(q, period_s, limits.velocity_rad_s, limits.acceleration_rad_s2))
    raise TimingError(move_index, float(u[worst_k]),
                      f"could not keep the joint limits on the output samples (speed x{speed:.3f}, "
                      f"acceleration x{accel:.3f}, end steps x{ends:.3f}"
                      f"{f', torque x{torque:.3f}' if limits.torque else ''} after tightening)")


def _tightened(scale: LimitScale, worst_v: float, worst_c: float, worst_a: float, worst_t: float) -> LimitScale:
    """The scales of the next pass: each limit a sample broke (its ratio over 1, margin included) lowered
    by that ratio and a little more."""
    return LimitScale(scale.velocity * (0.998 / worst_v if worst_v > 1.0 else 1.0),
                      scale.tcp_speed * (0.998 / worst_c if worst_c > 1.0 else 1.0),
                      scale.acceleration * (0.995 / worst_a if worst_a > 1.0 else 1.0),
                      scale.torque * (0.995 / worst_t) if worst_t > 1.0 else scale.torque)


def _sample(profile: Profile, period_s: float, move_index: int, max_samples: int) -> tuple[np.ndarray, float]:
    duration = float(profile.t_nodes[-1])
    count = max(1, math.ceil(duration / period_s - 1e-9))
    check_move_samples(move_index, count, max_samples, duration, period_s)  # before the samples are allocated
    stretch = count * period_s / duration if duration > 0 else 1.0
    t = np.arange(count + 1) * period_s / stretch
    u = np.maximum.accumulate(np.clip(profile.u_at(t), 0.0, 1.0))
    u[0], u[-1] = 0.0, 1.0
    return u, count * period_s
