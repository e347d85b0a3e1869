"""The plan's samples a controller program moves through, chosen so that moving between them in
straight joint-space lines keeps the TCP within a tolerance of the plan.

A controller program holds far fewer points than the plan has samples (one per controller period).
Between two consecutive program points ``q_i`` and ``q_j`` the controller interpolates the joints
(KRL PTP spline segments, RAPID ``MoveAbsJ``, FANUC ``J`` moves); the model here is the straight
line ``q_i + sigma (q_j - q_i)``. The plan's samples ``k`` in between are matched to the line by
their joint-space arc length, ``sigma_k = s_k / s_j`` (``s`` the length of the plan's joint path
from ``q_i``), which follows the plan at rest (sigma stands still where the plan stands still) and
through a null-space pause (where only the joints move). A segment is accepted when, for every
sample between its ends,

    |p(q_i + sigma_k (q_j - q_i)) - p(q_k)| <= T         (TCP position, T [m])
    angle(R(q_i + sigma_k (q_j - q_i)), R(q_k)) <= Theta (TCP orientation, Theta [rad])

so the straight joint segment's TCP stays within ``T`` of every planned TCP sample matched to it.
That is the chord error of the joint path seen through the forward kinematics: for a joint path of
curvature kappa (joint space) and a lever L [m] it grows as L kappa h^2 / 8 with the segment length
h, so halving T takes about 1.4 times the points.

Points are chosen greedily: from each point the farthest sample the criterion accepts becomes the
next point (found by doubling the step, then bisecting between the last accepted and the first
refused length). The criterion is not strictly monotone in the length (a longer chord can fit where
a shorter one does not), so bisection may stop short of the farthest acceptable sample, never
beyond an accepted one: every segment returned is one the criterion accepted. Greedy farthest
reach gives the fewest points when acceptance is monotone (any shorter segment inside an accepted
one is accepted), the usual case, as a chord's sag grows with its length, but not a guarantee.
A second, backward pass evens out a stretch whose last segment came out short (:func:`_stretch`).

Points are forced at every segment boundary of the trajectory and wherever the plan stops (see
:func:`stop_samples`); no segment is longer than a format's longest segment (e.g. FANUC's 32 s).
On woven moves the position tolerance shrinks by the weave's slope (:func:`weave_scale`).
"""

from __future__ import annotations

import itertools
import math
from dataclasses import dataclass, field

import numpy as np

from singplan.kinematics.geometry import rotation_angles
from singplan.kinematics.robot import Robot
from singplan.outputs.timeline import pause_window, sample_range
from singplan.results.path import programmed_path, woven_moves
from singplan.results.trajectory import Trajectory


@dataclass(frozen=True)
class PointTolerance:
    """How far the straight joint segments between program points may take the TCP from the plan.

    Attributes:
        position_m: TCP position [m].
        orientation_rad: TCP orientation [rad].
        max_segment_s: the longest time between two points a format can express [s] (inf: no limit).
    """

    position_m: float
    orientation_rad: float
    max_segment_s: float = math.inf


def weave_scale(traj: Trajectory, robot: Robot) -> np.ndarray:
    """Per sample (K,), the share of the position tolerance a chord may use: 1, and on a woven move
    ``1 / sqrt(1 + s^2)``, s the weave's steepest slope against its base path.

    A weave's error is measured across its base path at the same base position (DESIGN: the offset
    at arc length s along the base path; the checker measures it so, and so does a welder). A chord
    within d of the woven curve can be up to d sqrt(1 + s^2) from it measured that way, where the
    curve climbs at slope s = a (2 pi P / L) max|f'| (amplitude a, P periods over the base length L,
    f' = cos for a sine, 2 / pi for the triangle).
    """
    scale = np.ones(len(traj.t))
    if not woven_moves(traj.task):
        return scale  # no move weaves: no programmed path to build
    by_move = traj.segments_by_move()
    for i, programmed in enumerate(programmed_path(traj.task, robot, traj.q[0])):
        segs = by_move.get(i)
        if not segs or programmed.move.weave is None:
            continue
        k0, k1 = sample_range(traj, segs[0])[0], sample_range(traj, segs[-1])[1]
        scale[k0:k1 + 1] = 1.0 / math.sqrt(1.0 + programmed.weave_slope**2)
    return scale


@dataclass(frozen=True)
class ProgramPoints:
    """The samples a program moves through.

    Attributes:
        index: sample indices (P,) into the trajectory, increasing, first 0 and last K - 1.
        stop: (P,) True where the robot stops (an exact stop: the plan is at rest there).
        max_position_error_m: the largest TCP position deviation [m] of the straight joint segments
            from the plan's samples (the criterion's left side, over every segment).
        max_orientation_error_rad: the same for orientation [rad].
        pauses: the null-space pauses, each (first, last) sample at which the TCP stands still.
        ended_by: (P - 1,) what ended each segment's reach: :data:`FORCED` (the next forced point,
            or the format's longest segment), or the tolerance a longer segment broke,
            :data:`POSITION`, :data:`ORIENTATION` or both (their sum).
    """

    index: np.ndarray
    stop: np.ndarray
    max_position_error_m: float
    max_orientation_error_rad: float
    pauses: tuple[tuple[int, int], ...] = ()
    ended_by: np.ndarray = field(default_factory=lambda: np.zeros(0, dtype=int))


FORCED, POSITION, ORIENTATION = 0, 1, 2  # what ended a segment: ProgramPoints.ended_by


@dataclass(frozen=True)
class _Plan:
    """What the search reads: the robot, the joint samples, the plan's TCP frames, the joint arc length."""

    robot: Robot
    position_tol_m: np.ndarray  # (K,) [m]: the position tolerance at each sample
    q: np.ndarray  # (K, n) [rad]
    t: np.ndarray  # (K,) [s]
    p: np.ndarray  # (K, 3) [m]
    R: np.ndarray  # (K, 3, 3)
    arc: np.ndarray  # (K,) joint-space arc length from the first sample [rad]


def null_space_pauses(traj: Trajectory, tcp_step_m: np.ndarray) -> tuple[tuple[int, int], ...]:
    """The (first, last) sample of each null-space pause: in a crossing that paused (``pause_s``), the
    longest run of samples at which the TCP stands still (:func:`~singplan.outputs.timeline.pause_window`)."""
    windows = (pause_window(tcp_step_m, *sample_range(traj, seg)) for seg in traj.segments if seg.pause_s is not None)
    return tuple(w for w in windows if w is not None)


def stop_samples(traj: Trajectory, pauses: tuple[tuple[int, int], ...]) -> np.ndarray:
    """Samples where the plan is at rest: the first and the last, the end of every move that is not
    blended into the next (DESIGN: such a move ends at rest on a sample), and both ends of every
    null-space pause (the TCP stands still while the aligned joints turn; the joint path turns a
    corner there and the timing comes to rest at it). Sorted, unique."""
    stops = {0, len(traj.t) - 1, *(k for window in pauses for k in window)}
    for segments in traj.segments_by_move().values():
        if segments[-1].kind != "blend":
            stops.add(sample_range(traj, segments[-1])[1])
    return np.array(sorted(stops), dtype=int)


def boundary_samples(traj: Trajectory) -> np.ndarray:
    """The first and last sample of every segment, sorted and unique."""
    return np.unique([k for seg in traj.segments for k in sample_range(traj, seg)] + [0, len(traj.t) - 1])


def choose_points(traj: Trajectory, robot: Robot, tolerance: PointTolerance) -> ProgramPoints:
    """The program points of a trajectory (see the module's docstring for the criterion and the search)."""
    p, R = robot.tcp_frames(traj.q)
    step = np.linalg.norm(np.diff(traj.q, axis=0), axis=1)
    plan = _Plan(robot, tolerance.position_m * weave_scale(traj, robot), np.asarray(traj.q), np.asarray(traj.t),
                 p, R, np.concatenate([[0.0], np.cumsum(step)]))
    pauses = null_space_pauses(traj, np.linalg.norm(np.diff(p, axis=0), axis=1))
    stops = stop_samples(traj, pauses)
    forced = np.union1d(boundary_samples(traj), stops)
    chosen = [0]
    errors: list[tuple[float, float, float]] = []
    ended: list[int] = []
    for a, b in zip(forced[:-1].tolist(), forced[1:].tolist(), strict=True):
        stretch, stretch_errors, stretch_ended = _stretch(plan, a, b, tolerance)
        chosen += stretch[1:]
        errors += stretch_errors
        ended += stretch_ended
    index = np.array(chosen, dtype=int)
    worst = np.max(np.array(errors), axis=0) if errors else np.zeros(3)
    return ProgramPoints(index, np.isin(index, stops), float(worst[0]), float(worst[1]), pauses,
                         np.array(ended, dtype=int))


def _stretch(plan: _Plan, a: int, b: int, tol: PointTolerance
             ) -> tuple[list[int], list[tuple[float, float, float]], list[int]]:
    """The points from forced point a to forced point b, each segment's deviations, and what ended
    each forward reach (``ProgramPoints.ended_by``; kept for the evened-out set, whose points lie
    between the forward and backward reaches).

    Greedy reach forward gives the fewest points, each as late as it can be (f_k); greedy reach
    backward from b gives, for the same count, each as early as it can be (g_k). Forward alone leaves
    whatever remains before b to the last segment, often a sample or two, which no controller can
    time; when that segment is shorter than half the stretch's mean, each point is placed half-way
    between g_k and f_k, and that set is kept when the criterion accepts all its segments (it does
    where acceptance is monotone), else the forward one.
    """
    forward, errors, ended = [a], [], []
    while forward[-1] < b:
        j, err, why = _reach(plan, forward[-1], b, tol, +1)
        forward.append(j)
        errors.append(err)
        ended.append(why)
    if (b - forward[-2]) * (len(forward) - 1) >= (b - a) / 2:  # the last segment is not short: keep them
        return forward, errors, ended
    backward = [b]
    while backward[-1] > a and len(backward) <= len(forward):
        backward.append(_reach(plan, backward[-1], a, tol, -1)[0])
    if len(forward) < 3 or len(backward) != len(forward) or backward[-1] != a:
        return forward, errors, ended
    middle = [a] + [(f + g + 1) // 2 for f, g in zip(forward[1:-1], backward[::-1][1:-1], strict=True)] + [b]
    middle_errors = [_deviation(plan, i, j) for i, j in itertools.pairwise(middle)]
    if all(i < j for i, j in itertools.pairwise(middle)) and all(_accepts(e, tol) for e in middle_errors):
        return middle, middle_errors, ended
    return forward, errors, ended


def _reach(plan: _Plan, i: int, end: int, tol: PointTolerance,
           direction: int) -> tuple[int, tuple[float, float, float], int]:
    """The sample j farthest from i towards ``end`` (``direction`` +1: later, -1: earlier) whose
    segment with i is accepted, with its deviations: the length doubled until refused, then bisected;
    and what stopped it (``ProgramPoints.ended_by``: the tolerances the shortest refused segment broke)."""
    def deviation(j: int) -> tuple[float, float, float]:
        return _deviation(plan, min(i, j), max(i, j))

    longest = tol.max_segment_s * (1 + 1e-12)  # the format's longest segment
    if direction > 0:
        last = int(np.searchsorted(plan.t, plan.t[i] + longest, side="right")) - 1
    else:
        last = int(np.searchsorted(plan.t, plan.t[i] - longest, side="left"))
    span = max(1, min(abs(end - i), abs(last - i)))
    best, best_err, refused = 1, deviation(i + direction), span + 1  # a neighbour: always accepted
    broken = FORCED  # the tolerances the shortest refused segment broke
    step = 2
    while step < span:
        err = deviation(i + direction * step)
        if not _accepts(err, tol):
            refused, broken = step, _broken(err, tol)
            break
        best, best_err, step = step, err, step * 2
    else:
        if best < span:
            err = deviation(i + direction * span)
            if _accepts(err, tol):
                return i + direction * span, err, FORCED
            refused, broken = span, _broken(err, tol)
    while refused - best > 1:  # best accepted, refused not: bisect between them
        mid = (best + refused) // 2
        err = deviation(i + direction * mid)
        if _accepts(err, tol):
            best, best_err = mid, err
        else:
            refused, broken = mid, _broken(err, tol)
    return i + direction * best, best_err, broken


def _broken(err: tuple[float, float, float], tol: PointTolerance) -> int:
    """The tolerances a refused segment's deviations break (:data:`POSITION`, :data:`ORIENTATION`, or both)."""
    return POSITION * (err[2] > 1.0) + ORIENTATION * (err[1] > tol.orientation_rad)


def _accepts(err: tuple[float, float, float], tol: PointTolerance) -> bool:
    return err[2] <= 1.0 and err[1] <= tol.orientation_rad


def _deviation(plan: _Plan, i: int, j: int) -> tuple[float, float, float]:
    """Largest TCP position [m] and orientation [rad] deviation of the straight joint segment i -> j
    from the plan's samples strictly between i and j, matched by joint-space arc length, and the
    largest position deviation as a share of the tolerance there."""
    if j - i < 2:
        return 0.0, 0.0, 0.0
    length = plan.arc[j] - plan.arc[i]
    sigma = (plan.arc[i + 1:j] - plan.arc[i]) / length if length > 0.0 else np.zeros(j - i - 1)
    q_line = plan.q[i] + sigma[:, None] * (plan.q[j] - plan.q[i])
    p_line, R_line = plan.robot.tcp_frames(q_line)
    dist = np.linalg.norm(p_line - plan.p[i + 1:j], axis=1)
    err_r = float(np.max(rotation_angles(R_line, plan.R[i + 1:j])))
    return float(np.max(dist)), err_r, float(np.max(dist / plan.position_tol_m[i + 1:j]))
