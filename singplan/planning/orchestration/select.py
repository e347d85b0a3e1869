"""auto and multi-variant methods: try each candidate method on a move, keep the fastest.

A candidate that fails (a limit, a tolerance, the move's size budget) is listed with its reason;
a method this arm's family cannot use is never run in disguise: it is listed as infeasible with
the reason, and asked for alone it is refused where the move meets a zone.

Every candidate's joint map is planned first and bounded (:mod:`~singplan.planning.timing.bound`: no
timing of it can end sooner); they are then timed and checked fastest bound first, and one whose
bound cannot beat the best duration found so far is not timed at all, or no further than the
timing pass whose tightened limits show it (:class:`~singplan.planning.timing.records.Outrun`). Ties
go to the method asked for first, as if every candidate had been timed: the choice is the same, only the losers'
durations are replaced by their bounds.
"""

from __future__ import annotations

import logging
from collections.abc import Callable, Iterable, Sequence
from dataclasses import dataclass, replace
from functools import partial
from typing import NamedTuple, TypeVar

from singplan.errors import BudgetError, MethodError, PlanningError, SingplanError, SingularityError, UnreachableError
from singplan.kinematics.robot import Robot
from singplan.planning.crossing import registry
from singplan.planning.crossing.base import CrossingMethod
from singplan.planning.crossing.methods import Exact
from singplan.planning.orchestration.alternatives import NO_DEVIATION, Alternative, Deviation
from singplan.planning.orchestration.records import PlannedMove
from singplan.planning.timing.records import Outrun, TimedMove
from singplan.planning.timing.toppra import TimingPath


@dataclass(frozen=True)
class Candidate:
    """One method's plan of a move, before it is timed.

    Attributes:
        method: the method.
        order: its place among the methods asked for (a tie goes to the earlier).
        pm: its joint map and what was found along it.
        path: TOPP-RA's path of the joint map, made once for the bound and the timing (None: a move
            that stops on its path, a null-space pause or a PTP jump, timed in pieces).
        bound_s: no timing of the joint map ends sooner [s] (0: no bound known).
        refusal: a failure certain before timing (the configuration the joint map ends in); the
            candidate is timed only if no other one plans the move, so that the error is the full one.
        screened: ``refusal`` was looked for (and the crossings' own joints found within the
            tolerances where it is None): the checks after timing need not look again.
        outrun: its timing stopped at a pass whose tightened limits gave ``bound_s``.
        deviation: how far its crossings leave the pose, on their own joints (known before timing).
    """

    method: CrossingMethod
    order: int
    pm: PlannedMove
    path: TimingPath | None = None
    bound_s: float = 0.0
    refusal: PlanningError | None = None
    screened: bool = False
    outrun: bool = False
    deviation: Deviation = NO_DEVIATION

    def rank(self, duration_s: float, cost: float) -> Rank:
        """Where the candidate stands with this duration (or a bound on it) [s], its deviation counted
        at ``cost`` (auto's rule: the fraction of the move's time a whole tolerance costs)."""
        return Rank(duration_s * (1.0 + cost * self.deviation.share), self.order)


class Rank(NamedTuple):
    """Where a candidate stands: a shorter duration wins (its deviation counted, :meth:`Candidate.rank`),
    a tie goes to the method asked for first."""

    counted_s: float  # its duration, or a bound on it, with its deviation counted [s]
    order: int  # its place among the methods asked for


class _Result(NamedTuple):
    pm: PlannedMove
    tm: TimedMove
    candidate: Candidate


class Failure(NamedTuple):
    """Why one method (variant) could not plan a move."""

    order: int
    method: str
    variant: str
    error: PlanningError | BudgetError


class Refused(Exception):  # noqa: N818 - a candidate's outcome, not an error of the program
    """Raised by a :data:`Finish` before timing: the candidate cannot be kept whatever its timing (its
    joint path collides). It is tried again, timed, only if no other candidate plans the move, so that
    the error then is the full one (time and sample)."""

    def __init__(self, error: PlanningError) -> None:
        super().__init__(str(error))
        self.error = error


logger = logging.getLogger(__name__)
Prepare = Callable[[CrossingMethod, int], Candidate]  # plan one method's joint map and bound its duration
# time and check a candidate; it may stop (an Outrun) once it cannot beat the best so far
Finish = Callable[[Candidate, Rank | None], tuple[PlannedMove, TimedMove] | Outrun]


def best_of(robot: Robot, i: int, kind: str, methods: list[CrossingMethod], prepare: Prepare,
            finish: Finish, cost: float = 0.0) -> tuple[PlannedMove, TimedMove]:
    """Plan the move with each method; keep the fastest within the tolerances, each candidate's
    deviation counted at ``cost`` (``singularity.deviation_cost_percent`` / 100: a candidate whose
    crossings use their whole tolerance counts as that fraction slower; 0: the fastest).

    A method this arm's family cannot use is never run in disguise: it is listed as infeasible
    with the reason, and asked for alone it is refused where the move meets a zone.
    """
    serving, refused = _serving(robot, methods)
    candidates, failures = _prepared(i, kind, serving or [Exact()], prepare)  # nothing serves: exact's, if no zone
    results, skipped, timing_failures = _timed_best_first(i, kind, candidates, finish, cost)
    if not serving and results and results[0].pm.zones:
        raise _refusal(robot, results[0].pm, refused)
    failures = sorted(failures + timing_failures, key=lambda f: f.order)
    failures += [Failure(len(methods), name, "", PlanningError(f"{name} {why} (this arm is {robot.family})"))
                 for name, why in refused.items()]
    if not results:
        raise no_plan(i, kind, failures)
    results.sort(key=lambda r: r.candidate.rank(r.tm.duration_s, cost))
    best = results[0]
    best_rank = best.candidate.rank(best.tm.duration_s, cost)
    alternatives = tuple([Alternative(r.pm.method, True, r.pm.variant, r.tm.duration_s,
                                      position_mm=r.candidate.deviation.position_mm,
                                      orientation_deg=r.candidate.deviation.orientation_deg) for r in results]
                         + [_untimed(c, best.tm.duration_s, best_rank, cost) for c in skipped if c.refusal is None]
                         + [Alternative(f.method, False, f.variant, reason=str(f.error)) for f in failures]
                         + [Alternative(c.method.name, False, c.method.variant, reason=str(c.refusal)) for c in skipped
                            if c.refusal is not None])
    forget_tracebacks(f.error for f in failures)  # listed by their messages, never raised now
    return replace(best.pm, alternatives=alternatives if len(methods) > 1 else ()), best.tm


def _prepared(i: int, kind: str, methods: list[CrossingMethod], prepare: Prepare
              ) -> tuple[list[Candidate], list[Failure]]:
    """Each method's candidate, or why it could not plan the joint map."""
    candidates: list[Candidate] = []
    failures: list[Failure] = []
    for order, method in enumerate(methods):
        try:
            candidate = isolated(i, kind, method, partial(prepare, method, order))
        except (PlanningError, BudgetError) as exc:  # a slow method over the allowance: another may fit
            failures.append(Failure(order, method.name, method.variant, exc))
            continue
        candidates.append(candidate)
        if not candidate.pm.zones:
            break  # nothing to cross: every method gives this same motion
    return candidates, failures


def _timed_best_first(i: int, kind: str, candidates: list[Candidate], finish: Finish, cost: float
                      ) -> tuple[list[_Result], list[Candidate], list[Failure]]:
    """Time and check the candidates best bound first (deviation counted), skipping those that cannot win."""
    results: list[_Result] = []
    skipped: list[Candidate] = []
    failures: list[Failure] = []
    deferred: list[Candidate] = []  # refused before timing (Refused): timed only if nothing else plans
    best: Rank | None = None
    order = sorted(candidates, key=lambda c: (c.refusal is not None, c.rank(c.bound_s, cost)))
    while order:
        c = order.pop(0)
        if best is not None and (c.refusal is not None or c.rank(c.bound_s, cost) > best):
            skipped.append(c)
            continue
        try:
            done = isolated(i, kind, c.method, partial(finish, c, best))
        except Refused as refused:
            deferred.append(replace(c, refusal=refused.error))
            if not order and best is None:  # nothing else planned: time them for their full errors
                order, deferred = deferred, []
            continue
        except (PlanningError, BudgetError) as exc:
            failures.append(Failure(c.order, c.method.name, c.method.variant, exc))
            continue
        if isinstance(done, Outrun):  # a timing pass tightened its limits past what could win
            skipped.append(replace(c, bound_s=done.at_least_s, outrun=True))
            continue
        pm, tm = done
        results.append(_Result(replace(pm, method=c.method.name, variant=c.method.variant), tm, c))
        best = min(best or c.rank(tm.duration_s, cost), c.rank(tm.duration_s, cost))
    skipped += deferred
    return results, sorted(skipped, key=lambda c: c.rank(c.bound_s, cost)), failures


def forget_tracebacks(errors: Iterable[BaseException]) -> None:
    """Drop the tracebacks of errors kept as values once none of them will be raised (their messages
    are what is reported), and their causes'. A traceback holds the frames it passed through, and they
    hold the move's candidates (joint maps, TOPP-RA splines) in a reference cycle that only Python's
    cyclic collector frees, late: on a program of a thousand moves, tens of MB at a time."""
    todo, seen = list(errors), set()
    while todo:
        exc = todo.pop()
        if id(exc) not in seen:
            seen.add(id(exc))
            exc.__traceback__ = None
            todo += [e for e in (exc.__cause__, exc.__context__) if e is not None]


T = TypeVar("T")


def isolated(i: int, kind: str, method: CrossingMethod, work: Callable[[], T]) -> T:
    """``work()`` (one method's planning or timing of move ``i``), a failure inside its own
    computation (not a SingplanError: a solver that did not converge, a numerical error) turned into
    :class:`~singplan.errors.MethodError`, so that one method cannot take the others down (exit 1).
    The traceback is logged (debug level) for a report."""
    try:
        return work()
    except (SingplanError, BudgetError, Refused, MemoryError):
        raise
    except Exception as exc:
        logger.debug("move %d: method %s failed", i, method.name, exc_info=True)
        cause = f"{type(exc).__name__}: {exc}"
        raise MethodError(f"move {i} ({kind}): method {method.name} failed in its own computation ({cause})",
                            move=i, method=method.name, cause=cause) from exc


def _untimed(c: Candidate, best_s: float, best: Rank, cost: float) -> Alternative:
    how = "timing stopped after a pass: at its tightened limits" if c.outrun else "not timed:"
    tie = " (a tie goes to the method listed first)" if c.rank(c.bound_s, cost).counted_s == best.counted_s else ""
    counted = ""
    if cost > 0.0 and (c.deviation.share > 0.0 or best.counted_s != best_s):
        counted = (f" (with the deviations counted: at least {c.rank(c.bound_s, cost).counted_s:.3f} s against "
                   f"{best.counted_s:.3f} s)")
    return Alternative(c.method.name, None, c.method.variant, at_least_s=c.bound_s,
                       reason=f"{how} no timing of its joint map ends before {c.bound_s:.3f} s, and the "
                              f"chosen method's move takes {best_s:.3f} s{counted}{tie}",
                       position_mm=c.deviation.position_mm, orientation_deg=c.deviation.orientation_deg)


def no_plan(i: int, kind: str, failures: Sequence[Failure]) -> PlanningError | BudgetError:
    """The error when no method plans the move: the path's own or the task's size when that is why,
    or the one wall every method met, else each distinct reason once, after the methods (and
    variants: ``wrist-joint (window x1.5)``) that met it."""
    decisive: list[PlanningError | BudgetError] = [
        f.error for f in failures if isinstance(f.error, (UnreachableError, BudgetError))]
    if len(failures) == 1 or decisive or len({str(f.error) for f in failures}) == 1:
        return (decisive or [failures[0].error])[0]
    prefix = f"move {i} ({kind}): "
    met: dict[str, list[Failure]] = {}  # each reason, without the move named again, and who met it
    for f in failures:
        met.setdefault(str(f.error).removeprefix(prefix), []).append(f)
    return PlanningError(prefix + "no method could plan it: "
                         + "; ".join(f"{_named(who)}: {reason}" for reason, who in met.items()))


def _named(failures: list[Failure]) -> str:
    """The methods of some failures, in order, each once with its variants: ``exact, wrist-joint (window x1,
    window x1.5)``."""
    variants: dict[str, list[str]] = {}
    for f in failures:
        variants.setdefault(f.method, []).extend([f.variant] if f.variant else [])
    return ", ".join(f"{name} ({', '.join(v)})" if v else name for name, v in variants.items())


def _serving(robot: Robot, methods: list[CrossingMethod]) -> tuple[list[CrossingMethod], dict[str, str]]:
    """The methods that can serve this arm's family, and why each other one cannot (by name)."""
    notes = registry.refusals(robot.recognition)
    return ([m for m in methods if not notes.get(m.name)],
            {m.name: notes[m.name] for m in methods if notes.get(m.name)})


def _refusal(robot: Robot, pm: PlannedMove, refused: dict[str, str]) -> SingularityError:
    """The error for a move that meets a zone with only methods this arm cannot use."""
    zone = pm.zones[0]
    name, why = next(iter(refused.items()))
    where = pm.piece.describe(zone.u_closest) if pm.piece is not None else "its start"
    return SingularityError(f"move {pm.index} ({pm.kind}): {name} cannot cross the {zone.kind} zone at {where}: "
                            f"it {why} (this arm is {robot.family}); use exact or auto",
                            move=pm.index, kind=zone.kind, s_m=zone.u_closest * pm.limits.length_m)
