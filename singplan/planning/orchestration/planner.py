"""plan_moves(task) -> PlannedTask: the planning stages of DESIGN.md for one task, orchestrated.

For each move: the Cartesian path (LIN / CIRC) is sampled and tracked by continuous IK,
singular zones are detected on the tracked joints, the crossing method decides what happens
in each zone (:mod:`~singplan.planning.orchestration.select` keeps the fastest of several candidates), and
the resulting joint map is timed by TOPP-RA and resampled at the controller period. PTP moves
are straight lines in joint space. :func:`singplan.results.plan.plan` stitches the moves into
the trajectory record. Orchestration only: one move's joint map is :mod:`.move_plan`'s, the
validators are :mod:`.checks`', the IK of targets :mod:`.targets`', fly-by corners
:mod:`.blending` and :mod:`.chain`'s; the geometry-only pass of ``singplan check`` is :mod:`.detect`.
"""

from __future__ import annotations

import time
from collections.abc import Callable, Iterable, Sequence
from dataclasses import dataclass, replace
from pathlib import Path
from typing import Protocol

import numpy as np
import pinocchio as pin

from singplan.errors import BudgetError, CollisionError, PlanningError
from singplan.kinematics.clearance import check_clearance
from singplan.kinematics.collision import CollisionModel, describe_distance
from singplan.kinematics.configuration import classify
from singplan.kinematics.held import HeldJoint
from singplan.kinematics.robot import Robot
from singplan.planning.crossing import registry
from singplan.planning.crossing.base import CrossingMethod
from singplan.planning.orchestration import collide
from singplan.planning.orchestration.blending import RAMPS, Blend, CrossingMemo, corners, side_of, stopped
from singplan.planning.orchestration.budget import check_task
from singplan.planning.orchestration.chain import chain_limits, chain_map, chains, describe_chain_point, split, starved
from singplan.planning.orchestration.checks import check_config, check_samples, screen
from singplan.planning.orchestration.move_plan import MoveTracking, plan_move
from singplan.planning.orchestration.records import PlannedMove
from singplan.planning.orchestration.rows import RowStore
from singplan.planning.orchestration.select import Candidate, Rank, Refused, best_of, forget_tracebacks
from singplan.planning.orchestration.stops import stops, time_in_pieces
from singplan.planning.orchestration.targets import move_limits, ptp_targets, task_arm
from singplan.planning.path.cartesian import STEP_M, STEP_RAD
from singplan.planning.timing.bound import duration_bound_s
from singplan.planning.timing.move import time_move
from singplan.planning.timing.records import GiveUp, LimitScale, MoveLimits, Outrun, TimedMove, TimingError
from singplan.planning.timing.toppra import TimingPath, timing_path
from singplan.task.load import load_task
from singplan.task.schema import Move, Task

Progress = Callable[[int, int], None]


class MoveSink(Protocol):
    """What takes each move once it is decided (planned, timed, its fly-by corner settled), in order
    (the trajectory record's parts of it: :class:`singplan.results.build.MoveReports`); the planner then
    keeps only what the trajectory's final gate needs of the move (:meth:`PlannedMove.for_messages`)."""

    def take(self, pm: PlannedMove, tm: TimedMove, nxt: PlannedMove | None, blend: Blend | None) -> None:
        """Move ``pm`` timed as ``tm``; ``nxt``: the move after it (None for the last), ``blend``: its
        flown fly-by corner into ``nxt`` (None where it ends at rest)."""
        ...


# Given the chain planned and the task as planned: the sink its moves are handed to
SinkFor = Callable[[Robot, Task], MoveSink]


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
    q: np.ndarray  # (K, n) every move's samples in one array, a shared boundary sample once; each ``timed`` q a view
    planning_s: float  # wall time from the call to the last move timed
    collision: CollisionModel  # the bodies and pairs checked (``robot``'s)
    blends: tuple[Blend, ...] = ()  # every corner that asked for a fly-by, with the radius it got
    # the sink every move was handed to (``moves`` then hold what the final gate's messages need of
    # them, each ``timed`` q a view of ``q``); None: the moves whole
    sink: MoveSink | None = None


def plan_moves(task: Task | str | Path, method: str | CrossingMethod | None = None,
               progress: Progress | None = None, sink_for: SinkFor | None = None) -> PlannedTask:
    """Plan and time every move of a task (a :class:`Task`, or the path of a YAML file).

    ``method`` overrides the task's crossing method: a registered name, or a method object
    (:class:`~singplan.planning.crossing.base.CrossingMethod`) used on every move. ``sink_for``: the
    sink each move is handed to once decided: as it is planned where no corner asks for a fly-by (a
    long program then keeps no planned move whole: its memory is what the sink keeps), after the
    corners otherwise (their ramp is chosen over the whole program).

    Raises:
        InputError: the task is malformed or contradicts the robot (exit code 2).
        PlanningError: the task cannot be executed within the limits and tolerances (exit code 3).
    """
    started = time.perf_counter()
    if not isinstance(task, Task):
        task = load_task(task)
    registry.check_name("singularity.method", task.singularity.method)
    chosen = None if method is None or isinstance(method, str) else method  # a method object: on every move
    if isinstance(method, str):
        task = task.with_method(registry.check_name("method", method))  # an unknown name is the caller's argument
    arm = task_arm(task)
    robot, arm_task, q = arm.robot, arm.task, arm.q_start
    allowance = check_task(arm_task, robot, q, STEP_M, STEP_RAD).output_allowance  # before anything large
    collide.refuse_fixed_contacts(arm.collision)  # no plan can be clear of it
    T = robot.fk(q)
    planned: list[PlannedMove] = []
    timed: list[TimedMove] = []
    left = allowance - 1  # output samples the remaining moves may add (they share their boundary samples)
    requested_m = [m.blend_mm / 1e3 for m in arm_task.moves]  # each corner's fly-by radius asked for
    flies = any(r > 0 for r in requested_m[:-1])  # a corner asks for a fly-by: _fly_by evaluates the maps
    store = _SampleStore(robot.n_joints)
    sink = sink_for(robot, arm_task) if sink_for is not None else None
    for i, move in enumerate(task.moves):
        methods = registry.candidates(task.singularity.method, move) if chosen is None else [chosen]
        place = _Place(arm.collision, allowance - 1 - left)
        if move.kind == "ptp" and move.to_joints_deg is None and place.collision.active:
            pm, tm = _best_end(robot, arm_task, i, arm_task.moves[i], T, q, methods, left, place)
        else:
            pm, tm = _best_of(robot, arm_task, i, arm_task.moves[i], T, q, methods, left, place)
        left -= len(tm.q) - 1
        pm.jmap.release()  # its timing is done: a fly-by or a message that evaluates it makes them again
        q = tm.q[-1]
        T = pm.piece.T_end if pm.piece is not None else robot.fk(q)
        pm, tm = store.kept(pm if flies else pm.without_joint_map(), tm)
        if sink is not None and not flies:
            sink.take(pm, tm, None, None)  # a move not flown needs neither its successor nor a corner
            pm = pm.for_messages()
        planned.append(pm)
        timed.append(tm)
        if progress is not None:
            progress(i + 1, len(task.moves))
    timed, blends = _fly_by(robot, planned, timed, requested_m, task.period_s, allowance, arm.collision) if flies \
        else (timed, {})
    q_all, planned, timed = _stitched(planned, timed)
    if sink is not None:
        if flies:
            hand_over(sink, planned, timed, blends.values())
        timed = _views(q_all, timed)  # no move's own samples are needed any more
    return PlannedTask(task, task.singularity.method if chosen is None else chosen.name,
                       arm.full, robot, arm.held, tuple(planned), tuple(timed), q_all, time.perf_counter() - started,
                       arm.collision, tuple(blends.values()), sink)


def hand_over(sink: MoveSink, planned: list[PlannedMove], timed: Sequence[TimedMove], blends: Iterable[Blend]) -> None:
    """Each move handed to ``sink`` in order, with the move after it and its flown corner (``blends``:
    every corner that asked for one); ``planned`` is consumed: each move is replaced by what the final
    gate's messages need of it (:meth:`PlannedMove.for_messages`) once taken, freeing the rest."""
    flown = {b.move: b for b in blends if b.jmap is not None}
    for i, (pm, tm) in enumerate(zip(planned, timed, strict=True)):
        sink.take(pm, tm, planned[i + 1] if i + 1 < len(planned) else None, flown.get(pm.index))
        planned[i] = pm.for_messages()


def _views(q_all: np.ndarray, timed: list[TimedMove]) -> list[TimedMove]:
    """The moves with their samples views of the stitched samples ``q_all`` (K, n)."""
    out = []
    k0 = 0
    for tm in timed:
        out.append(replace(tm, q=q_all[k0:k0 + len(tm.q)]))
        k0 += len(tm.q) - 1
    return out


class _SampleStore:
    """The chosen moves' samples and their path parameters, copied into blocks (:class:`RowStore`) as
    the moves are planned: a long program keeps no array of its own per move."""

    def __init__(self, n: int) -> None:
        self.q = RowStore((n,))
        self.u = RowStore()

    def kept(self, pm: PlannedMove, tm: TimedMove) -> tuple[PlannedMove, TimedMove]:
        """The move with its samples and their path parameters (and those its deviations were measured
        on, the same arrays) views of their copies in the blocks."""
        q, u = self.q.kept(tm.q), self.u.kept(tm.u)
        if pm.deviations is not None and pm.deviations.q is tm.q and pm.deviations.u is tm.u:
            pm = replace(pm, deviations=replace(pm.deviations, q=q, u=u))
        return pm, replace(tm, q=q, u=u)


def _stitched(planned: list[PlannedMove], timed: list[TimedMove]
              ) -> tuple[np.ndarray, list[PlannedMove], list[TimedMove]]:
    """Every move's samples in one array (K, n) (a move starts at the sample its predecessor ends at),
    and the moves with their samples (and the samples their deviations were measured on) as views of
    it: a long program's samples held once, by the trajectory record, not again move by move.

    A LIN / CIRC whose samples a fly-by timed again keeps its own array: the record measures its
    deviations on it, and numpy's kernels may round differently on a view at another memory
    alignment (the figures must stay those of the samples as timed). Its old deviations are dropped."""
    q_all = np.concatenate([timed[0].q] + [tm.q[1:] for tm in timed[1:]])
    moves, samples = [], []
    k0 = 0
    for pm, tm in zip(planned, timed, strict=True):
        view = q_all[k0:k0 + len(tm.q)]
        measured = pm.deviations.of(tm.u, tm.q) if pm.deviations is not None else None
        moves.append(replace(pm, deviations=None if measured is None else replace(measured, q=view)))
        samples.append(replace(tm, q=view) if measured is not None or pm.piece is None else tm)
        k0 += len(tm.q) - 1
    return q_all, moves, samples


def _fly_by(robot: Robot, planned: list[PlannedMove], timed: list[TimedMove], requested_m: list[float],
            period_s: float, allowance: int, collision: CollisionModel) -> tuple[list[TimedMove], dict[int, Blend]]:
    """The fly-by corners, and the moves timed through them: with each ramp shape of
    :func:`~singplan.planning.blending.ramps` (the quartic's smooth seams win on some corners, the
    quadratic's tighter curve on others), the one whose program ends sooner kept."""
    sides = [side_of(robot, pm.jmap, pm.piece is not None, pm.limits.tcp_speed_m_s) for pm in planned]
    at_rest = [_at_rest(pm) for pm in planned]
    best: tuple[float, list[TimedMove], dict[int, Blend]] | None = None
    memo = CrossingMemo()  # where the moves cross each corner's sphere: the same for every ramp
    for ramp in RAMPS:
        blends = corners(robot, sides, at_rest, requested_m, ramp, memo)
        if not any(b.jmap is not None for b in blends.values()):
            return timed, blends  # nothing flown: the ramp makes no difference
        flown = _time_chains(planned, timed, blends, period_s, allowance, collision)
        total_s = sum(tm.duration_s for tm in flown)
        if best is None or total_s < best[0]:
            best = (total_s, flown, blends)
    assert best is not None
    return best[1], best[2]


def _at_rest(pm: PlannedMove) -> str:
    """Why a move must start and end at rest ("" when it need not)."""
    if any(c.pause is not None for c in pm.crossings):
        return "pauses on its path (a null-space crossing starts and ends at rest)"
    if stops(pm.crossings):
        return "jumps over a zone with a PTP motion, which starts and ends at rest"
    if pm.limits.quintic:
        return "is timed by the quintic PTP law, which runs from rest to rest"
    return ""


def _time_chains(planned: list[PlannedMove], timed: list[TimedMove], blends: dict[int, Blend], period_s: float,
                 allowance: int, collision: CollisionModel) -> list[TimedMove]:
    """Moves joined by flown corners timed in one pass each (the others keep their timing);
    ``blends`` is updated in place where a corner is stopped at after all (:func:`_time_chain`)."""
    out: list[TimedMove] = []
    for group in chains(planned, blends):
        out.extend(_time_chain(planned, timed, blends, group, period_s, allowance, collision))
    return out


def _time_chain(planned: list[PlannedMove], timed: list[TimedMove], blends: dict[int, Blend], group: list[int],
                period_s: float, allowance: int, collision: CollisionModel) -> list[TimedMove]:
    """One chain timed in one pass. Where a move between two corners gets no sample of its own
    path, the corner into it is stopped at, and so is a corner with no sample inside (:func:`starved`);
    where the chain ends later than its moves stopping at
    every corner (a jerk limit's uniform stretch spans the whole chain), its middle corner is; where
    the flown motion is not clear of collisions, the corner nearest the contact is (each move stopping
    at its corners was clear); either way each part is timed again, and the corner's reason reported."""
    if len(group) == 1:
        return [timed[group[0]]]
    members = [planned[i] for i in group]
    cmap = chain_map(members, blends)
    limits = chain_limits(members, cmap)
    try:
        tm = time_move(cmap, limits, period_s, group[0], allowance)
    except TimingError as exc:
        move, where = describe_chain_point(cmap, members, exc.u)
        raise TimingError(move, exc.u, exc.reason, kind=planned[move].kind, where=where) from exc
    stop_s = sum(timed[i].duration_s for i in group)
    short = starved(cmap, tm)
    if short is None and tm.duration_s <= stop_s:
        parts = split(cmap, tm, limits, period_s)
        blocked = _blocked_corner(collision, group, parts, period_s) if collision.active else None
        if blocked is None:
            return parts
        cut, reason = blocked
    elif short is not None:
        cut, reason = group.index(short[0]) + 1, short[1]
    else:
        cut = len(group) // 2
        why = " (the jerk limit's uniform slowing spans the whole chain)" if limits.jerk_rad_s3 is not None else ""
        reason = (f"moves {group[0]}-{group[-1]} flown through take {tm.duration_s:.3f} s, stopping at every corner "
                  f"{stop_s:.3f} s{why}: stopped here and the parts timed apart")
    blends[group[cut - 1]] = stopped(blends[group[cut - 1]], reason)
    return (_time_chain(planned, timed, blends, group[:cut], period_s, allowance, collision)
            + _time_chain(planned, timed, blends, group[cut:], period_s, allowance, collision))


def _blocked_corner(collision: CollisionModel, group: list[int], parts: list[TimedMove],
                    period_s: float) -> tuple[int, str] | None:
    """Where a flown chain is not clear: the place in ``group`` after the corner nearest the first contact
    found, and why it is stopped at; None when the chain's samples and the motion between them are clear."""
    q = np.concatenate([parts[0].q] + [tm.q[1:] for tm in parts[1:]])
    found = check_clearance(collision, q, exact=False)
    if found.clear:
        return None
    contact = found.contacts[0]
    ends = np.cumsum([len(tm.q) - 1 for tm in parts])  # each move's last sample in the chain
    corners = [(int(ends[m]) if parts[m].blend_from is None else int(ends[m] - len(parts[m].q) + 1
                                                                      + parts[m].blend_from), m)
               for m in range(len(parts) - 1)]  # where each corner starts, and its incoming move
    _, m = min(corners, key=lambda corner: abs(corner[0] - contact.sample))
    a, b = contact.bodies
    return m + 1, (f"flown by, {a} and {b} would be {describe_distance(contact.distance_m)}, closer than the "
                   f"clearance {collision.clearance_m * 1e3:g} mm: stopped here")


def _timed(pm: PlannedMove, period_s: float, max_samples: int, path: TimingPath | None = None,
           give_up: GiveUp | None = None) -> TimedMove | Outrun:
    """time_move (``path``: the joint map's timing path, where made; ``give_up``: see there, the
    timing then may stop with an :class:`Outrun`), a failure located on the move."""
    try:
        if stops(pm.crossings):  # the TCP waits or jumps: timed in pieces
            return time_in_pieces(pm.jmap, pm.crossings, pm.limits, period_s, pm.index, max_samples)
        return time_move(pm.jmap, pm.limits, period_s, pm.index, max_samples, path, give_up)
    except TimingError as exc:
        raise _located(pm, exc) from exc


def _timing_path(pm: PlannedMove) -> TimingPath:
    try:
        return timing_path(pm.jmap, pm.limits, pm.index)
    except TimingError as exc:
        raise _located(pm, exc) from exc


def _located(pm: PlannedMove, exc: TimingError) -> TimingError:
    """The error with its path parameter turned into the point on the move."""
    return TimingError(pm.index, exc.u, exc.reason, kind=pm.kind, where=pm.describe(exc.u))


@dataclass(frozen=True)
class _Place:
    """Where a move's candidates are checked for collisions: the bodies, and the trajectory sample the move
    starts at (its samples' times in messages; the first move's first sample starts the trajectory)."""

    collision: CollisionModel
    offset: int


def _best_of(robot: Robot, task: Task, i: int, move: Move, T: pin.SE3, q: np.ndarray,
             methods: list[CrossingMethod], max_samples: int, place: _Place,
             q_target: np.ndarray | None = None) -> tuple[PlannedMove, TimedMove]:
    """Plan each method's joint map, then time and check the candidates that can still win;
    :func:`select.best_of` keeps the fastest. ``q_target``: a PTP's end joints (default: the preferred)."""
    candidates = _MoveCandidates(robot, task, i, move, T, q, len(methods), max_samples, place, q_target)
    best = best_of(robot, i, move.kind, methods, candidates.prepare, candidates.finish,
                   task.singularity.deviation_cost_percent / 100.0)
    forget_tracebacks(outcome for _, outcome in candidates.outcomes if isinstance(outcome, Exception))
    return best


def _best_end(robot: Robot, task: Task, i: int, move: Move, T: pin.SE3, q: np.ndarray,
              methods: list[CrossingMethod], max_samples: int, place: _Place) -> tuple[PlannedMove, TimedMove]:
    """A PTP to a pose with collision checking on: the preferred end configuration (the nearest,
    :func:`~singplan.planning.targets.ptp_targets`) where its joint line is clear, else the fastest clear
    one of the others the move's ``config`` allows. Each line is checked before it is timed
    (:func:`~singplan.planning.collide.screen_line`), the others fastest bound first
    (:func:`ptp_duration_bound_s`), and none is timed whose bound cannot beat the fastest clear one.

    Raises:
        CollisionError: no end configuration is clear (the nearest's collision with its time and sample,
            each other's reason).
    """
    targets = ptp_targets(robot, i, move, q)
    blocked = collide.screen_line(place.collision, q, targets[0], i)
    if blocked is None:
        return _best_of(robot, task, i, move, T, q, methods, max_samples, place, targets[0])
    limits = move_limits(robot, task, move, 0.0)
    refused: list[tuple[np.ndarray, PlanningError | BudgetError]] = []
    best: tuple[PlannedMove, TimedMove] | None = None
    bounded = sorted(((ptp_duration_bound_s(q, target, limits), k) for k, target in enumerate(targets[1:], 1)))
    for bound_s, k in bounded:  # (a tie in the bound: the target listed first, as a stable sort did)
        target = targets[k]
        if best is not None and bound_s >= best[1].duration_s:
            break  # neither this nor a later one can be faster (a tie: the nearer end, tried first)
        error: PlanningError | BudgetError | None = collide.screen_line(place.collision, q, target, i)
        if error is None:
            try:
                found = _best_of(robot, task, i, move, T, q, methods, max_samples, place, target)
            except (PlanningError, BudgetError) as exc:
                error = exc
            else:
                if best is None or found[1].duration_s < best[1].duration_s:
                    best = found
                continue
        refused.append((target, error))
    if best is not None:
        forget_tracebacks(error for _, error in refused)  # listed by their messages, never raised now
        return best
    pm, tm = _best_of(robot, task, i, move, T, q, methods, max_samples, place, targets[0])
    reasons = "; ".join(f"{classify(robot, target).label}: {_reason(error)}" for target, error in refused)
    try:
        collide.check_move(place.collision, tm.q, i, "ptp", place.offset, task.period_s,
                           lambda k: pm.describe(float(tm.u[k])))
    except CollisionError as first:
        message = f"{first} (no end configuration of the pose is clear: {reasons})" if reasons else str(first)
        raise CollisionError(message, first.move, first.sample, first.t_s, first.bodies, first.distance_m,
                             first.clearance_m) from first
    raise blocked  # its output samples clear where its line is not (within the line's sub-sampling)


def ptp_duration_bound_s(q_from: np.ndarray, q_to: np.ndarray, limits: MoveLimits) -> float:
    """No timing of the straight joint motion q_from -> q_to ends sooner [s]: each joint alone needs at
    least its rest-to-rest time at its own speed and acceleration limits (bang-bang, or bang-coast-bang)."""
    d = np.abs(np.asarray(q_to, dtype=float) - q_from)
    v, a = limits.velocity_rad_s, limits.acceleration_rad_s2
    triangle = d <= v * v / a
    return float(np.max(np.where(triangle, 2.0 * np.sqrt(d / a), d / v + v / a)))


def _reason(error: Exception) -> str:
    """An error's message without its move prefix and the free-space note (listed after the first's)."""
    text = str(error).split("): ", 1)[-1]
    return text.split("; singplan keeps", 1)[0]


class _MoveCandidates:
    """One move's candidate plans: each method's joint map (sharing the move's tracking,
    :class:`MoveTracking`), its timing path, bound and refusal, then its timing and checks. A
    candidate whose joint map equals an earlier one's (wrist-joint hands a shoulder zone to exact)
    takes that one's timing path, bound, refusal and outcome."""

    def __init__(self, robot: Robot, task: Task, i: int, move: Move, T: pin.SE3, q: np.ndarray, count: int,
                 max_samples: int, place: _Place, q_target: np.ndarray | None = None) -> None:
        self.robot, self.task, self.index, self.move, self.T, self.q = robot, task, i, move, T, q
        self.place, self.q_target = place, q_target
        self.compared = count > 1  # one candidate alone needs no bound or refusal
        self.max_samples = max_samples
        self.tracking: MoveTracking | None = None  # made by the first candidate (a bad piece fails every method alike)
        self.prepared: list[Candidate] = []
        self.outcomes: list[tuple[PlannedMove, TimedMove | PlanningError | BudgetError]] = []

    def prepare(self, method: CrossingMethod, order: int) -> Candidate:
        """The method's joint map, with what lets it be skipped before timing."""
        if self.move.kind != "ptp" and self.tracking is None:
            self.tracking = MoveTracking(self.robot, self.task, self.index, self.move, self.T)
        pm = plan_move(self.robot, self.task, self.index, self.move, self.T, self.q, method, self.tracking,
                       self.q_target)
        same = next((c for c in self.prepared if _same_motion(c.pm, pm)), None)
        if same is not None:
            return replace(same, method=method, order=order, pm=pm)
        path = None if stops(pm.crossings) else _timing_path(pm)
        if not self.compared:
            return Candidate(method, order, pm, path)
        bound_s = 0.0 if path is None else duration_bound_s(path, pm.limits, self.task.period_s)
        why_not, deviation = screen(self.robot, self.task, self.move, pm)
        self.prepared.append(Candidate(method, order, pm, path, bound_s, why_not, screened=True, deviation=deviation))
        return self.prepared[-1]

    def finish(self, c: Candidate, best: Rank | None) -> tuple[PlannedMove, TimedMove] | Outrun:
        """The candidate timed and checked, or the :class:`Outrun` of a timing that stopped once it
        could not beat ``best`` (not kept: another candidate of the same motion is timed afresh)."""
        same = next(((seen, done) for seen, done in self.outcomes if _same_motion(seen, c.pm)), None)
        if same is None:
            found = self._timed_and_checked(c, best)
            if isinstance(found, Outrun):
                return found
            same = found
            self.outcomes.append(same)
        seen, outcome = same
        if isinstance(outcome, (PlanningError, BudgetError)):
            raise outcome
        return replace(c.pm, deviations=seen.deviations), outcome

    def _timed_and_checked(self, c: Candidate, best: Rank | None
                           ) -> tuple[PlannedMove, TimedMove | PlanningError | BudgetError] | Outrun:
        period_s = self.task.period_s
        cost = self.task.singularity.deviation_cost_percent / 100.0
        give_up = None if best is None or c.path is None else _cannot_beat(c, c.path, best, period_s, cost)
        collision = self.place.collision
        if collision.active and len(self.prepared) > 1 and c.refusal is None and self.move.kind != "ptp":
            error = collide.screen(collision, c.pm, c.path)  # before timing: a joint path that collides is out
            if error is not None:
                raise Refused(error)
        try:
            timed = _timed(c.pm, period_s, self.max_samples, c.path, give_up)
            if isinstance(timed, Outrun):
                return timed
            check_config(self.robot, self.move, c.pm, timed.u, timed.q)
            deviations = check_samples(self.robot, self.task, c.pm, timed, c.screened)
            if collision.active and c.refusal is not None:  # refused, timed for the full error
                collide.check_move(collision, timed.q, self.index, c.pm.kind, self.place.offset, period_s,
                                   lambda k: c.pm.describe(float(timed.u[k])))
            return replace(c.pm, deviations=deviations), timed
        except (PlanningError, BudgetError) as exc:
            return c.pm, exc


def _cannot_beat(c: Candidate, path: TimingPath, best: Rank, period_s: float, cost: float) -> GiveUp:
    """After a timing pass: the bound at the tightened limits, if it shows ``c`` cannot beat ``best``."""
    def give_up(scale: LimitScale, pass_s: float) -> float | None:
        bound_s = duration_bound_s(path, c.pm.limits, period_s, scale, pass_s)
        return bound_s if c.rank(bound_s, cost) > best else None

    return give_up


def _same_motion(a: PlannedMove, b: PlannedMove) -> bool:
    """Whether two plans of one move give the same timing and checks: equal joint maps and zones, no pause."""
    if a.zones != b.zones or len(a.jmap.parts) != len(b.jmap.parts):
        return False
    if stops(a.crossings) or stops(b.crossings):
        return False
    return all(p.kind == r.kind and p.axis == r.axis and p.exact == r.exact and _equal(p.u, r.u)
               and _equal(p.q, r.q) and _equal(p.dq_du, r.dq_du)
               for p, r in zip(a.jmap.parts, b.jmap.parts, strict=True))


def _equal(a: np.ndarray | None, b: np.ndarray | None) -> bool:
    return a is b or (a is not None and b is not None and np.array_equal(a, b))
