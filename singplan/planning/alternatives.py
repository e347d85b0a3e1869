"""What auto compared on a move (:class:`Alternative`), and the record base that reads as its
trajectory.json mapping (:class:`JsonRecord`). Imports nothing heavy: the trajectory record and
the pages use them without loading the planner."""

from __future__ import annotations

from collections.abc import Iterator, Mapping
from dataclasses import dataclass
from functools import cached_property
from typing import Any


class JsonRecord(Mapping[str, Any]):
    """A frozen record that also reads as its trajectory.json mapping (``record["key"]``).

    Subclasses are frozen dataclasses with typed fields and say how they are written
    (:meth:`to_json`); the mapping view is that document, formed once.
    """

    def to_json(self) -> dict[str, Any]:
        raise NotImplementedError

    @cached_property
    def _document(self) -> dict[str, Any]:
        return self.to_json()

    def __getitem__(self, key: str) -> Any:
        return self._document[key]

    def __iter__(self) -> Iterator[str]:
        return iter(self._document)

    def __len__(self) -> int:
        return len(self._document)


@dataclass(frozen=True, eq=False)
class Alternative(JsonRecord):
    """One method auto (or a multi-variant method) tried on a move.

    Attributes:
        method: the method's name.
        feasible: it planned the move within the limits and tolerances; None: not timed, because
            no timing of its joint map could end sooner than the chosen one's (``at_least_s``).
        variant: which of the method's variants (e.g. the wrist-joint blend window), "" for none.
        duration_s: the move's duration with it [s] (feasible ones).
        reason: why it could not plan the move (infeasible ones), or why it was not timed.
        at_least_s: the lower bound on its duration that ruled it out [s] (those not timed).
    """

    method: str
    feasible: bool | None
    variant: str = ""
    duration_s: float | None = None
    reason: str = ""
    at_least_s: float | None = None

    def to_json(self) -> dict[str, Any]:
        if self.feasible:
            return {"method": self.method, "variant": self.variant, "duration_s": self.duration_s, "feasible": True}
        if self.feasible is None:
            return {"method": self.method, "variant": self.variant, "feasible": None, "at_least_s": self.at_least_s,
                    "reason": self.reason}
        return {"method": self.method, "variant": self.variant, "feasible": False, "reason": self.reason}

    @classmethod
    def from_json(cls, doc: Mapping[str, Any]) -> Alternative:
        def number(key: str) -> float | None:
            return None if doc.get(key) is None else float(doc[key])

        feasible = doc["feasible"]
        return cls(str(doc["method"]), None if feasible is None else bool(feasible), str(doc.get("variant", "")),
                   number("duration_s"), str(doc.get("reason", "")), number("at_least_s"))
