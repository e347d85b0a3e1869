"""Collision checks of planned motion: one move's samples (a candidate), a whole trajectory (the last gate),
and the refusal when the motion is not clear (DESIGN.md, "Collision").

The samples checked are the output samples at the controller period, so a candidate is judged on
exactly what it would put in the trajectory, and the straight joint motion between them.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence

import numpy as np

from singplan.errors import CollisionError
from singplan.kinematics.clearance import Clearance, Contact, check_clearance
from singplan.kinematics.collision import CollisionModel, describe_distance

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
