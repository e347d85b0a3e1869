"""What auto compared on a move (:class:`Alternative`) and how far a candidate leaves the pose
(:class:`Deviation`). Imports nothing heavy: the trajectory record and the pages use them without
loading the planner."""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass
from typing import Any, NamedTuple


class Deviation(NamedTuple):
    """How far a candidate's crossings leave the programmed pose (on their own joints, known before
    timing), and the share of the task's tolerance that is: the larger of position / its tolerance
    and orientation / its tolerance (0 .. 1). auto counts it (``singularity.deviation_cost_percent``)."""

    position_mm: float
    orientation_deg: float
    share: float


NO_DEVIATION = Deviation(0.0, 0.0, 0.0)


@dataclass(frozen=True)
class Alternative:
    """One method auto (or a multi-variant method) tried on a move.

    Attributes:
        method: the method's name.
        feasible: it planned the move within the limits and tolerances; None: not timed, because
            no timing of its joint map could end sooner than the chosen one's (``at_least_s``).
        variant: which of the method's variants (e.g. the wrist-joint blend window), "" for none.
        duration_s: the move's duration with it [s] (feasible ones).
        reason: why it could not plan the move (infeasible ones), or why it was not timed.
        at_least_s: the lower bound on its duration that ruled it out [s] (those not timed).
        position_mm, orientation_deg: how far its crossings leave the pose (:class:`Deviation`;
            feasible ones and those not timed; None for infeasible ones).
    """

    method: str
    feasible: bool | None
    variant: str = ""
    duration_s: float | None = None
    reason: str = ""
    at_least_s: float | None = None
    position_mm: float | None = None
    orientation_deg: float | None = None

    def to_json(self) -> dict[str, Any]:
        """Its trajectory.json mapping (inside a crossing's ``alternatives``): the keys its verdict has."""
        out: dict[str, Any] = {"method": self.method, "variant": self.variant}
        if self.feasible is False:
            return {**out, "feasible": False, "reason": self.reason}
        deviation = {"position_mm": self.position_mm, "orientation_deg": self.orientation_deg}
        if self.feasible:
            return {**out, "duration_s": self.duration_s, "feasible": True, **deviation}
        return {**out, "feasible": None, "at_least_s": self.at_least_s, "reason": self.reason, **deviation}

    @classmethod
    def from_json(cls, doc: Mapping[str, Any]) -> Alternative:
        """The inverse of :meth:`to_json` (a checked trajectory.json's mapping)."""
        def number(key: str) -> float | None:
            return None if doc.get(key) is None else float(doc[key])

        feasible = doc["feasible"]
        return cls(str(doc["method"]), None if feasible is None else bool(feasible), str(doc.get("variant", "")),
                   number("duration_s"), str(doc.get("reason", "")), number("at_least_s"), number("position_mm"),
                   number("orientation_deg"))
