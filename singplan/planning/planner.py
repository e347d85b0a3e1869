"""plan_moves(task) -> PlannedTask: the planning stages of DESIGN.md for one task, orchestrated.

For each move: the Cartesian path (LIN / CIRC) is sampled and tracked by continuous IK,
singular zones are detected on the tracked joints, the crossing method decides what happens
in each zone (:mod:`~singplan.planning.select` keeps the fastest of several candidates), and
the resulting joint map is timed by TOPP-RA and resampled at the controller period. PTP moves
are straight lines in joint space. :func:`singplan.results.plan.plan` stitches the moves into
the trajectory record. Orchestration only: one move's joint map is :mod:`~singplan.planning.move_plan`'s,
the validators are :mod:`~singplan.planning.checks`', the IK of targets :mod:`~singplan.planning.targets`',
fly-by corners :mod:`~singplan.planning.blending` and :mod:`~singplan.planning.chain`'s; the
geometry-only pass of ``singplan check`` is :mod:`~singplan.planning.detect`.
"""

from __future__ import annotations

import time
from collections.abc import Callable
from dataclasses import dataclass, replace
from pathlib import Path

import numpy as np
import pinocchio as pin

from singplan.errors import PlanningError
from singplan.kinematics.robot import Robot
from singplan.planning.blending import RAMPS, Blend, corners, side_of, stopped
from singplan.planning.bound import duration_bound_s
from singplan.planning.budget import BudgetError, check_task
from singplan.planning.chain import chain_limits, chain_map, chains, describe_chain_point, split, starved
from singplan.planning.checks import check_config, check_samples, screen
from singplan.planning.crossing import registry
from singplan.planning.crossing.base import CrossingMethod
from singplan.planning.move_plan import MoveTracking, plan_move
from singplan.planning.path import STEP_M, STEP_RAD
from singplan.planning.records import PlannedMove
from singplan.planning.redundancy import HeldJoint
from singplan.planning.select import Candidate, Rank, best_of
from singplan.planning.stops import stops, time_in_pieces
from singplan.planning.targets import task_arm
from singplan.planning.timing import GiveUp, Scale, TimedMove, TimingError, TimingPath, time_move, timing_path
from singplan.task.load import load_task
from singplan.task.schema import Move, Task

Progress = Callable[[int, int], None]


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
        task = task.with_method(method, given_as="method")  # an unknown name is the caller's argument
    arm = task_arm(task)
    robot, arm_task, q = arm.robot, arm.task, arm.q_start
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
    timed, blends = _fly_by(robot, planned, timed, [m.blend_mm / 1e3 for m in arm_task.moves], task.period_s,
                            allowance)
    return PlannedTask(task, task.singularity.method if chosen is None else chosen.name,
                       arm.full, robot, arm.held, tuple(planned), tuple(timed), time.perf_counter() - started,
                       tuple(blends.values()))


def _fly_by(robot: Robot, planned: list[PlannedMove], timed: list[TimedMove], requested_m: list[float],
            period_s: float, allowance: int) -> tuple[list[TimedMove], dict[int, Blend]]:
    """The fly-by corners, and the moves timed through them: with each ramp shape of
    :func:`~singplan.planning.blending.ramps` (the quartic's smooth seams win on some corners, the
    quadratic's tighter curve on others), the one whose program ends sooner kept."""
    sides = [side_of(robot, pm.jmap, pm.piece is not None, pm.limits.tcp_speed_m_s) for pm in planned]
    at_rest = [_at_rest(pm) for pm in planned]
    best: tuple[float, list[TimedMove], dict[int, Blend]] | None = None
    for ramp in RAMPS:
        blends = corners(robot, sides, at_rest, requested_m, ramp)
        if not any(b.jmap is not None for b in blends.values()):
            return timed, blends  # nothing flown: the ramp makes no difference
        flown = _time_chains(planned, timed, blends, period_s, allowance)
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
                 allowance: int) -> list[TimedMove]:
    """Moves joined by flown corners timed in one pass each (the others keep their timing);
    ``blends`` is updated in place where a corner is stopped at after all (:func:`_time_chain`)."""
    out: list[TimedMove] = []
    for group in chains(planned, blends):
        out.extend(_time_chain(planned, timed, blends, group, period_s, allowance))
    return out


def _time_chain(planned: list[PlannedMove], timed: list[TimedMove], blends: dict[int, Blend], group: list[int],
                period_s: float, allowance: int) -> list[TimedMove]:
    """One chain timed in one pass. Where a move between two corners gets no sample of its own
    path, the corner into it is stopped at, and so is a corner with no sample inside (:func:`starved`);
    where the chain ends later than its moves stopping at
    every corner (a jerk limit's uniform stretch spans the whole chain), its middle corner is;
    either way each part is timed again, and the corner's reason reported."""
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
        return split(cmap, tm, limits, period_s)
    if short is not None:
        cut, reason = group.index(short[0]) + 1, short[1]
    else:
        cut = len(group) // 2
        why = " (the jerk limit's uniform slowing spans the whole chain)" if limits.jerk_rad_s3 is not None else ""
        reason = (f"moves {group[0]}-{group[-1]} flown through take {tm.duration_s:.3f} s, stopping at every corner "
                  f"{stop_s:.3f} s{why}: stopped here and the parts timed apart")
    blends[group[cut - 1]] = stopped(blends[group[cut - 1]], reason)
    return (_time_chain(planned, timed, blends, group[:cut], period_s, allowance)
            + _time_chain(planned, timed, blends, group[cut:], period_s, allowance))


def _timed(pm: PlannedMove, period_s: float, max_samples: int, path: TimingPath | None = None,
           give_up: GiveUp | None = None) -> TimedMove:
    """time_move (``path``: the joint map's timing path, where made; ``give_up``: see there), a
    failure located on the move."""
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


def _best_of(robot: Robot, task: Task, i: int, move: Move, T: pin.SE3, q: np.ndarray,
             methods: list[CrossingMethod], max_samples: int) -> tuple[PlannedMove, TimedMove]:
    """Plan each method's joint map, then time and check the candidates that can still win;
    :func:`select.best_of` keeps the fastest."""
    candidates = _MoveCandidates(robot, task, i, move, T, q, len(methods), max_samples)
    return best_of(robot, i, move.kind, methods, candidates.prepare, candidates.finish,
                   task.singularity.deviation_cost_percent / 100.0)


class _MoveCandidates:
    """One move's candidate plans: each method's joint map (sharing the move's tracking,
    :class:`MoveTracking`), its timing path, bound and refusal, then its timing and checks. A
    candidate whose joint map equals an earlier one's (wrist-joint hands a shoulder zone to exact)
    takes that one's timing path, bound, refusal and outcome."""

    def __init__(self, robot: Robot, task: Task, i: int, move: Move, T: pin.SE3, q: np.ndarray, count: int,
                 max_samples: int) -> None:
        self.robot, self.task, self.index, self.move, self.T, self.q = robot, task, i, move, T, q
        self.compared = count > 1  # one candidate alone needs no bound or refusal
        self.max_samples = max_samples
        self.tracking: MoveTracking | None = None  # made by the first candidate (a bad piece fails every method alike)
        self.prepared: list[Candidate] = []
        self.outcomes: list[tuple[PlannedMove, TimedMove | PlanningError | BudgetError]] = []

    def prepare(self, method: CrossingMethod, order: int) -> Candidate:
        """The method's joint map, with what lets it be skipped before timing."""
        if self.move.kind != "ptp" and self.tracking is None:
            self.tracking = MoveTracking(self.robot, self.task, self.index, self.move, self.T)
        pm = plan_move(self.robot, self.task, self.index, self.move, self.T, self.q, method, self.tracking)
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

    def finish(self, c: Candidate, best: Rank | None) -> tuple[PlannedMove, TimedMove]:
        """The candidate timed and checked (timing.Outrun once it cannot beat ``best``)."""
        same = next(((seen, done) for seen, done in self.outcomes if _same_motion(seen, c.pm)), None)
        if same is None:
            same = self._timed_and_checked(c, best)
            self.outcomes.append(same)
        seen, outcome = same
        if isinstance(outcome, (PlanningError, BudgetError)):
            raise outcome
        return replace(c.pm, deviations=seen.deviations), outcome

    def _timed_and_checked(self, c: Candidate, best: Rank | None
                           ) -> tuple[PlannedMove, TimedMove | PlanningError | BudgetError]:
        period_s = self.task.period_s
        cost = self.task.singularity.deviation_cost_percent / 100.0
        give_up = None if best is None or c.path is None else _cannot_beat(c, c.path, best, period_s, cost)
        try:
            timed = _timed(c.pm, period_s, self.max_samples, c.path, give_up)
            check_config(self.robot, self.move, c.pm, timed.u, timed.q)
            return replace(c.pm, deviations=check_samples(self.robot, self.task, c.pm, timed, c.screened)), timed
        except (PlanningError, BudgetError) as exc:
            return c.pm, exc


def _cannot_beat(c: Candidate, path: TimingPath, best: Rank, period_s: float, cost: float) -> GiveUp:
    """After a timing pass: the bound at the tightened limits, if it shows ``c`` cannot beat ``best``."""
    def give_up(scale: Scale, pass_s: float) -> float | None:
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
