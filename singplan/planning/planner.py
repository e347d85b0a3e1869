"""plan_moves(task) -> PlannedTask: the planning stages of DESIGN.md for one task, orchestrated.

For each move: the Cartesian path (LIN / CIRC) is sampled and tracked by continuous IK,
singular zones are detected on the tracked joints, the crossing method decides what happens
in each zone (:mod:`~singplan.planning.select` keeps the fastest of several candidates), and
the resulting joint map is timed by TOPP-RA and resampled at the controller period. PTP moves
are straight lines in joint space. :func:`singplan.results.plan.plan` stitches the moves into
the trajectory record. ``detect`` is the geometry-only pass of ``singplan check``.
"""

from __future__ import annotations

import math
import time
from collections.abc import Callable
from dataclasses import dataclass, replace
from pathlib import Path

import numpy as np
import pinocchio as pin

from singplan.errors import JointLimitError, PlanningError, SingularityError, UnreachableError
from singplan.kinematics.configuration import classify, distances_batch, labels_from_distances, parse_configuration
from singplan.kinematics.dynamics import TorqueLimit, effort_limits_nm, require_dynamics
from singplan.kinematics.geometry import rpy_deg_to_rotation
from singplan.kinematics.ik.solve import solve_all
from singplan.kinematics.robot import Robot, load_robot
from singplan.kinematics.stopping import path_estimate, ptp_estimate
from singplan.planning.blending import Blend, corners
from singplan.planning.budget import BudgetError, check_task
from singplan.planning.chain import chain_limits, chain_map, chains, describe_chain_point, split
from singplan.planning.crossing import registry
from singplan.planning.crossing.base import Crossing, CrossingMethod, MoveContext
from singplan.planning.crossing.nullspace import time_with_pauses
from singplan.planning.jointmap import JointMap, JointPart
from singplan.planning.path import CartesianPiece, move_target, sample_deviations
from singplan.planning.pieces import move_piece
from singplan.planning.records import PlannedMove, SampleDeviations
from singplan.planning.redundancy import HeldJoint, hold_for_task
from singplan.planning.select import best_of
from singplan.planning.timing import MoveLimits, TimedMove, TimingError, time_move
from singplan.planning.tracking import BranchCandidates, TrackedPath, track
from singplan.planning.weave import path_grid
from singplan.planning.zones import DistanceFunction, Zone, distances_along, find_zones
from singplan.task.load import check_against_robot, load_task
from singplan.task.schema import Move, Task

STEP_M = 0.002  # initial path sampling: at most 2 mm ...
STEP_RAD = math.radians(0.5)  # ... and 0.5 deg of tool rotation between samples
Progress = Callable[[int, int], None]


def load_task_robot(task: Task) -> Robot:
    tool = pin.SE3(rpy_deg_to_rotation(task.tool_rpy_deg), np.asarray(task.tool_xyz, dtype=float))
    robot = load_robot(task.robot, tip=task.tip, tool=tool)
    check_against_robot(task, robot)
    if task.limits.torque_scale is not None:
        require_dynamics(robot)
    return robot.with_acceleration(np.asarray(task.limits.acceleration_rad_s2, dtype=float))


@dataclass(frozen=True)
class PlannedTask:
    """A task planned and timed move by move, before the trajectory record is built (results)."""

    task: Task  # as given (with a method name override applied)
    method: str  # the crossing method asked for: the task's, or the name of the object passed
    full: Robot  # the robot of the task
    robot: Robot  # the chain planned: ``full``, or with ``redundancy`` the 6R chain with one joint held
    held: HeldJoint | None
    moves: tuple[PlannedMove, ...]
    timed: tuple[TimedMove, ...]  # moves joined by fly-by corners were timed together, then split
    planning_s: float  # wall time from the call to the last move timed
    blends: tuple[Blend, ...] = ()  # every corner that asked for a fly-by, with the radius it got


def plan_moves(task: Task | str | Path, method: str | CrossingMethod | None = None,
               progress: Progress | None = None) -> PlannedTask:
    """Plan and time every move of a task (a :class:`Task`, or the path of a YAML file).

    ``method`` overrides the task's crossing method: a registered name, or a method object
    (:class:`~singplan.planning.crossing.base.CrossingMethod`) used on every move.

    Raises:
        InputError: the task is malformed or contradicts the robot (exit code 2).
        PlanningError: the task cannot be executed within the limits and tolerances (exit code 3).
    """
    started = time.perf_counter()
    if not isinstance(task, Task):
        task = load_task(task)
    chosen = None if method is None or isinstance(method, str) else method  # a method object: on every move
    if isinstance(method, str):
        task = task.with_method(method)
    full = load_task_robot(task)
    held = hold_for_task(task, full)  # with `redundancy`, the 6R chain is planned like any 6-joint arm
    robot, arm_task = (held.reduced, held.reduce_task(task)) if held is not None else (full, task)
    q = _start_joints(arm_task, robot)
    allowance = check_task(arm_task, robot, q, STEP_M, STEP_RAD).output_allowance  # before anything large
    T = robot.fk(q)
    planned: list[PlannedMove] = []
    timed: list[TimedMove] = []
    left = allowance - 1  # output samples the remaining moves may add (they share their boundary samples)
    for i, move in enumerate(task.moves):
        methods = registry.candidates(task.singularity.method, move) if chosen is None else [chosen]
        pm, tm = _best_of(robot, arm_task, i, arm_task.moves[i], T, q, methods, left)
        left -= len(tm.q) - 1
        planned.append(pm)
        timed.append(tm)
        q = tm.q[-1]
        T = pm.piece.T_end if pm.piece is not None else robot.fk(q)
        if progress is not None:
            progress(i + 1, len(task.moves))
    blends = corners(robot, [(pm.jmap, pm.piece is not None, pm.limits.tcp_speed_m_s,
                              any(c.pause is not None for c in pm.crossings)) for pm in planned],
                     [m.blend_mm / 1e3 for m in arm_task.moves])
    if any(b.jmap is not None for b in blends.values()):
        timed = _time_chains(planned, timed, blends, task.period_s, allowance)
    return PlannedTask(task, task.singularity.method if chosen is None else chosen.name,
                       full, robot, held, tuple(planned), tuple(timed), time.perf_counter() - started,
                       tuple(blends.values()))


def _time_chains(planned: list[PlannedMove], timed: list[TimedMove], blends: dict[int, Blend], period_s: float,
                 allowance: int) -> list[TimedMove]:
    """Moves joined by flown corners timed in one pass each (the others keep their timing).

    A chain that ends later than its moves stopping at every corner (a jerk limit's uniform
    stretch can cost more than the corners save) keeps the stop-to-stop timing; its corners are
    then reported as not flown, with both durations (``blends`` is updated in place).
    """
    out: list[TimedMove] = []
    for group in chains(planned, blends):
        alone = [timed[i] for i in group]
        if len(group) == 1:
            out.extend(alone)
            continue
        members = [planned[i] for i in group]
        cmap = chain_map(members, blends)
        limits = chain_limits(members, cmap)
        try:
            tm = time_move(cmap, limits, period_s, group[0], allowance)
        except TimingError as exc:
            move, where = describe_chain_point(cmap, members, exc.u)
            raise TimingError(move, exc.u, exc.reason, kind=planned[move].kind, where=where) from exc
        stop_s = sum(t.duration_s for t in alone)
        if tm.duration_s <= stop_s:
            out.extend(split(cmap, tm, limits, period_s))
            continue
        out.extend(alone)
        why = " (the jerk limit's uniform slowing spans the whole chain)" if limits.jerk_rad_s3 is not None else ""
        for i in group[:-1]:
            blends[i] = Blend(i, blends[i].requested_m, 0.0, f"not flown by: moves {group[0]}-{group[-1]} flown "
                                                            f"through take {tm.duration_s:.3f} s, stopping at "
                                                            f"every corner {stop_s:.3f} s{why}")
    return out


def _timed(robot: Robot, pm: PlannedMove, period_s: float, max_samples: int) -> TimedMove:
    """time_move, with a failure's path parameter turned into the point on the move."""
    try:
        if any(c.pause is not None for c in pm.crossings):  # the TCP waits: timed in pieces
            return time_with_pauses(pm.jmap, pm.crossings, pm.limits, period_s, pm.index, max_samples)
        return time_move(pm.jmap, pm.limits, period_s, pm.index, max_samples)
    except TimingError as exc:
        raise TimingError(pm.index, exc.u, exc.reason, kind=pm.kind, where=pm.describe(exc.u)) from exc


def _best_of(robot: Robot, task: Task, i: int, move: Move, T: pin.SE3, q: np.ndarray,
             methods: list[CrossingMethod], max_samples: int) -> tuple[PlannedMove, TimedMove]:
    """Plan, time and check the move with each method; :func:`select.best_of` keeps the fastest.

    The candidates share the move's tracking (:class:`MoveTracking`); a candidate whose joint map
    equals an earlier one's (wrist-joint hands a shoulder zone to exact) takes that one's outcome.
    """
    tracking: list[MoveTracking] = []  # made by the first attempt, inside it (a bad piece fails every method alike)
    outcomes: list[tuple[PlannedMove, TimedMove | PlanningError | BudgetError]] = []

    def attempt(method: CrossingMethod) -> tuple[PlannedMove, TimedMove]:
        if move.kind != "ptp" and not tracking:
            tracking.append(MoveTracking(robot, task, i, move, T))
        pm = _plan_move(robot, task, i, move, T, q, method, tracking[0] if tracking else None)
        same = next(((seen, done) for seen, done in outcomes if _same_motion(seen, pm)), None)
        if same is None:
            try:
                timed = _timed(robot, pm, task.period_s, max_samples)
                _check_config(robot, move, pm, timed)
                pm = replace(pm, deviations=_check_tolerances(robot, task, pm, timed))
                same = (pm, timed)
            except (PlanningError, BudgetError) as exc:
                same = (pm, exc)
            outcomes.append(same)
        seen, outcome = same
        if isinstance(outcome, (PlanningError, BudgetError)):
            raise outcome
        return replace(pm, deviations=seen.deviations), outcome

    return best_of(robot, i, move.kind, methods, attempt)


def _same_motion(a: PlannedMove, b: PlannedMove) -> bool:
    """Whether two plans of one move give the same timing and checks: equal joint maps and zones, no pause."""
    if a.zones != b.zones or len(a.jmap.parts) != len(b.jmap.parts):
        return False
    if any(c.pause is not None for c in (*a.crossings, *b.crossings)):
        return False
    return all(p.kind == r.kind and p.axis == r.axis and p.exact == r.exact and _equal(p.u, r.u)
               and _equal(p.q, r.q) and _equal(p.dq_du, r.dq_du)
               for p, r in zip(a.jmap.parts, b.jmap.parts, strict=True))


def _equal(a: np.ndarray | None, b: np.ndarray | None) -> bool:
    return a is b or (a is not None and b is not None and np.array_equal(a, b))


def _check_tolerances(robot: Robot, task: Task, pm: PlannedMove, tm: TimedMove) -> SampleDeviations | None:
    """A crossing may deviate up to the task's tolerances; more is no plan (exit 3).

    Returns the samples' deviations (None for a PTP move), for the trajectory record to reuse.
    """
    if pm.piece is None:
        return None
    pos, ori = sample_deviations(robot, pm.piece, tm.u, tm.q)
    pos_tol = task.singularity.position_tolerance_mm / 1e3
    ori_tol = math.radians(task.singularity.orientation_tolerance_deg)
    if pos.max(initial=0.0) <= pos_tol and ori.max(initial=0.0) <= ori_tol:
        return SampleDeviations(tm.u, tm.q, pos, ori)
    k = int(np.argmax(np.maximum(pos / pos_tol, ori / ori_tol)))
    zone = min(pm.zones, key=lambda z: abs(z.u_closest - tm.u[k])) if pm.zones else None
    where = f"in the {zone.kind} zone " if zone else ""
    raise SingularityError(
        f"move {pm.index} ({pm.kind}): the crossing {where}deviates {pos[k] * 1e3:.4f} mm / "
        f"{math.degrees(ori[k]):.4f} deg at {pm.piece.describe(float(tm.u[k]))}, over the tolerance "
        f"{task.singularity.position_tolerance_mm:g} mm / {task.singularity.orientation_tolerance_deg:g} deg",
        move=pm.index, kind=zone.kind if zone else "path", s_m=float(tm.u[k]) * pm.piece.length_m)


def _start_joints(task: Task, robot: Robot) -> np.ndarray:
    if task.start_joints_deg is not None:
        return np.radians(np.asarray(task.start_joints_deg, dtype=float))
    assert task.start_pose is not None
    pose = task.start_pose
    T = pin.SE3(rpy_deg_to_rotation(pose.rpy_deg or (0.0, 0.0, 0.0)), np.asarray(pose.xyz, dtype=float))
    sols = solve_all(robot, T, seed=np.zeros(robot.n_joints))
    keep = [k for k, label in enumerate(sols.labels) if task.start_config in (None, label)]
    if not keep:
        wanted = f" in configuration {task.start_config}" if task.start_config else ""
        raise UnreachableError(f"start.pose: no IK solution{wanted} inside the joint limits "
                               f"(xyz {list(pose.xyz)}); available: {sorted(set(sols.labels)) or 'none'}")
    best = min(keep, key=lambda k: float(np.max(np.abs(sols.q[k]))))  # the solution nearest zero
    return np.array(sols.q[best])


def _limits(robot: Robot, task: Task, move: Move, length_m: float) -> MoveLimits:
    scale = task.limits.velocity_scale * (move.velocity_scale if move.kind == "ptp" else 1.0)
    torque = (TorqueLimit(robot, effort_limits_nm(robot) * task.limits.torque_scale)
              if task.limits.torque_scale is not None else None)
    jerk = (np.broadcast_to(np.asarray(task.limits.jerk_rad_s3, dtype=float), (robot.n_joints,)).copy()
            if task.limits.jerk_rad_s3 is not None else None)
    return MoveLimits(robot.velocity_rad_s * scale, robot.acceleration_rad_s2, length_m,
                      move.speed_m_s if move.kind != "ptp" else None, torque, jerk,
                      quintic=move.kind == "ptp" and task.limits.ptp_time_law == "quintic")


def _plan_move(robot: Robot, task: Task, i: int, move: Move, T_start: pin.SE3, q_start: np.ndarray,
               method: CrossingMethod, tracking: MoveTracking | None = None) -> PlannedMove:
    """One move's joint map with ``method``; ``tracking`` shares the tracked stretches among candidates."""
    if move.kind == "ptp":
        q_target = _ptp_target(robot, i, move, q_start)
        part = JointPart("ptp", np.array([0.0, 1.0]), np.array([q_start, q_target]))
        return PlannedMove(i, "ptp", JointMap(robot, None, [part]), _limits(robot, task, move, 0.0))
    tracking = tracking if tracking is not None else MoveTracking(robot, task, i, move, T_start)
    return _plan_cartesian(robot, task, i, move, tracking, q_start, method)


def _ptp_target(robot: Robot, i: int, move: Move, q_start: np.ndarray) -> np.ndarray:
    if move.to_joints_deg is not None:
        return np.radians(np.asarray(move.to_joints_deg, dtype=float))
    target = move_target(move, robot.fk(q_start))
    sols = solve_all(robot, target, seed=q_start)
    keep = [k for k, label in enumerate(sols.labels) if move.config in ("auto", "keep", label)]
    if move.config == "keep":
        keep = [k for k in keep if sols.labels[k] == classify(robot, q_start).label]
    if not keep:
        raise UnreachableError(f"move {i} (ptp): no IK solution for xyz {target.translation.tolist()} inside the joint "
                               f"limits in the requested configuration ({move.config}); available: "
                               f"{sorted(set(sols.labels)) or 'none'}", move=i)
    best = min(keep, key=lambda k: float(np.max(np.abs(sols.q[k] - q_start))))
    return np.array(sols.q[best])


def _plan_cartesian(robot: Robot, task: Task, i: int, move: Move, tracking: MoveTracking, q_start: np.ndarray,
                    method: CrossingMethod) -> PlannedMove:
    """Track the path, let the method handle each zone, and stitch the joint map."""
    piece = tracking.piece
    grid = tracking.grid
    parts: list[JointPart] = []
    zones: list[Zone] = []
    crossings: list[Crossing] = []
    u_from, q_from = 0.0, q_start
    full = False  # track singular zones in full (a method kept one that was left coarse)
    while True:
        stage = tracking.stage(grid, u_from, q_from, full, crossings[-1].zone.kind if crossings else None)
        tracked = stage.ctx.tracked
        # the grid as refined: a re-track after a crossing starts from it (tracked.u starts at u_from)
        grid = np.concatenate([grid[grid < u_from], tracked.u])
        zones_before = list(zones)
        result = _first_crossing(method, stage.ctx, stage.found, zones, u_from)
        if tracked.coarse_from_u < (result.blend.u0 if result is not None else math.inf):
            zones[:], full = zones_before, True  # a kept zone was left coarse: track it in full
            continue
        full = False
        if result is None:
            parts.append(JointPart("track", tracked.u, tracked.q))
            _check_limits(robot, i, move, piece, tracked.u, tracked.q, zones)
            break
        k_a = int(np.searchsorted(tracked.u, result.blend.u0))
        parts.append(JointPart("track", tracked.u[:k_a + 1], tracked.q[:k_a + 1]))
        _check_limits(robot, i, move, piece, tracked.u[:k_a + 1], tracked.q[:k_a + 1], zones)
        for part in result.parts:
            parts.append(part)
            _check_limits(robot, i, move, piece, part.u, part.q, zones)  # every method's crossing
        crossings.append(result)
        u_from, q_from = result.parts[-1].u1, result.q_exit
    return PlannedMove(i, move.kind, JointMap(robot, piece.poses, parts), _limits(robot, task, move, piece.length_m),
                       piece, tuple(zones), tuple(crossings))


@dataclass(frozen=True)
class _Stage:
    """One tracked stretch of a move, from where it starts to the move's end, and the zones along it."""

    ctx: MoveContext  # what a method sees: the tracked joints and their singular distances
    found: tuple[Zone, ...]


class MoveTracking:
    """The tracking of one LIN / CIRC move, shared by the candidate methods that plan it.

    A stretch (IK tracked from a start to the move's end, its singular distances and zones)
    depends only on where it starts, the grid ahead of it, whether held zones are tracked in
    full and which zone kind it continues, never on the method: every candidate starts with the
    same stretch, and candidates whose crossings end alike share the stretch after them too.
    """

    def __init__(self, robot: Robot, task: Task, i: int, move: Move, T_start: pin.SE3) -> None:
        self.robot, self.task, self.index, self.move = robot, task, i, move
        self.piece = move_piece(i, move, T_start)
        self.grid = path_grid(self.piece, STEP_M, STEP_RAD)
        self.thresholds = task.singularity.zone.si()
        self._cands = BranchCandidates(robot, self.piece.poses)  # IK branches per path parameter, solved once
        self._in_zone = _ZoneTest(robot, self.thresholds)
        self._stages: dict[tuple[float, bytes, bool, str | None, bytes], _Stage] = {}

    def stage(self, grid: np.ndarray, u_from: float, q_from: np.ndarray, full: bool,
              continued: str | None) -> _Stage:
        """The stretch from ``q_from`` at ``u_from`` over ``grid``'s points after it (computed once)."""
        ahead = grid[grid > u_from + 1e-12]
        key = (u_from, np.asarray(q_from, dtype=float).tobytes(), full, continued, ahead.tobytes())
        if key not in self._stages:
            self._stages[key] = self._track(np.concatenate([[u_from], ahead]), q_from, full, continued)
        return self._stages[key]

    def _track(self, u: np.ndarray, q_from: np.ndarray, full: bool, continued: str | None) -> _Stage:
        robot, piece, task = self.robot, self.piece, self.task
        # inside singular zones the in-branch swing is resolved only if the method keeps it
        tracked = track(robot, piece.poses, u, q_from, cands=self._cands, hold=None if full else self._in_zone)
        _check_tracked(robot, self.index, self.move, piece, tracked)
        dist = self._in_zone.distances(tracked.q)
        ref = JointMap(robot, piece.poses, [JointPart("track", tracked.u, tracked.q)])
        found = find_zones(tracked.u, dist, self.thresholds, _refiner(robot, ref), continued=continued)
        ctx = MoveContext(robot, self.index, self.move.kind, piece, tracked, dist,
                          task.singularity.position_tolerance_mm / 1e3,
                          math.radians(task.singularity.orientation_tolerance_deg), self.thresholds)
        return _Stage(ctx, tuple(found))


def _first_crossing(method: CrossingMethod, ctx: MoveContext, found: tuple[Zone, ...], zones: list[Zone],
                    u_from: float) -> Crossing | None:
    """Ask the method about each new zone; record zones; return the first crossing it makes."""
    for zone in found:
        if zones and zone.u_entry <= u_from + 1e-12 and zones[-1].kind == zone.kind and u_from > 0:
            zones[-1] = Zone(zone.kind, zones[-1].u_entry, zone.u_exit, zones[-1].u_closest,
                             zones[-1].min_distance, zones[-1].threshold)  # the rest of a crossed zone
            continue
        zones.append(zone)
        crossing = method.cross(ctx, zone)
        if crossing is not None:
            zones[-1] = _spanning(crossing)
            return crossing
    return None


def _spanning(crossing: Crossing) -> Zone:
    """The crossing's zone widened to the joint-map part it replaced.

    A method may start its part before the detected entry (at the tracked sample below it) or end
    it after the exit; every sample of that part is the crossing's, so its segment must cover it.
    """
    z, u0, u1 = crossing.zone, crossing.parts[0].u0, crossing.parts[-1].u1
    return Zone(z.kind, min(z.u_entry, u0), max(z.u_exit, u1), z.u_closest, z.min_distance, z.threshold)


class _ZoneTest:
    """Which joint samples lie in a singular zone of any kind (the tracker's ``hold``).

    Keeps the signed distances of the last samples it was asked about, so the planner reads
    the distances of the tracked path without computing them again (per sample on arms
    without a closed form).
    """

    def __init__(self, robot: Robot, thresholds: np.ndarray) -> None:
        self.robot = robot
        self.thresholds = thresholds
        self._q: np.ndarray | None = None
        self._d = np.empty((0, 3))

    def distances(self, q: np.ndarray) -> np.ndarray:
        """Signed (wrist, shoulder, elbow) distances (N, 3) of joint samples q (N, n)."""
        if q is not self._q:
            self._q, self._d = q, distances_batch(self.robot, q)
        return self._d

    def __call__(self, q: np.ndarray) -> np.ndarray:
        return np.any(np.abs(self.distances(q)) < self.thresholds, axis=1)  # NaN rows compare False


def _refiner(robot: Robot, ref: JointMap) -> DistanceFunction:
    def abs_distance(u: np.ndarray, index: int) -> np.ndarray:
        return np.abs(distances_batch(robot, ref.evaluate(u))[:, index])

    return abs_distance


def _check_tracked(robot: Robot, i: int, move: Move, piece: CartesianPiece, tracked: TrackedPath) -> None:
    if tracked.gap_index < 0:
        return
    k = tracked.gap_index + 1
    u = float(tracked.u[k])
    if not np.all(np.isfinite(tracked.q[k])):
        what = ("no joint values give that position with the path's tool z axis (five joints keep both only "
                "where the axis is within the arm's reach; the z axis turns with the slerp from the start's "
                "orientation to the target's, so a target rotated about its z axis against the start turns it "
                "too: give the target the start's rotation about z)" if robot.n_joints == 5 else
                "no inverse kinematics solution there")
        raise UnreachableError(f"move {i} ({move.kind}): the path leaves the workspace at {piece.describe(u)}: "
                               f"{what}", move=i)
    raise PlanningError(f"move {i} ({move.kind}): no continuous joint motion follows the path at "
                        f"{piece.describe(u)} (the inverse kinematics jumps by "
                        f"{math.degrees(tracked.max_step_rad):.1f} deg)")


def _check_limits(robot: Robot, i: int, move: Move, piece: CartesianPiece, u: np.ndarray, q: np.ndarray,
                  zones: list[Zone]) -> None:
    low = q < robot.lower_rad - 1e-9
    high = q > robot.upper_rad + 1e-9
    if not (low.any() or high.any()):
        return
    k, j = np.argwhere(low | high)[0]
    lo, hi = robot.lower_rad[j], robot.upper_rad[j]
    near = [z for z in zones if z.u_entry - 0.05 <= u[k] <= z.u_exit + 0.05]
    why = (f"; the path passes {near[0].describe_distance()} from a {near[0].kind} singularity and keeping the "
           f"pose swings the joints" if near else "")
    kept = "the position and tool axis" if robot.n_joints == 5 else "the full pose"
    raise JointLimitError(
        f"move {i} ({move.kind}): following the path with {kept} drives {robot.joint_names[j]} to "
        f"{math.degrees(q[k, j]):.2f} deg at {piece.describe(float(u[k]))}, outside its limits "
        f"[{math.degrees(lo):.1f}, {math.degrees(hi):.1f}] deg{why}",
        joint=robot.joint_names[j], value_rad=float(q[k, j]), lower_rad=float(lo), upper_rad=float(hi), move=i)


def _check_config(robot: Robot, move: Move, pm: PlannedMove, tm: TimedMove) -> None:
    if move.config == "auto":
        return
    i = pm.index
    labels = labels_from_distances(distances_batch(robot, tm.q))  # closed form for OPW and UR arms
    first, last = labels[0], labels[-1]
    if move.config == "keep":
        changed = [k for k, label in enumerate(labels) if label != first]
        if changed:
            k = changed[0]
            s_m = float(tm.u[k]) * (pm.piece.length_m if pm.piece is not None else 0.0)
            raise SingularityError(f"move {i} ({move.kind}): config 'keep', but the motion changes the "
                                   f"configuration from {first} to {labels[k]} at {pm.describe(float(tm.u[k]))}",
                                   move=i, kind="config", s_m=s_m)
        return
    wanted = parse_configuration(move.config).label
    if last != wanted:
        raise PlanningError(f"move {i} ({move.kind}): ends in configuration {last} at {pm.describe(1.0)}, "
                            f"but the move asks for {wanted}; the chosen method cannot change the configuration here")


@dataclass(frozen=True)
class MoveZones:
    """Singular zones of one move along the programmed path (``singplan check``)."""

    index: int
    kind: str
    length_m: float
    zones: tuple[Zone, ...]
    stopping: tuple[float, float] = (0.0, 0.0)  # an estimate at the programmed speed [m], and the u where


def detect(task: Task | str | Path) -> list[MoveZones]:
    """Zones along every LIN/CIRC move, in the branch the start configuration leads to.

    Geometry only: no crossing method, no timing, no limit checks; each move's stopping distance is
    an estimate at the programmed speed (:func:`singplan.kinematics.stopping.path_estimate`, ``ptp_estimate``).
    """
    if not isinstance(task, Task):
        task = load_task(task)
    full = load_task_robot(task)
    held = hold_for_task(task, full)
    robot, task = (held.reduced, held.reduce_task(task)) if held is not None else (full, task)
    thresholds = task.singularity.zone.si()
    q = _start_joints(task, robot)
    check_task(task, robot, q, STEP_M, STEP_RAD, timed=False)  # before any path is sampled
    T = robot.fk(q)
    out = []
    vmax = robot.velocity_rad_s * task.limits.velocity_scale
    for i, move in enumerate(task.moves):
        if move.kind == "ptp":
            q_from, q = q, _ptp_target(robot, i, move, q)
            T = robot.fk(q)
            out.append(MoveZones(i, "ptp", 0.0, (), ptp_estimate(robot, q_from, q, vmax * move.velocity_scale)))
            continue
        piece = move_piece(i, move, T)
        grid = path_grid(piece, STEP_M, STEP_RAD)
        tracked = track(robot, piece.poses, grid, q)
        _check_tracked(robot, i, move, piece, tracked)
        dist, _ = distances_along(robot, tracked.q)
        ref = JointMap(robot, piece.poses, [JointPart("track", tracked.u, tracked.q)])
        zones = find_zones(tracked.u, dist, thresholds, _refiner(robot, ref))
        out.append(MoveZones(i, move.kind, piece.length_m, tuple(zones),
                             path_estimate(robot, tracked.u, tracked.q, piece.length_m, move.speed_m_s, vmax)))
        q, T = tracked.q[-1], piece.T_end
    return out
