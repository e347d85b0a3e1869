"""Crossing method ``null-space``: SEEDS 002's null-space mover.

Where a LIN/CIRC meets a singular configuration (wrist: axes 4 and 6 aligned; shoulder: the
wrist point on axis 1), the joints can move without moving the tool: the Jacobian has a null
space there (A4 against A6 at the wrist; A1 with A4-A6 compensating at the shoulder). Exact
tracking goes through the singular point and continues in the other configuration; where that
continuation leaves a joint limit, this method stops the TCP on the singular point, turns the
aligned joints by half a turn (or a whole one) through the null space, and continues in the
branch that turn leads to. The full pose is kept; only time is spent.

How the pause is represented (one move, three timed pieces). A move's joint map is a function
of the path parameter u; a pause is a joint motion at one u, which no such function holds. So a
:class:`Crossing` with a pause carries two joint-map parts, ``blend`` up to the singular point
``u_s`` and ``pause.after`` from it, and the :class:`Pause` itself: reference joint values of the
null-space motion. :func:`singplan.planning.stops.time_in_pieces` times the move as pieces that each start and end at
rest (the path up to ``u_s``, the pause, the path after it, ...) with the same TOPP-RA timing as
any move, and joins them: every sample of the pause carries ``u = u_s``, so the segment labelling
puts it inside the crossing, and the seams are within the acceleration limit because every
piece's end steps are (:func:`singplan.planning.timing.end_step_ratio`).

The method acts only where the path meets the singularity within exact's tolerance (0.01 deg,
or the position tolerance at the shoulder): elsewhere no joint motion keeps the pose, and it
keeps the branch as exact does. An elbow singularity has no finite self-motion; there it
behaves as exact. Neither has a shoulder singularity whose wrist point lies beside axis 1 rather
than on it (a UR arm, a shoulder offset): turning A1 moves the tool, and the turn is refused
with the figures (:func:`self_motion`).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, replace

import numpy as np

from singplan.errors import JointLimitError, SingularityError
from singplan.kinematics.configuration import distances_batch
from singplan.kinematics.ik.numeric import damped_solve, pose_error
from singplan.kinematics.robot import Robot
from singplan.planning.crossing.base import Crossing, MoveContext, Pause
from singplan.planning.crossing.methods import (
    EXACT_ORIENTATION_TOL_RAD,
    Exact,
    exit_candidates,
    met_below,
    path_slope,
    rest_of_move,
    sample_densely,
    through,
)
from singplan.planning.path.jointmap import JointMap, JointPart, interpolate
from singplan.planning.path.tracking import nearest_candidate
from singplan.planning.path.zones import KIND_INDEX, Zone

# turns of the driven joint tried, smallest first: half a turn changes the branch, a whole one
# only the joint's turn number
TURNS_RAD = (math.pi, -math.pi, 2 * math.pi, -2 * math.pi)
_PAUSE_STEP_RAD = math.radians(0.25)  # reference samples of the pause, in the driven joint
_MAX_PAUSE_STEP_RAD = math.radians(5.0)  # a compensating joint jumping more per reference step: no self-motion
_EDGE_FACTOR, _EDGE_MIN = 50.0, {"wrist": math.radians(0.05), "shoulder": 0.0005}  # as exact's through-crossing
_MAX_PROJECTION_STEP_RAD = 0.1  # Gauss-Newton steps of the projection onto the singularity, capped
_SINGULAR_WEIGHT = 10.0  # weight of the singular distance against the pose error when projecting


@dataclass(frozen=True)
class _Blocked:
    """Why one way on leaves the limits: the joint, its value and where."""

    joint: int
    value_rad: float
    where: str
    sample: int = 0  # row of the joint values checked


class NullSpace:
    """Pause on a met singularity and turn the aligned joints in the null space (module doc).

    ``only_when_needed`` (auto): refuse (so auto lists why) where exact's own crossing keeps the
    limits or where the path does not meet the singularity; auto then keeps exact's result.
    """

    name = "null-space"
    variant = ""

    def __init__(self, only_when_needed: bool = False) -> None:
        self.only_when_needed = only_when_needed

    def cross(self, ctx: MoveContext, zone: Zone) -> Crossing | None:
        met = met_below(ctx, zone)
        # under auto, a zone that needs no pause refuses (auto has exact's plan already) unless a
        # later zone on the move may need one
        refuse = self.only_when_needed and not _zone_after(ctx, zone)
        if zone.kind == "elbow" or zone.min_distance >= met or not 1e-9 < zone.u_closest < 1.0 - 1e-9:
            if refuse:
                raise self._not_needed(ctx, zone, "acts only where the path meets a wrist or shoulder singularity "
                                                  f"inside the move (closest {zone.describe_distance()})")
            return Exact().cross(ctx, zone)
        plain = through(ctx, zone, self.name)
        plain_block = None if plain is None else (
            _outside(ctx.robot, plain.blend.q, ctx.piece.describe(zone.u_closest))
            or _rest_blocked(ctx, plain.blend.u1, plain.q_exit))
        if plain is not None and plain_block is None:
            if refuse:
                raise self._not_needed(ctx, zone, "is not needed: exact's crossing keeps the joint limits")
            return plain
        return self._pause(ctx, zone, plain, plain_block)

    def _not_needed(self, ctx: MoveContext, zone: Zone, why: str) -> SingularityError:
        return SingularityError(f"move {ctx.move_index} ({ctx.move_kind}): null-space {why}; the {zone.kind} zone's "
                                f"closest point is at {ctx.piece.describe(zone.u_closest)}",
                                move=ctx.move_index, kind=zone.kind, s_m=zone.u_closest * ctx.piece.length_m)

    def _pause(self, ctx: MoveContext, zone: Zone, plain: Crossing | None, plain_block: _Blocked | None) -> Crossing:
        robot, u, q, u_s = ctx.robot, ctx.tracked.u, ctx.tracked.q, zone.u_closest
        d = np.abs(ctx.distances[:, KIND_INDEX[zone.kind]])
        edge = max(_EDGE_FACTOR * zone.min_distance, _EDGE_MIN[zone.kind])
        a = int(np.nonzero((u < u_s) & (d >= edge))[0][-1]) if np.any((u < u_s) & (d >= edge)) else 0
        after_edge = np.nonzero((u > u_s) & (d >= edge))[0]
        u_b = float(u[after_edge[0]]) if after_edge.size else 1.0
        T_s = ctx.piece.poses(np.array([u_s]))[0]
        # exact's through-crossing passes the singular point with continuous joints: its joints there
        guess = q[a] if plain is None else JointMap(robot, ctx.piece.poses, [plain.blend]).evaluate(np.array([u_s]))[0]
        q_s = singular_config(robot, guess, T_s, zone.kind)
        before = _blend(ctx, float(u[a]), q[a], u_s, q_s, a > 0, False)
        joint = 0 if zone.kind == "shoulder" else robot.n_joints - 3
        tried: list[tuple[float, _Blocked | str]] = []
        arriving = _outside(robot, before.q, f"{ctx.piece.describe(u_s)} (arriving at the singular point)")
        if arriving is not None:  # no turn at the point can help a path that leaves the limits before it
            raise _refusal(ctx, zone, joint, None, [(0.0, arriving)])
        for turn in TURNS_RAD:
            found = self._turn(ctx, zone, before, T_s, joint, turn, u_b)
            if isinstance(found, Crossing):
                return found
            tried.append((turn, found))
        raise _refusal(ctx, zone, joint, plain_block, tried)

    def _turn(self, ctx: MoveContext, zone: Zone, before: JointPart, T_s: np.ndarray, joint: int, turn: float,
              u_b: float) -> Crossing | _Blocked | str:
        """The crossing that turns ``joint`` by ``turn`` at the end of ``before`` and rejoins the path
        at ``u_b``; else where that leaves a joint limit (in the pause, after it, or later on the move),
        or why no pose-keeping motion turns it so far."""
        u_s, where = before.u1, ctx.piece.describe(before.u1)
        try:
            motion = self_motion(ctx.robot, before.q[-1], T_s, joint, turn, ctx.position_tolerance_m)
        except _NoSelfMotionError as exc:
            return str(exc)
        blocked = _outside(ctx.robot, motion, f"{where} (the pause)")
        if blocked is not None:
            return blocked
        exits = exit_candidates(ctx, u_b)
        q_exit = nearest_candidate(np.array(exits), motion[-1])[0] if exits else motion[-1]
        after = _blend(ctx, u_s, motion[-1], u_b, q_exit, False, u_b < 1.0 - 1e-12)
        blocked = _outside(ctx.robot, after.q, f"{where} (leaving the singular point)") or \
            _rest_blocked(ctx, u_b, after.q[-1])
        if blocked is not None:
            return blocked
        return Crossing(zone, self.name, before, after.q[-1], Pause(u_s, motion, after, joint, turn, T_s))


def _zone_after(ctx: MoveContext, zone: Zone) -> bool:
    """Whether the tracked move comes inside a wrist or shoulder zone again after ``zone``."""
    after = ctx.tracked.u > zone.u_exit
    inside = np.abs(ctx.distances[after, :2]) < ctx.thresholds[:2]
    return bool(np.any(inside))


def _blend(ctx: MoveContext, u0: float, q0: np.ndarray, u1: float, q1: np.ndarray, slope0: bool,
           slope1: bool) -> JointPart:
    """A position-exact Hermite part from (u0, q0) to (u1, q1): the path's slope at an end that
    joins tracked path (``slope0`` / ``slope1``), the chord where it meets the pause or the move's end."""
    chord = (q1 - q0) / (u1 - u0)
    s0 = path_slope(ctx.robot, ctx.piece, u0, q0) if slope0 else chord
    s1 = path_slope(ctx.robot, ctx.piece, u1, q1) if slope1 else chord
    return sample_densely(ctx, JointPart("blend", np.array([u0, u1]), np.array([q0, q1]), np.array([s0, s1])))


def _outside(robot: Robot, q: np.ndarray, where: str) -> _Blocked | None:
    """The first joint of q (K, n) to leave its limits, at its furthest outside, or None."""
    bad = np.argwhere((q < robot.lower_rad - 1e-9) | (q > robot.upper_rad + 1e-9))
    if bad.size == 0:
        return None
    j = int(bad[0][1])
    over = np.maximum(robot.lower_rad[j] - q[:, j], q[:, j] - robot.upper_rad[j])
    k = int(np.argmax(over))
    return _Blocked(j, float(q[k, j]), where, k)


def _rest_blocked(ctx: MoveContext, u_from: float, q_from: np.ndarray) -> _Blocked | None:
    """Where following the rest of the move with the full pose from ``q_from`` leaves a limit."""
    rest = rest_of_move(ctx, u_from, q_from)
    if rest is None:
        return None
    blocked = _outside(ctx.robot, rest.q, "")
    return None if blocked is None else replace(blocked, where=ctx.piece.describe(float(rest.u[blocked.sample])))


def _refusal(ctx: MoveContext, zone: Zone, joint: int, plain: _Blocked | None,
             tried: list[tuple[float, _Blocked | str]]) -> JointLimitError | SingularityError:
    """Exit 3 naming the joint that stops each way on (the error's figures are the smallest
    overshoot's), or, where no turn keeps the pose at all, why."""
    robot = ctx.robot

    def over(b: _Blocked) -> float:
        return max(robot.lower_rad[b.joint] - b.value_rad, b.value_rad - robot.upper_rad[b.joint])

    def says(b: _Blocked | str) -> str:
        if isinstance(b, str):
            return b
        return (f"{robot.joint_names[b.joint]} reaches {math.degrees(b.value_rad):.2f} deg (limits "
                f"[{math.degrees(robot.lower_rad[b.joint]):.1f}, {math.degrees(robot.upper_rad[b.joint]):.1f}] deg) "
                f"at {b.where}")

    ways = [f"turning {robot.joint_names[joint]} by {math.degrees(t):+.0f} deg: {says(b)}" if t else says(b)
            for t, b in tried]
    if plain is not None:
        ways.insert(0, f"without a pause (exact): {says(plain)}")
    head = (f"move {ctx.move_index} ({ctx.move_kind}): null-space finds no joint motion at the {zone.kind} singular "
            f"point at {ctx.piece.describe(zone.u_closest)} from which the rest of the path keeps the joint limits; ")
    blocks = [b for _, b in tried if not isinstance(b, str)]  # exact's own block is why null-space was asked
    if not blocks:
        return SingularityError(head + "; ".join(ways), move=ctx.move_index, kind=zone.kind,
                                s_m=zone.u_closest * ctx.piece.length_m)
    worst = min(blocks, key=over)
    return JointLimitError(
        head + f"{robot.joint_names[worst.joint]} stops it: " + "; ".join(ways),
        joint=robot.joint_names[worst.joint], value_rad=worst.value_rad, lower_rad=float(robot.lower_rad[worst.joint]),
        upper_rad=float(robot.upper_rad[worst.joint]), move=ctx.move_index)


class _NoSelfMotionError(Exception):
    """The null space does not carry the driven joint on (the message says why)."""


def hold_pose(robot: Robot, q: np.ndarray, T_target: np.ndarray, joint: int, iterations: int = 10) -> np.ndarray:
    """q with every joint but ``joint`` moved so the pose is T_target (least squares; at a singular
    configuration the other joints' columns still span the Jacobian's range)."""
    def residual(qk: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        return pose_error(robot, qk, T_target), robot.jacobian(qk)

    free = [j for j in range(robot.n_joints) if j != joint]
    return damped_solve(residual, q, free, rcond=1e-10, tol=1e-13, iterations=iterations)


def singular_config(robot: Robot, q: np.ndarray, T_target: np.ndarray, kind: str, iterations: int = 30) -> np.ndarray:
    """Joints near q at the pose T_target with the ``kind`` singular distance zero (Gauss-Newton on
    the pose error and the weighted distance; the distance's gradient by central differences).
    Where the path only nearly meets the singularity, the pose error left is about the miss."""
    i, h = KIND_INDEX[kind], 1e-7

    def residual(qk: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        probes = np.vstack([qk, qk + h * np.eye(len(qk)), qk - h * np.eye(len(qk))])
        dist = distances_batch(robot, probes)[:, i]
        grad = (dist[1:len(qk) + 1] - dist[len(qk) + 1:]) / (2 * h)
        return (np.append(pose_error(robot, qk, T_target), -_SINGULAR_WEIGHT * dist[0]),
                np.vstack([robot.jacobian(qk), _SINGULAR_WEIGHT * grad]))

    # the self-motion direction is in the null space of both rows: truncate, never amplify it
    return damped_solve(residual, q, slice(None), rcond=1e-6, step_tol=1e-14, max_step=_MAX_PROJECTION_STEP_RAD,
                        iterations=iterations)


def self_motion(robot: Robot, q0: np.ndarray, T_target: np.ndarray, joint: int, turn_rad: float,
                tol_m: float = 1e-5) -> np.ndarray:
    """Reference samples (K, n) of the null-space motion from q0 turning ``joint`` by ``turn_rad``.

    Each step follows the Jacobian's null vector (its smallest right singular vector, scaled to
    move ``joint`` by the step) and then restores the pose with the other joints
    (:func:`hold_pose`). Raises _NoSelfMotionError where the null space does not move ``joint``,
    a compensating joint would jump (it would pass another singularity), or the pose drifts past
    ``tol_m`` / 0.01 deg (the singularity has no self-motion: e.g. a UR arm's shoulder, whose wrist
    point is beside axis 1, not on it).
    """
    steps = max(2, math.ceil(abs(turn_rad) / _PAUSE_STEP_RAD))
    out = np.empty((steps + 1, robot.n_joints))
    out[0] = q0
    for k in range(1, steps + 1):
        J = robot.jacobian(out[k - 1])
        if not np.all(np.isfinite(J)):  # the hold before did not converge to joint values: no way on
            raise _NoSelfMotionError(f"turning {robot.joint_names[joint]} loses the pose after {k - 1} steps")
        n = np.linalg.svd(J)[2][-1]
        if abs(n[joint]) < 0.1 * float(np.max(np.abs(n))):
            raise _NoSelfMotionError(f"the Jacobian's null space does not move {robot.joint_names[joint]} here")
        guess = out[k - 1] + n / n[joint] * (turn_rad / steps)
        out[k] = hold_pose(robot, guess, T_target, joint)
        err = pose_error(robot, out[k], T_target)
        moved_m, turned_rad = float(np.linalg.norm(err[:3])), float(np.linalg.norm(err[3:]))
        if moved_m > tol_m or turned_rad > EXACT_ORIENTATION_TOL_RAD:
            raise _NoSelfMotionError(f"turning {robot.joint_names[joint]} moves the tool by {moved_m * 1e3:.4f} mm / "
                                     f"{math.degrees(turned_rad):.4f} deg: no joint motion keeps the pose here")
        jump = float(np.max(np.abs(out[k] - out[k - 1])))
        if jump > _MAX_PAUSE_STEP_RAD:
            raise _NoSelfMotionError(f"turning {robot.joint_names[joint]} makes the other joints jump by "
                                f"{math.degrees(jump):.1f} deg (they would pass another singularity)")
    return out


class PauseMap(JointMap):
    """The pause as a joint map of v in [0, 1]: the reference samples interpolated, then the pose
    restored with the driven joint held, so every sample keeps the pose."""

    def __init__(self, robot: Robot, pause: Pause) -> None:
        super().__init__(robot, None, [JointPart("ptp", np.linspace(0.0, 1.0, len(pause.q)), pause.q)])
        self.pause = pause

    def evaluate(self, u: np.ndarray) -> np.ndarray:
        v = np.minimum(np.maximum(np.asarray(u, dtype=float), 0.0), 1.0)
        q = interpolate(self.parts[0], v)
        inner = (v > 0.0) & (v < 1.0)  # the ends are the neighbouring pieces' own samples
        for k in np.nonzero(inner)[0]:
            q[k] = hold_pose(self.robot, q[k], self.pause.T_target, self.pause.joint)
        return q
