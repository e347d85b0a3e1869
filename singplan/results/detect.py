"""``detect(task)``: what ``singplan check`` reports, the singular zones along every move and a bound
of the stopping distance, found by the planner's own stages without timing anything.

Each LIN / CIRC is tracked as the planner tracks it (:class:`~singplan.planning.orchestration.move_plan.MoveTracking`:
the same IK following, singular zones held coarse for a crossing method to replace, the same zone
detection), so ``check`` refuses a move (exit 3) only where every method's plan fails as well: the
path leaves the workspace, or the IK jumps outside any singular zone.

The stopping bound covers every plan a crossing method can make: each built-in (and registered)
method's joint map of the move is made as the planner makes it (no timing; the maps the planner
refuses before timing left out: a joint limit, the configuration it ends in, a crossing over the
tolerances, a collision), and each sample gets the fastest joint velocity any timing can
give it: along the path's slope, at the most the joint limits and the programmed TCP speed allow
(:func:`~singplan.kinematics.stopping.path_rates`), no joint faster than it can get from the nearest
point at rest (:func:`~singplan.kinematics.stopping.rest_speed_bounds`). Those states become
distances by the two bounds of :mod:`singplan.kinematics.stopping` (the smaller holds); a fly-by
corner, where the blend adds the two moves' speeds, by the joint-by-joint one. The next move starts
in each branch a method may end in (a few at most), so the bound of a later move covers the
planner's choice too. A move none of whose joint maps is left (from any of those branches) has no
plan, so the task has no bound: its :attr:`MoveZones.no_plan` says why (the planner's own
refusal, :func:`~singplan.planning.orchestration.select.no_plan`), and ``check`` exits 3.

With collision checking on, each move also gets its least clearance along the programmed path in
the branch the start leads to (the tracked path of a LIN / CIRC, the straight joint line of a PTP;
a crossing or a configuration change the planner makes may differ).
"""


from __future__ import annotations

from collections.abc import Iterator
from dataclasses import dataclass
from pathlib import Path
from typing import NamedTuple

import numpy as np

from singplan.errors import PlanningError, SingplanError
from singplan.kinematics.clearance import Clearance, check_clearance
from singplan.kinematics.collision import CollisionModel, FixedContact
from singplan.kinematics.robot import Robot
from singplan.kinematics.stopping import (
    capped_rates,
    path_rates,
    rest_speed_bounds,
    scaled_stopping_bound,
    stopping_bound,
    travel,
)
from singplan.planning.crossing import registry
from singplan.planning.crossing.base import CrossingMethod
from singplan.planning.crossing.methods import Exact, Stop
from singplan.planning.orchestration.budget import check_task
from singplan.planning.orchestration.checks import screen
from singplan.planning.orchestration.collide import line_samples, screen_line
from singplan.planning.orchestration.collide import screen as screen_collision
from singplan.planning.orchestration.move_plan import MoveTracking, plan_cartesian
from singplan.planning.orchestration.records import PlannedMove
from singplan.planning.orchestration.select import Failure, no_plan
from singplan.planning.orchestration.targets import ptp_target, task_arm
from singplan.planning.path.cartesian import STEP_M, STEP_RAD
from singplan.planning.path.zones import Zone
from singplan.task.load import load_task
from singplan.task.schema import AUTO_METHOD, Move, Task

MAX_BRANCHES = 4  # distinct end joints of one move a next move is bounded from
_DENSE_STEP_M = 1e-3  # a joint map's samples for the bound: 1 mm apart along the path ...
_DENSE_SAMPLES = (200, 20_000)  # ... at least and at most this many
_PTP_SAMPLES = 33  # states along a PTP's joint line
_BATCH = 256  # states whose figure is computed at once, the largest joint-by-joint bounds first


class StoppingFigure(NamedTuple):
    """``singplan check``'s stopping distance of one move (see :mod:`singplan.results.detect`)."""

    bound_m: float  # no output sample of any plan of the move stops farther [m]
    at: float  # where the bound is reached: path parameter u (LIN / CIRC) or fraction of the joint motion (PTP)


@dataclass(frozen=True)
class MoveZones:
    """One move as ``singplan check`` reports it: its singular zones along the programmed path (in
    the branch the start configuration leads to) and its stopping-distance bound (None when the
    move has no plan: ``no_plan`` says why)."""

    index: int
    kind: str
    length_m: float
    zones: tuple[Zone, ...]
    stopping: StoppingFigure | None
    clearance: Clearance | None = None  # along the programmed path in the start branch (None: nothing checked)
    u: tuple[float, ...] = ()  # the path parameters of the samples the clearance was checked at
    fixed: tuple[FixedContact, ...] = ()  # cell shapes touching the fixed base (every move alike; planning refuses)
    no_plan: SingplanError | None = None  # why no method's joint map of the move is left (None: some is)

    def where(self, sample: int, fraction: float = 0.0) -> str:
        """A checked sample (and a fraction of the way to the next) as a point of the move, for messages."""
        u = self.u[sample] + fraction * (self.u[min(sample + 1, len(self.u) - 1)] - self.u[sample])
        return f"{u:.2f} of the joint motion" if self.kind == "ptp" else f"s {u * self.length_m * 1e3:.1f} mm"


@dataclass(frozen=True)
class _States:
    """Joint states a move's plans pass through, along one joint path: joints (N, n) [rad], the path's
    slopes dq/ds (N, n) and the most ds/dt (N,) the joint limits and TCP speed allow there, each
    joint's turning since the path's start and until its end (N, n) [rad], where each state is on the
    move (u or PTP fraction, (N,)) and the TCP there (N, 3) [m]. ``paused``: a null-space pause, at
    rest at both ends whatever the move's corners."""

    q: np.ndarray
    slopes: np.ndarray
    rate: np.ndarray
    since: np.ndarray
    until: np.ndarray
    at: np.ndarray
    tcp: np.ndarray
    paused: bool = False

    @classmethod
    def along(cls, robot: Robot, s: np.ndarray, q: np.ndarray, velocity_rad_s: np.ndarray, at: np.ndarray,
              rate_cap: np.ndarray | None = None, paused: bool = False) -> _States:
        """The states of the joint path q(s) (samples s (N,), q (N, n))."""
        slopes, rate = path_rates(s, q, velocity_rad_s, rate_cap)
        turned = travel(q)
        return cls(q, slopes, rate, turned, turned[-1] - turned, at, robot.tcp_positions(q), paused)


def detect(task: Task | str | Path) -> list[MoveZones]:
    """Zones and stopping bounds of every move (a :class:`Task`, or the path of a YAML file).

    A move whose every joint map the planner would refuse before timing (a joint limit, a tolerance,
    a collision) is returned with ``no_plan`` set and no stopping figure, as is every move when one is.

    Raises:
        InputError: the task is malformed or contradicts the robot (exit code 2).
        PlanningError: a move no method can plan: its path leaves the workspace, the IK jumps
            outside the singular zones, or a PTP target has no solution (exit code 3).
    """
    if not isinstance(task, Task):
        task = load_task(task)
    registry.check_name("singularity.method", task.singularity.method)
    arm = task_arm(task)
    robot, task = arm.robot, arm.task
    check_task(task, robot, arm.q_start, STEP_M, STEP_RAD, timed=False)  # before any path is sampled
    starts = [arm.q_start]  # the first: the branch followed by continuity, whose zones are listed
    T = robot.fk(arm.q_start)
    found: list[tuple[float, tuple[Zone, ...]]] = []  # each move's length [m] and zones
    clear: list[tuple[Clearance | None, tuple[float, ...]]] = []  # each move's clearance and where it was checked
    states: list[list[_States]] = []
    refused: list[SingplanError | None] = []  # why each move has no plan (None: it has one)
    for i, move in enumerate(task.moves):
        failures: list[Failure] = []  # why each method's joint map from the first start is refused
        if move.kind == "ptp":
            move_states, ends, failures = _ptp_states(robot, task, i, move, starts, arm.collision)
            found.append((0.0, ()))
            u = np.linspace(0.0, 1.0, line_samples(starts[0], ends[0]))
            clear.append(_clearance(arm.collision, starts[0] + np.outer(u, ends[0] - starts[0]), u, i))
            starts = _distinct(ends)
            T = robot.fk(starts[0])
        else:
            tracking = MoveTracking(robot, task, i, move, T)
            stage = tracking.stage(tracking.grid, 0.0, starts[0], False, None)  # raises: no method plans
            move_states, ends = [], []
            for k, q in enumerate(starts):
                s, e, f = _path_states(robot, task, i, move, tracking, q, arm.collision)
                move_states += s
                ends += e
                failures += f if k == 0 else []
            found.append((tracking.piece.length_m, stage.found))
            clear.append(_clearance(arm.collision, stage.ctx.tracked.q, stage.ctx.tracked.u, i))
            starts = _distinct(ends) or [stage.ctx.tracked.q[-1]]  # no method plans it: on as tracked
            T = tracking.piece.T_end
        states.append(move_states)
        refused.append(None if move_states else no_plan(i, move.kind, failures))
    qd = _velocities(robot, task, states)
    bounded = not any(refused)  # a bound for every plan of the task: none without a plan
    return [MoveZones(i, move.kind, found[i][0], found[i][1],
                      _figure(robot, task, states, qd, i) if bounded else None, *clear[i],
                      arm.collision.fixed_contacts, no_plan=refused[i])
            for i, move in enumerate(task.moves)]


def _clearance(model: CollisionModel, q: np.ndarray, u: np.ndarray, i: int
               ) -> tuple[Clearance | None, tuple[float, ...]]:
    """The least clearance along joint samples q (N, n) at path parameters u (N,), when checking is on."""
    if not model.active:
        return None, ()
    return check_clearance(model, q, start=i == 0), tuple(float(v) for v in u)


def _methods(move: Move) -> Iterator[CrossingMethod]:
    """Every method a plan of the move may use (``stop`` crosses nothing)."""
    for name in registry.names():
        if name not in (AUTO_METHOD, Stop.name):
            yield from registry.candidates(name, move)


def _path_states(robot: Robot, task: Task, i: int, move: Move, tracking: MoveTracking, q_start: np.ndarray,
                 model: CollisionModel) -> tuple[list[_States], list[np.ndarray], list[Failure]]:
    """The states of each method's joint map of a LIN / CIRC from ``q_start`` that the planner
    would time, where each ends, and why each other one is refused (as the planner refuses it before
    timing: planned, screened, collision-checked). Without a singular zone every method keeps the
    tracked path: one of them stands for all."""
    zones = tracking.stage(tracking.grid, 0.0, q_start, False, None).found
    methods = list(_methods(move)) if zones else registry.candidates(Exact.name, move)
    states, ends, failures = [], [], []
    for order, method in enumerate(methods):
        try:
            pm = plan_cartesian(robot, task, i, move, tracking, q_start, method)
            refusal = screen(robot, task, move, pm)[0] or (screen_collision(model, pm) if model.active else None)
        except PlanningError as exc:
            refusal = exc
        if refusal is not None:  # the planner drops it before timing: no plan of it
            failures.append(Failure(order, method.name, method.variant, refusal))
            continue
        states += list(_jmap_states(robot, task, move, pm))
        ends.append(pm.jmap.evaluate(np.array([1.0]))[0])
    return states, ends, failures


def _jmap_states(robot: Robot, task: Task, move: Move, pm: PlannedMove) -> Iterator[_States]:
    """A planned LIN / CIRC's joint map at 1 mm steps (and its reference samples), and the joint
    motion of each null-space pause (the TCP waits, so only the joint limits bound it)."""
    velocity = robot.velocity_rad_s * task.joint_speed_scale(move)
    ref_u, _ = pm.jmap.reference()
    count = int(np.clip(pm.limits.length_m / _DENSE_STEP_M, *_DENSE_SAMPLES))
    u = np.union1d(ref_u, np.linspace(0.0, 1.0, count))
    clock = pm.limits.tcp_clock(u)
    cap = None if clock is None else 1.0 / np.maximum(np.gradient(clock, u), 1e-300)  # du/dt at the TCP speed
    yield _States.along(robot, u, pm.jmap.evaluate(u), velocity, u, cap)
    for crossing in pm.crossings:
        if crossing.pause is not None:
            p = crossing.pause
            yield _States.along(robot, np.arange(float(len(p.q))), p.q, velocity, np.full(len(p.q), p.u), paused=True)


def _ptp_states(robot: Robot, task: Task, i: int, move: Move, starts: list[np.ndarray], model: CollisionModel
                ) -> tuple[list[_States], list[np.ndarray], list[Failure]]:
    """A PTP's joint line from each start that stays clear (the first's target must exist: exit 3
    otherwise), synchronised at its speed scale, the targets (of every start, clear or not), and why the
    first start's line is refused."""
    states, ends, failures = [], [], []
    s = np.linspace(0.0, 1.0, _PTP_SAMPLES)
    velocity = robot.velocity_rad_s * task.joint_speed_scale(move)
    for k, q_from in enumerate(starts):
        try:
            q_to = ptp_target(robot, i, move, q_from)
        except PlanningError:
            if k == 0:
                raise
            continue
        ends.append(q_to)  # the next move goes on from here, clear or not (a collision is reported)
        collision = screen_line(model, q_from, q_to, i) if model.active else None
        if collision is not None:
            failures += [Failure(0, "ptp", "", collision)] if k == 0 else []
            continue
        states.append(_States.along(robot, s, q_from + s[:, None] * (q_to - q_from), velocity, s))
    return states, ends, failures


def _velocities(robot: Robot, task: Task, states: list[list[_States]]) -> list[list[np.ndarray]]:
    """Each state's fastest joint velocities (N, n) [rad/s]: along its path's slopes, at its rate,
    lowered where a joint would pass what it can reach from the nearest point at rest
    (:func:`~singplan.kinematics.stopping.rest_speed_bounds`). A move flown into (or out of) by a corner
    is at rest only where its chain of corners starts (ends): the turning of the moves between
    counts too, the most any of their states turns."""
    turned = [np.max([s.since[-1] for s in move], axis=0) if move else np.zeros(robot.n_joints) for move in states]
    flown = [m.blend_mm > 0 for m in task.moves]
    before, after = [np.zeros(robot.n_joints)], [np.zeros(robot.n_joints)]
    for i in range(1, len(states)):
        before.append(turned[i - 1] + before[-1] if flown[i - 1] else np.zeros(robot.n_joints))
    for i in range(len(states) - 2, -1, -1):
        after.insert(0, turned[i + 1] + after[0] if flown[i] else np.zeros(robot.n_joints))
    acc = task.limits.joint_accelerations(robot.n_joints)
    out = []
    for i, move in enumerate(states):
        qd = []
        for s in move:
            away = np.minimum(s.since, s.until) if s.paused else np.minimum(s.since + before[i], s.until + after[i])
            rate = capped_rates(s.slopes, s.rate, rest_speed_bounds(away, acc, task.period_s))
            qd.append(s.slopes * np.where(np.isfinite(rate), rate, 0.0)[:, None])
        out.append(qd)
    return out


def _figure(robot: Robot, task: Task, states: list[list[_States]], qd: list[list[np.ndarray]],
            i: int) -> StoppingFigure:
    """Move i's bound: the largest over its states, and over the corners it is flown into or out of."""
    figure = StoppingFigure(0.0, 0.0)
    if states[i]:
        q = np.concatenate([s.q for s in states[i]])
        bound, k = _largest_bound(robot, task.limits.joint_accelerations(robot.n_joints), q, np.concatenate(qd[i]))
        figure = StoppingFigure(bound, float(np.concatenate([s.at for s in states[i]])[k]))
    for a in (i - 1, i):
        if 0 <= a < len(states) - 1 and task.moves[a].blend_mm > 0 and states[a] and states[a + 1]:
            corner = _corner_bound(robot, task, a, states, qd)
            if corner > figure.bound_m:
                figure = StoppingFigure(corner, 1.0 if a == i else 0.0)
    return figure


def _largest_bound(robot: Robot, acc: np.ndarray, q: np.ndarray, qd: np.ndarray) -> tuple[float, int]:
    """The largest over states (q, c qd) (N, n), 0 <= c <= 1, of the smaller of the two bounds
    (:func:`~singplan.kinematics.stopping.stopping_bound`, cheap, then
    :func:`~singplan.kinematics.stopping.scaled_stopping_bound` on the states it leaves in the running,
    largest first), and the state where (``acc``: the joint acceleration limits [rad/s^2] (n,))."""
    joint_by_joint = stopping_bound(robot, q, np.abs(qd), acc)
    order = np.argsort(-joint_by_joint)
    best, where = 0.0, int(order[0])
    for c in range(0, len(order), _BATCH):
        rows = order[c:c + _BATCH]
        if joint_by_joint[rows[0]] <= best:
            break
        bound = np.minimum(joint_by_joint[rows], scaled_stopping_bound(robot, q[rows], qd[rows], acc))
        k = int(np.argmax(bound))
        if bound[k] > best:
            best, where = float(bound[k]), int(rows[k])
    return best, where


def _corner_bound(robot: Robot, task: Task, a: int, states: list[list[_States]], qd: list[list[np.ndarray]]) -> float:
    """The bound where moves a and a + 1 overlap at a flown corner (the last and first ``blend_mm`` of
    their TCP paths): the blend superposes the two motions, so a joint moves at up to the sum of both
    sides' speeds there (and its limit), displaced by up to either side's turning in the corner; only
    :func:`~singplan.kinematics.stopping.stopping_bound` holds for such states."""
    radius_m = task.moves[a].blend_mm / 1e3
    sides = []
    for move_states, move_qd, end in ((states[a], qd[a], True), (states[a + 1], qd[a + 1], False)):
        near = [np.linalg.norm(s.tcp - s.tcp[-1 if end else 0], axis=1) <= radius_m for s in move_states]
        sides.append((np.concatenate([s.q[k] for s, k in zip(move_states, near, strict=True)]),
                      np.concatenate([np.abs(v[k]) for v, k in zip(move_qd, near, strict=True)])))
    (q_in, v_in), (q_out, v_out) = sides
    scale = max(task.joint_speed_scale(task.moves[a]), task.joint_speed_scale(task.moves[a + 1]))
    joint_speed = np.minimum(v_in.max(axis=0) + v_out.max(axis=0), robot.velocity_rad_s * scale)
    q = np.concatenate([q_in, q_out])
    moved = np.maximum(np.ptp(q_in, axis=0), np.ptp(q_out, axis=0))
    return float(np.max(stopping_bound(robot, q, np.broadcast_to(joint_speed, q.shape),
                                       task.limits.joint_accelerations(robot.n_joints),
                                       moved)))


def _distinct(rows: list[np.ndarray]) -> list[np.ndarray]:
    """Up to :data:`MAX_BRANCHES` rows, each more than 1e-6 rad from the ones before it (first kept)."""
    kept: list[np.ndarray] = []
    for row in rows:
        if len(kept) < MAX_BRANCHES and all(np.max(np.abs(row - k)) > 1e-6 for k in kept):
            kept.append(row)
    return kept
