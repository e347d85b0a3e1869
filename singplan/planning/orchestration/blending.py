"""Fly-by corners (DESIGN.md ``blend_mm``; ABB zones, KUKA C_DIS, Fanuc CNT).

Where move i asks for ``blend_mm: r``, the robot leaves move i's path where the TCP comes
within r of its end point (``u_leave``) and joins move i+1's path where the TCP is r past it
(``u_join``). Between the two it follows the superposition of both motions, as controllers
blend: the rest of move i with a decelerating ramp alpha(v) and the start of move i+1 with an
accelerating ramp beta(v) = 1 - alpha(1 - v), v in [0, 1]:

    X(v) = X_i(alpha(v)) (+) X_c^-1 (+) X_j(beta(v))

(positions added as offsets from the corner, orientations composed as rotations relative to
the corner's). Two ramps are offered (:func:`ramps`), both with alpha' = 2 at the start and
alpha' = 0 at the end, so that with the chain's shares of its parameter
(:mod:`singplan.planning.orchestration.chain`) the joint path is C1 at the seams: the quartic
``alpha(v) = 2 v - 2 v^3 + v^4`` also has alpha'' = 0 at both ends (C2: neither the acceleration
nor, with a jerk limit, the jerk jumps where the corner begins or ends), the quadratic
``alpha(v) = 1 - (1 - v)^2`` (the parabolic blend) curves less sharply in the middle; the planner
times the program with each and keeps the faster. Both are concave, so beta <= alpha and the
weights of the two offsets, (1 - alpha) + beta, never exceed 1: along
straight lines the TCP stays inside the sphere of radius r and the orientation no further from
the corner's than at the ends (the checker's rules); other geometry is verified sample by
sample and the radius shrinks until it holds. One timing pass runs through the corner without
stopping: the braking of move i and the start of move i+1 overlap inside the sphere, which is
where a fly-by saves its time.

Between two LIN / CIRC moves the superposed pose is tracked by exact IK (the orientation is
kept); with a PTP on either side the joints themselves are superposed. The radius is at most
half of the shorter neighbouring move (the distance from each move's midpoint to its ends),
and it is halved where the blend would leave the sphere, the orientation bound or the joint
limits, or could not be tracked; every reduction is reported with its reason.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass, field
from typing import Literal

import numpy as np
import pinocchio as pin

from singplan.kinematics.geometry import rotation_angle
from singplan.kinematics.robot import Robot
from singplan.planning.path.jointmap import JointMap, JointPart
from singplan.planning.path.tracking import track

_SHRINK_STEPS = 6  # halvings of the radius tried before the corner is stopped at instead
_CHECK_POINTS = 65  # samples along a blend verified against the sphere and the orientation bound
_SPHERE_MARGIN = 0.999  # the blend's samples keep within this fraction of r (the checker allows r + tolerance)
_ORIENTATION_SLACK_RAD = math.radians(0.005)  # the checker allows 0.01 deg over the ends' deviation
_SAME_BRANCH_RAD = 1e-6  # the tracked blend must end on the next move's joints
_LEAST_RADIUS_M = 1e-6  # below this a corner is stopped at
_OWN_PATH = 0.05  # the least part of a move's parameter left on its own path between two corners


Ramp = Literal["quartic", "quadratic"]
RAMPS: tuple[Ramp, ...] = ("quartic", "quadratic")


def ramps(v: np.ndarray, kind: Ramp = "quartic") -> tuple[np.ndarray, np.ndarray]:
    """The superposition ramps (alpha, beta) at blend parameters v (N,): the quartic (C2 seams) or
    the quadratic ``alpha = 1 - (1 - v)^2`` (the parabolic blend: a constant acceleration between
    the seams, where it steps)."""
    w = 1.0 - v
    if kind == "quadratic":
        return 1.0 - w**2, v**2
    return 2.0 * v - 2.0 * v**3 + v**4, 1.0 - (2.0 * w - 2.0 * w**3 + w**4)


@dataclass(frozen=True)
class Side:
    """One neighbour of a corner as the blend sees it: its joint map and where its TCP is."""

    jmap: JointMap
    cap_m: float  # the largest radius that fits: the distance from the move's midpoint to its ends
    cartesian: bool  # a LIN / CIRC (its pose is kept); False: a PTP
    speed_m_s: float | None  # the programmed TCP speed (LIN / CIRC)


@dataclass(frozen=True)
class Blend:
    """The fly-by corner after move ``move``.

    Attributes:
        move: the incoming move's index (the blend segment's ``move``).
        requested_m: ``blend_mm`` as asked [m].
        radius_m: the radius used [m]; 0 when the corner is stopped at after all (``note`` says why).
        note: why the radius is smaller than asked ("" when it is not).
        u_leave: the incoming move's parameter where the blend starts.
        u_join: the outgoing move's parameter where the blend ends.
        jmap: the blend's joints over v in [0, 1] (None when the corner is stopped at).
        speed_m_s: the TCP speed cap inside the blend (the faster move's; None with a PTP side).
    """

    move: int
    requested_m: float
    radius_m: float
    note: str
    u_leave: float = 1.0
    u_join: float = 0.0
    jmap: JointMap | None = None
    speed_m_s: float | None = None
    arc_m: np.ndarray = field(default_factory=lambda: np.zeros(2))  # (N,) TCP path length [m] at v = linspace(0, 1, N)
    ramp: Ramp = "quartic"  # the superposition's weights (:func:`ramps`)


class SuperposedJoints(JointMap):
    """A blend with a PTP side: ``q(v) = q_i(alpha) + q_j(beta) - q_corner``, evaluated exactly."""

    def __init__(self, robot: Robot, incoming: JointMap, outgoing: JointMap, u_leave: float, u_join: float,
                 ramp: Ramp, q_corner: np.ndarray) -> None:
        self.incoming, self.outgoing = incoming, outgoing
        self.u_leave, self.u_join, self.ramp, self.q_corner = u_leave, u_join, ramp, q_corner
        v = np.linspace(0.0, 1.0, _CHECK_POINTS)
        super().__init__(robot, None, [JointPart("ptp", v, self.evaluate(v))])

    @property
    def straight(self) -> bool:
        return False

    def evaluate(self, u: np.ndarray) -> np.ndarray:
        alpha, beta = ramps(np.minimum(np.maximum(np.asarray(u, dtype=float), 0.0), 1.0), self.ramp)
        q_i = self.incoming.evaluate(self.u_leave + alpha * (1.0 - self.u_leave))
        q_j = self.outgoing.evaluate(beta * self.u_join)
        return q_i + q_j - self.q_corner


def superposed_poses(robot: Robot, incoming: JointMap, outgoing: JointMap, u_leave: float,
                     u_join: float, ramp: Ramp, T_corner: pin.SE3) -> Callable[[np.ndarray], np.ndarray]:
    """The blend's TCP poses (N, 4, 4) as a function of v (N,): both moves' actual poses superposed."""
    T_c = np.asarray(T_corner.homogeneous)

    def poses(v: np.ndarray) -> np.ndarray:
        alpha, beta = ramps(np.asarray(v, dtype=float), ramp)
        T_i = _fk_all(robot, incoming.evaluate(u_leave + alpha * (1.0 - u_leave)))
        T_j = _fk_all(robot, outgoing.evaluate(beta * u_join))
        out = np.empty_like(T_i)
        out[:, :3, 3] = T_i[:, :3, 3] + T_j[:, :3, 3] - T_c[:3, 3]
        out[:, :3, :3] = T_i[:, :3, :3] @ T_c[:3, :3].T @ T_j[:, :3, :3]
        out[:, 3] = (0.0, 0.0, 0.0, 1.0)
        return out

    return poses


def _fk_all(robot: Robot, q: np.ndarray) -> np.ndarray:
    return np.array([robot.fk(qk).homogeneous for qk in q])


def side_of(robot: Robot, jmap: JointMap, cartesian: bool, speed_m_s: float | None) -> Side:
    """What a corner needs to know of a move: the radius that fits."""
    p = robot.tcp_positions(jmap.evaluate(np.array([0.0, 0.5, 1.0])))
    cap = min(float(np.linalg.norm(p[1] - p[0])), float(np.linalg.norm(p[1] - p[2])))
    return Side(jmap, cap, cartesian, speed_m_s)


def crossing_parameter(robot: Robot, jmap: JointMap, corner_m: np.ndarray, radius_m: float, leaving: bool) -> float:
    """The move's parameter where its TCP is ``radius_m`` from the corner: the last such point
    before the end (``leaving``) or the first after the start, by bisection on the joint map."""
    u = np.linspace(0.0, 1.0, 257)
    d = np.linalg.norm(robot.tcp_positions(jmap.evaluate(u)) - corner_m, axis=1)
    outside = np.flatnonzero(d >= radius_m)
    if leaving:  # the interval where the distance last falls below r
        k = int(outside[-1]) if outside.size else 0
        lo, hi = u[k], u[min(k + 1, len(u) - 1)]
    else:
        k = int(outside[0]) if outside.size else len(u) - 1
        lo, hi = u[max(k - 1, 0)], u[k]
    for _ in range(50):
        mid = 0.5 * (lo + hi)
        far = float(np.linalg.norm(robot.tcp_positions(jmap.evaluate(np.array([mid])))[0] - corner_m)) >= radius_m
        if far == leaving:
            lo = mid
        else:
            hi = mid
    return lo if leaving else hi


class CrossingMemo:
    """Where each move's TCP crosses a corner's sphere, found once for every ramp shape tried: the
    crossing depends on the joint map, the corner and the radius, not on the ramp."""

    def __init__(self) -> None:
        self._found: dict[tuple[int, bool, float, bytes], float] = {}

    def parameter(self, robot: Robot, jmap: JointMap, corner_m: np.ndarray, radius_m: float, leaving: bool) -> float:
        """:func:`crossing_parameter` (``jmap`` alive while the memo is: its id is the key)."""
        key = (id(jmap), leaving, radius_m, corner_m.tobytes())
        if key not in self._found:
            self._found[key] = crossing_parameter(robot, jmap, corner_m, radius_m, leaving)
        return self._found[key]


def blend_corner(robot: Robot, move: int, requested_m: float, incoming: Side, outgoing: Side,
                 u_floor: float, ramp: Ramp = "quartic", memo: CrossingMemo | None = None) -> Blend:
    """The fly-by corner after ``move``, its radius reduced until it fits and holds.

    ``u_floor``: where the incoming move's own path begins (the end of the blend into it), so
    two blends never overlap on one move. ``memo``: crossings found for another ramp shape.
    """
    memo = memo if memo is not None else CrossingMemo()
    cap = min(incoming.cap_m, outgoing.cap_m)
    radius, note = requested_m, ""
    which = move if incoming.cap_m <= outgoing.cap_m else move + 1
    if cap <= _LEAST_RADIUS_M:
        return Blend(move, requested_m, 0.0, f"not flown by: move {which} has no TCP travel to fly by in")
    if cap < radius:
        radius, note = cap, f"reduced to half of move {which}'s length ({2 * cap * 1e3:.3f} mm)"
    q_corner = outgoing.jmap.evaluate(np.array([0.0]))[0]
    T_corner = robot.fk(q_corner)
    corner = T_corner.translation
    if u_floor > 0:  # the fly-by into the incoming move takes its start: keep some of its own path
        room = float(np.linalg.norm(robot.tcp_positions(incoming.jmap.evaluate(np.array([u_floor + _OWN_PATH])))[0]
                                    - corner))
        if room < radius:
            radius, note = room * 0.999, (f"reduced to {room * 0.999e3:.3f} mm: the fly-by into move {move} "
                                          f"leaves it no more room")
    if radius <= _LEAST_RADIUS_M:
        return Blend(move, requested_m, 0.0, f"not flown by: {radius * 1e3:g} mm is at or below the least radius flown "
                                             f"({_LEAST_RADIUS_M * 1e3:g} mm)")
    for _ in range(_SHRINK_STEPS):
        if radius <= _LEAST_RADIUS_M:
            break
        u_leave = memo.parameter(robot, incoming.jmap, corner, radius, leaving=True)
        u_join = memo.parameter(robot, outgoing.jmap, corner, radius, leaving=False)
        failure = f"it overlaps the fly-by into move {move}" if u_leave <= u_floor + _OWN_PATH else None
        blend = None
        if failure is None:
            blend, failure = _built(robot, move, requested_m, radius, note, incoming, outgoing, u_leave, u_join,
                                    ramp, q_corner, T_corner)
        if blend is not None:
            return blend
        radius *= 0.5
        note = f"halved to {radius * 1e3:.3f} mm: at {2 * radius * 1e3:.3f} mm {failure}"
    return Blend(move, requested_m, 0.0, f"not flown by: {note or 'the radius is 0'}")


def _built(robot: Robot, move: int, requested_m: float, radius_m: float, note: str, incoming: Side,
           outgoing: Side, u_leave: float, u_join: float, ramp: Ramp, q_corner: np.ndarray,
           T_corner: pin.SE3) -> tuple[Blend | None, str]:
    """The blend at one radius, or None and what went wrong."""
    joints = SuperposedJoints(robot, incoming.jmap, outgoing.jmap, u_leave, u_join, ramp, q_corner)
    if incoming.cartesian and outgoing.cartesian:
        poses = superposed_poses(robot, incoming.jmap, outgoing.jmap, u_leave, u_join, ramp, T_corner)
        jmap = _pose_kept(robot, poses, joints)
        if jmap is None:
            return None, "no continuous joint motion follows it (a singular point or a branch change inside)"
        speeds = [s for s in (incoming.speed_m_s, outgoing.speed_m_s) if s is not None]
        speed = max(speeds) if speeds else None
    else:
        jmap, speed = joints, None
    q = jmap.evaluate(np.linspace(0.0, 1.0, 4 * _CHECK_POINTS))
    T = _fk_all(robot, q)  # (N, 4, 4): the samples' poses, once for the checks and the arc length
    failure = _violation(robot, q, T, T_corner, radius_m)
    if failure:
        return None, failure
    arc = np.concatenate([[0.0], np.cumsum(np.linalg.norm(np.diff(T[:, :3, 3], axis=0), axis=1))])
    return Blend(move, requested_m, radius_m, note, u_leave, u_join, jmap, speed, arc, ramp), ""


def _pose_kept(robot: Robot, poses: Callable[[np.ndarray], np.ndarray], joints: SuperposedJoints) -> JointMap | None:
    """The superposed pose followed by IK from the blend's start to the next move's joints (None: not continuously).

    A six-joint arm tracks the pose along one IK branch; a redundant arm (no branch to follow) takes
    the superposed joints as its reference, each corrected to the pose, so the corner ends on the
    joints the next move starts from, whatever its null-space motion.
    """
    v = np.linspace(0.0, 1.0, _CHECK_POINTS)
    q_start, q_end = joints.evaluate(np.array([0.0, 1.0]))
    if robot.n_joints > 6:
        jmap = JointMap(robot, poses, [JointPart("track", v, joints.evaluate(v))])
        q = jmap.evaluate(np.linspace(0.0, 1.0, 4 * _CHECK_POINTS))
        jumps = float(np.max(np.abs(np.diff(q, axis=0)))) > math.radians(1.0)
        return None if jumps else JointMap(robot, poses, [JointPart("track", v, jmap.evaluate(v))])
    tracked = track(robot, poses, v, q_start)
    if tracked.gap_index >= 0 or float(np.max(np.abs(tracked.q[-1] - q_end))) > _SAME_BRANCH_RAD:
        return None
    return JointMap(robot, poses, [JointPart("track", tracked.u, tracked.q)])


def _violation(robot: Robot, q: np.ndarray, T: np.ndarray, T_corner: pin.SE3, radius_m: float) -> str:
    """What the blend's samples q (N, n), at poses T (N, 4, 4), break: the joint limits, the sphere
    or the orientation bound (no further from the corner's orientation than at the blend's ends);
    "" for none."""
    if not robot.within_limits(q):
        return "it leaves the joint limits"
    far = float(np.max(np.linalg.norm(T[1:-1, :3, 3] - T_corner.translation, axis=1), initial=0.0))
    if far > radius_m * _SPHERE_MARGIN + 1e-9:
        return f"it leaves the sphere ({far * 1e3:.3f} mm from the corner)"
    turn = np.array([rotation_angle(R, T_corner.rotation) for R in T[:, :3, :3]])
    if float(turn.max()) > max(turn[0], turn[-1]) + _ORIENTATION_SLACK_RAD:
        return (f"it turns the tool {math.degrees(float(turn.max())):.4f} deg from the corner's orientation, "
                f"more than at its ends")
    return ""


def corners(robot: Robot, sides: list[Side], at_rest: list[str], requested_m: list[float],
            ramp: Ramp = "quartic", memo: CrossingMemo | None = None) -> dict[int, Blend]:
    """The fly-by corners of a task's moves, in order, each fitted between its neighbours.

    Per move: ``sides`` (:func:`side_of`), why it must start and end at rest in ``at_rest`` (""
    when it need not; a null-space pause, the quintic PTP law), ``blend_mm`` [m] in
    ``requested_m`` (0: none).
    """
    out: dict[int, Blend] = {}
    u_floor = 0.0
    for i, r in enumerate(requested_m[:-1]):
        if r <= 0:
            u_floor = 0.0
            continue
        resting = [k for k in (i, i + 1) if at_rest[k]]
        if resting:
            out[i] = Blend(i, r, 0.0, f"not flown by: move {resting[0]} {at_rest[resting[0]]}")
            u_floor = 0.0
            continue
        out[i] = blend_corner(robot, i, r, sides[i], sides[i + 1], u_floor, ramp, memo)
        u_floor = out[i].u_join if out[i].jmap is not None else 0.0
    return out


def stopped(blend: Blend, reason: str) -> Blend:
    """The corner stopped at after all, with the reason."""
    return Blend(blend.move, blend.requested_m, 0.0, f"not flown by: {reason}")
