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
        feasible: it planned the move within the limits and tolerances.
        variant: which of the method's variants (e.g. the wrist-joint blend window), "" for none.
        duration_s: the move's duration with it [s] (feasible ones).
        reason: why it could not plan the move (infeasible ones).
    """

    method: str
    feasible: bool
    variant: str = ""
    duration_s: float | None = None
    reason: str = ""

    def to_json(self) -> dict[str, Any]:
        if self.feasible:
            return {"method": self.method, "variant": self.variant, "duration_s": self.duration_s, "feasible": True}
        return {"method": self.method, "feasible": False, "reason": self.reason}

    @classmethod
    def from_json(cls, doc: Mapping[str, Any]) -> Alternative:
        return cls(str(doc["method"]), bool(doc["feasible"]), str(doc.get("variant", "")),
                   None if doc.get("duration_s") is None else float(doc["duration_s"]), str(doc.get("reason", "")))
