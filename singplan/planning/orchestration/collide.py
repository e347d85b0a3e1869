"""Collision checks of planned motion: one move's samples (a candidate), a whole trajectory (the last gate),
and the refusal when the motion is not clear (DESIGN.md, "Collision").

The samples checked are the output samples at the controller period, so a candidate is judged on
exactly what it would put in the trajectory, and the straight joint motion between them.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Sequence

import numpy as np

from singplan.errors import CollisionError
from singplan.kinematics.clearance import Clearance, Contact, check_clearance
from singplan.kinematics.collision import CollisionModel, describe_distance
from singplan.planning.orchestration.records import PlannedMove
from singplan.planning.timing.toppra import TimingPath

NO_FREE_SPACE = "singplan keeps the programmed path and does not plan around obstacles (free-space planning is " \
                "not part of it)"

Describe = Callable[[int], str]  # a move's own sample index -> the point of the move, for messages


def check_move(model: CollisionModel, q: np.ndarray, move: int, kind: str, offset: int, period_s: float,
               describe: Describe | None = None) -> Clearance:
    """A move's output samples q (K+1, n) and the motion between them; ``offset``: the trajectory sample
    the move starts at (0 for the first move, whose first sample is the trajectory's start).

    Raises:
        CollisionError: a pair comes closer than the clearance (the worst place named).
    """
    found = check_clearance(model, q, offset=offset, start=offset == 0, exact=False)
    if not found.clear:
        raise refusal(model, found.contacts[0], move, kind, period_s, describe, offset)
    return found


def screen(model: CollisionModel, pm: PlannedMove, path: TimingPath | None = None) -> CollisionError | None:
    """A move's joint path checked before it is timed: its reference samples (``path``'s when made, the
    joint map's otherwise; a PTP's two ends) and the straight motion between them. Timing only chooses
    where on that path the output samples fall, so a path that collides is out whatever its timing.

    Returns the collision found (its place named on the path; no time yet), or None when the path is clear.
    """
    if pm.jmap.straight:
        q_ends = pm.jmap.evaluate(np.array([0.0, 1.0]))
        u = np.linspace(0.0, 1.0, line_samples(q_ends[0], q_ends[1]))
        q = pm.jmap.evaluate(u)
    else:
        u, q = (path.u, path.q) if path is not None else pm.jmap.reference()
    first = _first_contact(model, q, u)
    if first is None:
        return None
    contact, at = first
    return _untimed(model, contact, pm.index, pm.kind, pm.describe(at))


def _first_contact(model: CollisionModel, q: np.ndarray, u: np.ndarray) -> tuple[Contact, float] | None:
    """The first contact along joint samples q (N, n) at path parameters u (N,) and its path parameter
    (between two samples: interpolated), or None when the motion is clear."""
    found = check_clearance(model, q, exact=False)
    if found.clear:
        return None
    contact = found.contacts[0]
    k = contact.sample
    return contact, float(u[k] + contact.fraction * (u[min(k + 1, len(u) - 1)] - u[k]))


def _untimed(model: CollisionModel, contact: Contact, move: int, kind: str, where: str) -> CollisionError:
    """A contact found before timing (no sample or time yet), named at ``where`` on the move."""
    a, b = contact.bodies
    return CollisionError(f"move {move} ({kind}): {a} and {b} are {describe_distance(contact.distance_m)} "
                          f"at {where}, closer than the clearance {model.clearance_m * 1e3:g} mm",
                          move=move, sample=-1, t_s=math.nan, bodies=(a, b), distance_m=contact.distance_m,
                          clearance_m=model.clearance_m)


def refuse_fixed_contacts(model: CollisionModel) -> None:
    """Refuse a task whose cell touches a robot body no joint moves (the base): every sample of every plan
    would collide, so nothing is planned (DESIGN.md, "Collision": such a pair is allowed by name).

    Raises:
        CollisionError: the closest such pair, with the ``collision.allow`` that leaves it out.
    """
    if not model.fixed_contacts:
        return
    first, *more = model.fixed_contacts
    also = f" ({len(more)} more such pair(s): {', '.join(f'{c.body} / {c.shape}' for c in more)})" if more else ""
    raise CollisionError(f"the cell touches the robot's fixed base before any move: {first.advice(model.clearance_m)}"
                         f"{also}", move=0, sample=0, t_s=0.0, bodies=(first.body, first.shape),
                         distance_m=first.distance_m, clearance_m=model.clearance_m)


LINE_STEP_RAD = 0.03  # a straight joint line is checked at samples this far apart (the largest joint's step)


def line_samples(q_from: np.ndarray, q_to: np.ndarray) -> int:
    """How many samples a straight joint line is checked at (its ends included): a long line as one step
    would be sub-sampled pair by pair, where the samples' bounds prove most of it at once."""
    return 2 + math.ceil(float(np.max(np.abs(np.asarray(q_to) - q_from), initial=0.0)) / LINE_STEP_RAD)


def screen_line(model: CollisionModel, q_from: np.ndarray, q_to: np.ndarray, move: int) -> CollisionError | None:
    """A PTP's straight joint line checked before it is timed (every timing keeps to that line)."""
    n = line_samples(q_from, q_to)
    first = _first_contact(model, np.linspace(q_from, q_to, n), np.linspace(0.0, 1.0, n))
    if first is None:
        return None
    contact, at = first
    return _untimed(model, contact, move, "ptp", f"{at:.3f} of the joint motion")


def check_trajectory(model: CollisionModel, q: np.ndarray, spans: Sequence[tuple[int, int]], kinds: Sequence[str],
                     period_s: float) -> Clearance:
    """The last gate: every sample of a trajectory (N, n) and the motion between them, the closest
    approach of each move (``spans``: each move's first and last sample).

    Raises:
        CollisionError: a pair comes closer than the clearance (the worst place, and its move, named).
    """
    found = check_clearance(model, q, spans, start=True)
    if not found.clear:
        contact = found.contacts[0]
        move = next(m for m, (k0, k1) in enumerate(spans) if k0 <= contact.sample <= k1
                    and (contact.fraction == 0.0 or contact.sample < k1))
        raise refusal(model, contact, move, kinds[move], period_s)
    return found


def refusal(model: CollisionModel, contact: Contact, move: int, kind: str, period_s: float,
            describe: Describe | None = None, offset: int = 0) -> CollisionError:
    """The error for a motion that is not clear: move, time, sample, the two bodies and their distance."""
    a, b = contact.bodies
    t_s = (contact.sample + contact.fraction) * period_s
    if contact.between:
        where = f"between samples {contact.sample} and {contact.sample + 1} (t = {t_s:.4f} s)"
    else:
        where = f"at t = {t_s:.4f} s (sample {contact.sample})"
    at = f" at {describe(contact.sample - offset)}" if describe is not None else ""
    allowed = model.clearance_m * 1e3
    return CollisionError(
        f"move {move} ({kind}): {a} and {b} are {describe_distance(contact.distance_m)} {where}{at}, closer than "
        f"the clearance {allowed:g} mm; {NO_FREE_SPACE}", move=move, sample=contact.sample, t_s=t_s,
        bodies=(a, b), distance_m=contact.distance_m, clearance_m=model.clearance_m)
