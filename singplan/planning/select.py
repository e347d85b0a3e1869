"""auto and multi-variant methods: try each candidate method on a move, keep the fastest.

A candidate that fails (a limit, a tolerance, the move's size budget) is listed with its reason;
a method this arm's family cannot use is never run in disguise: it is listed as infeasible with
the reason, and asked for alone it is refused where the move meets a zone.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import replace

from singplan.errors import PlanningError, SingularityError, UnreachableError
from singplan.kinematics.robot import Robot
from singplan.planning.alternatives import Alternative
from singplan.planning.budget import BudgetError
from singplan.planning.crossing.base import CrossingMethod
from singplan.planning.crossing.methods import Exact
from singplan.planning.records import PlannedMove
from singplan.planning.timing import TimedMove

Attempt = Callable[[CrossingMethod], tuple[PlannedMove, TimedMove]]  # plan, time and check one move


def best_of(robot: Robot, i: int, kind: str, methods: list[CrossingMethod],
            attempt: Attempt) -> tuple[PlannedMove, TimedMove]:
    """Plan and time the move with each method; keep the fastest within the tolerances.

    A method this arm's family cannot use is never run in disguise: it is listed as infeasible
    with the reason, and asked for alone it is refused where the move meets a zone.
    """
    results: list[tuple[PlannedMove, TimedMove]] = []
    failures: list[tuple[str, PlanningError | BudgetError]] = []
    serving, refused = _serving(robot, methods)
    for method in serving or [Exact()]:  # with nothing to cross, any method gives exact's motion
        if results and not results[0][0].zones:
            break  # nothing to cross: every method gives this same motion
        try:
            pm, tm = attempt(method)
        except (PlanningError, BudgetError) as exc:  # a slow method over the allowance: another may fit
            failures.append((method.name, exc))
            continue
        results.append((replace(pm, method=method.name, variant=method.variant), tm))
    if not serving and results and results[0][0].zones:
        raise _refusal(robot, results[0][0], refused)
    failures += [(name, PlanningError(f"{name} {why} (this arm is {robot.family})")) for name, why in refused.items()]
    if not results:
        decisive: list[PlanningError | BudgetError] = [
            exc for _, exc in failures if isinstance(exc, (UnreachableError, BudgetError))]
        if len(failures) == 1 or decisive or len({str(exc) for _, exc in failures}) == 1:
            # the path itself fails, or the task is too large, or every method met the same wall: no method can help
            raise (decisive or [failures[0][1]])[0]
        raise PlanningError(f"move {i} ({kind}): no method could plan it: "
                            + "; ".join(f"{name}: {exc}" for name, exc in failures))
    results.sort(key=lambda r: r[1].duration_s)
    alternatives = tuple([Alternative(r[0].method, True, r[0].variant, r[1].duration_s) for r in results]
                         + [Alternative(name, False, reason=str(exc)) for name, exc in failures])
    best_pm, best_tm = results[0]
    return replace(best_pm, alternatives=alternatives if len(methods) > 1 else ()), best_tm


def _serving(robot: Robot, methods: list[CrossingMethod]) -> tuple[list[CrossingMethod], dict[str, str]]:
    """The methods that can serve this arm's family, and why each other one cannot (by name)."""
    notes = robot.recognition.crossing_methods()
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
