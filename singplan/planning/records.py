"""Records the planning stages hand forward: one move's joint map and what was found along it."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from singplan.planning.alternatives import Alternative
from singplan.planning.crossing.methods import Crossing
from singplan.planning.jointmap import JointMap
from singplan.planning.path import CartesianPiece
from singplan.planning.timing import MoveLimits
from singplan.planning.zones import Zone


@dataclass(frozen=True)
class PlannedMove:
    """One move before timing: its joint map and what was found along it."""

    index: int
    kind: str
    jmap: JointMap
    limits: MoveLimits
    piece: CartesianPiece | None = None
    zones: tuple[Zone, ...] = ()
    crossings: tuple[Crossing, ...] = ()
    method: str = "exact"
    variant: str = ""  # e.g. the wrist-joint blend window
    alternatives: tuple[Alternative, ...] = ()  # what auto compared, fastest first

    def describe(self, u: float) -> str:
        """A point of the move for messages: the path point of a LIN / CIRC, the fraction and joints of a PTP."""
        if self.piece is not None:
            return self.piece.describe(u)
        q = self.jmap.evaluate(np.array([u]))[0]
        return f"{u:.3f} of the joint motion (joints_deg {np.round(np.degrees(q), 3).tolist()})"
