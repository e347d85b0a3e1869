"""The built-in crossing methods: what a move does inside a singular zone.

The protocol and the records are in :mod:`singplan.planning.crossing.base`; the names users
plan with are mapped to these objects in :mod:`singplan.planning.crossing.registry`.

A method looks at one zone of a tracked move and either keeps the tracked (in-branch)
solution, returns a :class:`Crossing` that replaces the zone's joint values and continues
the move in another branch, or refuses with :class:`~singplan.errors.SingularityError`.
Methods never time anything; the timing slows the path where joints must move fast.

Available now:

* ``wrist-joint``: see :class:`WristJoint` (SEEDS 001).
* ``exact``: the full pose is kept. At a near miss the branch is kept and the wrist (or axis
  1) swings while the timing slows the path (SEEDS 002's speed scaleback). Where the path
  passes within the exact tolerance of the singularity (0.01 deg, or the position tolerance
  for the shoulder) it goes *through* it: the label changes at the closest point, the
  joints stay continuous, and the pose deviates by at most the miss (see :func:`through`).
* ``stop``: refuse every zone, naming the move and the point (like MoveIt / Pilz).
"""

from __future__ import annotations

import math
from dataclasses import replace
from typing import ClassVar

import numpy as np
import pinocchio as pin

from singplan.errors import SingularityError
from singplan.kinematics.configuration import distances_batch, labels_from_distances
from singplan.kinematics.ik import numeric as ik_numeric
from singplan.kinematics.ik.solve import closed_form_branches
from singplan.kinematics.robot import Robot
from singplan.planning.crossing.base import Crossing, MoveContext
from singplan.planning.path.cartesian import CartesianPiece
from singplan.planning.path.jointmap import JointMap, JointPart, hermite
from singplan.planning.path.tracking import TrackedPath, nearest_candidate, track
from singplan.planning.path.zones import KIND_INDEX, Zone

EXACT_ORIENTATION_TOL_RAD = math.radians(0.01)
# a through-crossing blends where the in-branch swing has not started: |distance| above
# this many times the miss, and at least these absolute values
_EDGE_FACTOR = 50.0
_EDGE_MIN = {"wrist": math.radians(0.05), "elbow": math.radians(0.05), "shoulder": 0.0005}
_THROUGH_MAX_JUMP_RAD = math.radians(5.0)
_BLEND_STEP_M = 0.001  # reference samples of a blend: every millimetre of path


class Stop:
    """Refuse at every singular zone."""

    name = "stop"
    variant = ""

    def cross(self, ctx: MoveContext, zone: Zone) -> Crossing | None:
        where, closest = ctx.piece.describe(zone.u_entry), ctx.piece.describe(zone.u_closest)
        raise SingularityError(
            f"move {ctx.move_index} ({ctx.move_kind}): {zone.kind} singular zone at {where}, "
            f"closest {zone.describe_distance()} at {closest}; method 'stop' refuses to cross",
            move=ctx.move_index, kind=zone.kind, s_m=zone.u_entry * ctx.piece.length_m)


class Exact:
    """Keep the full pose; go through the singularity only where the path (almost) meets it."""

    name = "exact"
    variant = ""

    def cross(self, ctx: MoveContext, zone: Zone) -> Crossing | None:
        if zone.min_distance >= met_below(ctx, zone):
            return None  # a near miss: stay in the branch, the timing slows the swing
        return through(ctx, zone, self.name)


def met_below(ctx: MoveContext, zone: Zone) -> float:
    """The singular distance under which a zone's singularity counts as met: exact goes through it
    (above it: a near miss it follows), null-space may pause on it."""
    return ctx.position_tolerance_m if zone.kind == "shoulder" else EXACT_ORIENTATION_TOL_RAD


def through(ctx: MoveContext, zone: Zone, method: str) -> Crossing | None:
    """Pass a (nearly) met singularity with continuous joints and a label change.

    Around the closest point the in-branch solution would swing by ~180 deg within a
    distance comparable to the miss. Instead, the joints are blended (cubic Hermite, joints
    1-3 re-solved for the exact position) from the last sample before the swing to the
    branch of the other label just after it; the pose deviates there by about the miss.
    Returns None when no nearby solution of the other label exists.
    """
    u, q, d = ctx.tracked.u, ctx.tracked.q, np.abs(ctx.distances[:, KIND_INDEX[zone.kind]])
    edge = max(_EDGE_FACTOR * zone.min_distance, _EDGE_MIN[zone.kind])
    before = np.nonzero((u < zone.u_closest) & (d >= edge))[0]
    after = np.nonzero((u > zone.u_closest) & (d >= edge))[0]
    if before.size == 0 or after.size == 0:
        return None
    a, b = int(before[-1]), int(after[0])
    options = _other_side(ctx.robot, exit_candidates(ctx, float(u[b])), q[a], zone.kind)
    if not options:
        return None
    q_exit, jump = nearest_candidate(np.array(options), q[a])
    if jump > _THROUGH_MAX_JUMP_RAD:
        return None
    return blend_crossing(ctx, zone, method, a, float(u[b]), q_exit)


def exit_candidates(ctx: MoveContext, u: float) -> list[np.ndarray]:
    """Every IK branch of the path pose at ``u``: the closed form, or on an arm without one the
    all-branch numeric IK (:func:`singplan.kinematics.ik.numeric.all_branches`, inside the joint limits)."""
    T = ctx.piece.poses(np.array([u]))
    sols = closed_form_branches(ctx.robot, T)[0]
    if sols.shape[0] == 0:
        rows, _ = ik_numeric.all_branches(ctx.robot, pin.SE3(T[0, :3, :3], T[0, :3, 3]))
        return [np.asarray(q) for q in rows]
    return list(sols[np.all(np.isfinite(sols), axis=1)])


def path_slope(robot: Robot, piece: CartesianPiece, u: float, q: np.ndarray) -> np.ndarray:
    """dq/du [rad] of the exact IK branch through joints ``q`` at path parameter ``u``: ``J(q)^-1 dX/du``.

    ``dX/du`` is the path's velocity (:meth:`CartesianPiece.velocity`, in the frame
    :meth:`Robot.jacobian` uses); outside singular zones J is well conditioned, so seams match
    the path's true slope rather than a chord of samples.
    """
    J, x_u = robot.jacobian(q), piece.velocity(u)
    return np.linalg.solve(J, x_u) if J.shape[1] == 6 else np.linalg.lstsq(J, x_u, rcond=None)[0]


def _seam_slopes(ctx: MoveContext, a: int, u_b: float, q_exit: np.ndarray) -> np.ndarray:
    """dq/du (2, n) at a crossing's seams: the exact path's through tracked sample ``a`` and
    through ``q_exit`` at ``u_b``, so joint velocities are continuous there; the chord where a
    seam is the start of the tracked stretch or the end of the move."""
    u, q = ctx.tracked.u, ctx.tracked.q
    chord = (q_exit - q[a]) / (u_b - u[a])
    entry = path_slope(ctx.robot, ctx.piece, float(u[a]), q[a]) if a > 0 else chord
    exit_ = path_slope(ctx.robot, ctx.piece, u_b, q_exit) if u_b < 1.0 - 1e-12 else chord
    return np.array([entry, exit_])


def blend_crossing(ctx: MoveContext, zone: Zone, method: str, a: int, u_b: float, q_exit: np.ndarray) -> Crossing:
    """A Hermite blend from tracked sample ``a`` to ``q_exit`` at ``u_b``, position re-solved."""
    u, q = ctx.tracked.u, ctx.tracked.q
    ends = JointPart("blend", np.array([u[a], u_b]), np.array([q[a], q_exit]), _seam_slopes(ctx, a, u_b, q_exit))
    return Crossing(zone, method, sample_densely(ctx, ends), q_exit)


def sample_densely(ctx: MoveContext, ends: JointPart) -> JointPart:
    """A blend or axis part given by its two ends, sampled every ``_BLEND_STEP_M`` of path, each
    sample exact in what its method keeps (the position for a blend)."""
    count = max(9, math.ceil((ends.u1 - ends.u0) * ctx.piece.length_m / _BLEND_STEP_M) + 1)
    dense_u = np.linspace(ends.u0, ends.u1, count)
    jmap = JointMap(ctx.robot, ctx.piece.poses, [ends])
    dense_q = jmap.fix_position(hermite(ends, dense_u), dense_u) if ends.kind == "blend" else \
        jmap.solve_axis(ends, dense_u)
    return replace(ends, u=dense_u, q=dense_q)


class WristJoint:
    """SEEDS 001: interpolate the wrist joints across a wrist zone, keep the position exact.

    q4..q6 go from their entry values to the exit values of the target branch (the one
    nearest the entry: the flipped wrist at a near miss) along a cubic Hermite blend whose
    slopes match the neighbouring path, so joint velocities are continuous at the seams; q1..q3
    are re-solved at every sample so the TCP position stays on the path. The orientation
    follows the joints and deviates by about the miss angle; the planner reports it.
    """

    name = "wrist-joint"

    def __init__(self, target: str | None = None, widen: float = 1.0) -> None:
        self.target = target  # a configuration label the zone must end in, or None for the nearest
        self.widen = widen  # the blend spans the zone stretched by this factor about its closest point
        self.variant = f"window x{widen:g}"

    def cross(self, ctx: MoveContext, zone: Zone) -> Crossing | None:
        if zone.kind != "wrist":
            return Exact().cross(ctx, zone)  # other kinds: as exact tracking does
        zone = _widened(zone, self.widen)  # the crossing (and its segment) spans the blend
        a, b = _zone_span(ctx, zone)
        if b <= a:
            return None
        u = ctx.tracked.u
        q_exit = _exit_joints(ctx, zone, ctx.tracked.q[a], float(u[b]), self.target, change=False)
        if q_exit is None:
            return None
        return blend_crossing(ctx, zone, self.name, a, float(u[b]), q_exit)


def _other_side(robot: Robot, options: list[np.ndarray], q: np.ndarray, kind: str) -> list[np.ndarray]:
    """The options on the other side of the ``kind`` singularity than ``q`` (the other letter of
    that kind in the configuration label: the sign of its singular distance)."""
    if not options:
        return []
    i = KIND_INDEX[kind]
    sides = distances_batch(robot, np.vstack([q, *options]))[:, i] >= 0  # (1 + M,) as the labels read it
    return [c for c, side in zip(options, sides[1:], strict=True) if side != sides[0]]


def _widened(zone: Zone, factor: float) -> Zone:
    """The zone stretched about its closest point (clipped to the move)."""
    entry = max(0.0, zone.u_closest - factor * (zone.u_closest - zone.u_entry))
    exit_ = min(1.0, zone.u_closest + factor * (zone.u_exit - zone.u_closest))
    return Zone(zone.kind, entry, exit_, zone.u_closest, zone.min_distance, zone.threshold)


def _zone_span(ctx: MoveContext, zone: Zone) -> tuple[int, int]:
    """Tracked sample indices a <= entry and b >= exit of a zone."""
    u = ctx.tracked.u
    a = max(0, int(np.searchsorted(u, zone.u_entry, side="right")) - 1)
    b = min(len(u) - 1, int(np.searchsorted(u, zone.u_exit, side="left")))
    return a, b


def _exit_joints(ctx: MoveContext, zone: Zone, q_entry: np.ndarray, u_b: float,
                 target: str | None, change: bool) -> np.ndarray | None:
    """Exit joints: the target label's branch, else (``change``) the other label of the zone's
    kind, else any branch; the one nearest the entry joints."""
    options = exit_candidates(ctx, u_b)
    if not options:
        return None
    if target is not None:
        labels = labels_from_distances(distances_batch(ctx.robot, np.array(options)))
        wanted = [c for c, label in zip(options, labels, strict=True) if label == target]
    elif change:
        wanted = _other_side(ctx.robot, options, q_entry, zone.kind)
    else:
        wanted = []
    return nearest_candidate(np.array(wanted or options), q_entry)[0]


class Axis:
    """SEEDS 000: interpolate one axis across the zone; the others keep one pose component.

    Wrist zone: A4 interpolated, A1-A3 keep the position exact, A5/A6 minimise the orientation
    error. Shoulder zone: A1 interpolated, A4-A6 keep the orientation exact, A2/A3 minimise the
    position error. Elbow zone: A2 interpolated, A1/A3 minimise the position error (the wrist
    keeps the orientation). The zone ends in the other configuration of its kind (or the
    move's target). The residual of the minimised component is the reported deviation; the
    shoulder and elbow variants leave the path by about the miss distance.
    """

    name = "axis"
    variant = ""
    _SETUP: ClassVar[dict[str, tuple[int, str]]] = {
        "wrist": (3, "position"), "shoulder": (0, "orientation"), "elbow": (1, "orientation")}

    def __init__(self, target: str | None = None) -> None:
        self.target = target

    def cross(self, ctx: MoveContext, zone: Zone) -> Crossing | None:
        a, b = _zone_span(ctx, zone)
        if b <= a:
            return None
        u, q = ctx.tracked.u, ctx.tracked.q
        q_exit = _exit_joints(ctx, zone, q[a], float(u[b]), self.target, change=True)
        if q_exit is None:
            return None
        fixed, exact = self._SETUP[zone.kind]
        slopes = _seam_slopes(ctx, a, float(u[b]), q_exit)
        ends = JointPart("axis", np.array([u[a], u[b]]), np.array([q[a], q_exit]), slopes, fixed, exact)
        part = sample_densely(ctx, ends)
        return Crossing(zone, self.name, part, part.q[-1])


class Ptp:
    """Baseline (SEEDS 004): jump over the zone's singular stretch with a joint-space straight line.

    The jump spans the singular sample: from the last tracked sample before the zone's closest
    point to the first after it, each at least 0.05 deg (0.5 mm at the shoulder) off the
    singularity (the rest of the zone is followed as exact does), so that it is the smallest span
    the IK cannot follow; a near miss is tracked in full first. It lands on the branch nearest its
    start from which the rest of the move can be followed inside the joint limits. It is a PTP
    motion: it starts and ends at rest (:mod:`singplan.planning.orchestration.stops`), as a
    controller runs one, and the TCP leaves the path on it (its speed is held to the move's).
    """

    name = "ptp"
    variant = ""

    def cross(self, ctx: MoveContext, zone: Zone) -> Crossing | None:
        a, b = _zone_span(ctx, zone)
        if b <= a:
            return None
        u, q = ctx.tracked.u, ctx.tracked.q
        # the tracked samples next to the singular point, each clear of it (where the branches meet and
        # joints are free): the smallest span the IK cannot follow, widened only that far
        index = np.arange(len(u))
        clear = (index >= a) & (index <= b) & (np.abs(ctx.distances[:, KIND_INDEX[zone.kind]]) >= _EDGE_MIN[zone.kind])
        before = np.nonzero(clear & (u < zone.u_closest))[0]
        after = np.nonzero(clear & (u > zone.u_closest))[0]
        a = int(before[-1]) if before.size else a
        b = int(after[0]) if after.size else b
        if zone.min_distance >= met_below(ctx, zone) and ctx.tracked.coarse_from_u <= u[b]:
            return None  # a near miss the tracking left coarse: the planner tracks the swing in full and asks again
        options = exit_candidates(ctx, float(u[b]))
        if not options:
            return None
        # the nearest branch from which the rest of the move can be followed inside the joint limits,
        # one that keeps the other kinds' configuration letters first (it jumps over this zone only)
        shifted = [nearest_candidate(np.array([c]), q[a]) for c in options]
        sides = distances_batch(ctx.robot, np.array([q[a]] + [c for c, _ in shifted])) >= 0  # (1 + M, 3)
        others = [k for k in range(3) if k != KIND_INDEX[zone.kind]]
        same = [bool(np.all(row[others] == sides[0, others])) for row in sides[1:]]
        ranked = [c for (c, _), _ in sorted(zip(shifted, same, strict=True), key=lambda cs: (not cs[1], cs[0][1]))]
        q_exit = next((c for c in ranked if _rest_followed(ctx, float(u[b]), c)), ranked[0])
        line = JointPart("ptp", np.array([u[a], u[b]]), np.array([q[a], q_exit]))
        return Crossing(zone, self.name, line, q_exit, stops=True)


def rest_of_move(ctx: MoveContext, u_from: float, q_from: np.ndarray) -> TrackedPath | None:
    """The rest of the move followed with the full pose from ``q_from`` at ``u_from`` (on the tracked
    grid ahead), or None at the move's end."""
    if u_from >= 1.0 - 1e-12:
        return None
    grid = ctx.tracked.u
    inner = grid[(grid > u_from + 1e-12) & (grid < 1.0 - 1e-12)]
    return track(ctx.robot, ctx.piece.poses, np.concatenate([[u_from], inner, [1.0]]), q_from, cands=ctx.branches)


def _rest_followed(ctx: MoveContext, u_from: float, q_from: np.ndarray) -> bool:
    """Whether the rest of the move can be followed from ``q_from`` continuously inside the joint limits."""
    rest = rest_of_move(ctx, u_from, q_from)
    if rest is None:
        return True
    return rest.gap_index < 0 and ctx.robot.within_limits(rest.q)


class Average:
    """Baseline (SEEDS 004): follow the path as ``exact`` does, and replace the joints of each
    singular sample (|distance| under a fifth of the zone's threshold) by the average of its
    neighbours, weighted by where it lies between them (the plain average on a uniform grid).

    The samples are exact's: the tracked branch in full where it keeps the branch (a near miss),
    the samples of its through-crossing where it goes through (a hit). The joints run a smooth
    spline through them, their slopes the path's at the ends; the averaged samples leave the path
    by what the averaging changes, which the planner measures.
    """

    name = "average"
    variant = ""
    _CORE = 0.2  # the "singular samples": |distance| under this fraction of the threshold

    def cross(self, ctx: MoveContext, zone: Zone) -> Crossing | None:
        through_crossing = Exact().cross(ctx, zone)
        if through_crossing is not None:
            part = through_crossing.blend
            u, q, slopes = part.u, part.q.copy(), part.dq_du
            distances = distances_batch(ctx.robot, q)[:, KIND_INDEX[zone.kind]]
        else:
            a, b = _zone_span(ctx, zone)
            if b - a < 2 or ctx.tracked.coarse_from_u <= ctx.tracked.u[b]:
                return None  # kept for now: the planner tracks a coarse zone in full and asks again
            u, q = ctx.tracked.u[a:b + 1], ctx.tracked.q[a:b + 1].copy()
            distances = ctx.distances[a:b + 1, KIND_INDEX[zone.kind]]
            slopes = _seam_slopes(ctx, a, float(u[-1]), q[-1])
        core = np.abs(distances) < self._CORE * zone.threshold
        core[0] = core[-1] = False
        k = np.nonzero(core)[0]
        if k.size:
            t = ((u[k] - u[k - 1]) / (u[k + 1] - u[k - 1]))[:, None]
            q[k] = (1.0 - t) * q[k - 1] + t * q[k + 1]  # from the samples as followed, not as averaged
        return Crossing(zone, self.name, JointPart("spline", u, q, slopes), q[-1])


class Dls:
    """Baseline: damped least squares tracking, one step per sample as a servo loop does.

    ``qd = J^T (J J^T + lambda^2 I)^-1 e`` with the pose error ``e`` to the next path pose
    (lambda = 0.01). Near the singularity the damping trades tracking for bounded joint speed,
    so the tool leaves the path; at the zone exit the motion rejoins the nearest exact
    solution. The joints run a smooth spline through the servo samples; the deviation is
    measured and reported.
    """

    name = "dls"
    variant = ""
    damping = 1e-2

    def cross(self, ctx: MoveContext, zone: Zone) -> Crossing | None:
        a, b = _zone_span(ctx, zone)
        if b <= a:
            return None
        u_all = ctx.tracked.u
        steps = max(2, math.ceil((u_all[b] - u_all[a]) * ctx.piece.length_m / _BLEND_STEP_M))
        u = np.linspace(u_all[a], u_all[b], steps + 1)
        targets = ctx.piece.poses(u)
        q = np.empty((len(u), ctx.robot.n_joints))
        q[0] = ctx.tracked.q[a]
        for k in range(1, len(u)):
            q[k] = self._step(ctx.robot, q[k - 1], targets[k])
        q_exit = _exit_joints(ctx, zone, q[-2], float(u[-1]), None, change=False)
        if q_exit is None:
            return None
        q[-1] = q_exit
        slopes = _seam_slopes(ctx, a, float(u[-1]), q_exit)
        return Crossing(zone, self.name, JointPart("spline", u, q, slopes), q_exit)

    def _step(self, robot: Robot, q: np.ndarray, T_target: np.ndarray) -> np.ndarray:
        return q + ik_numeric.damped_step(robot.jacobian(q), ik_numeric.pose_error(robot, q, T_target), self.damping**2)
