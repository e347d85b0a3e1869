"""What a crossing method sees and returns, and the protocol every method (built-in or a user's) follows."""

from __future__ import annotations

from dataclasses import dataclass
from typing import Protocol

import numpy as np

from singplan.kinematics.robot import Robot
from singplan.planning.jointmap import JointPart
from singplan.planning.path import CartesianPiece
from singplan.planning.tracking import TrackedPath
from singplan.planning.zones import Zone


@dataclass(frozen=True)
class MoveContext:
    """What a method may look at: one LIN/CIRC move tracked in its current branch."""

    robot: Robot
    move_index: int
    move_kind: str
    piece: CartesianPiece
    tracked: TrackedPath
    distances: np.ndarray  # (N, 3) signed (wrist, shoulder, elbow) at tracked.u
    position_tolerance_m: float  # the task's tolerances, the most a crossing may deviate
    orientation_tolerance_rad: float


@dataclass(frozen=True)
class Crossing:
    """A crossing that replaces the tracked joints on [u_a, u_b] and changes branch.

    ``blend`` covers the zone; the move continues from ``q_exit`` at ``u_b`` in the new branch.
    """

    zone: Zone
    method: str
    blend: JointPart
    q_exit: np.ndarray  # (n,)


class CrossingMethod(Protocol):
    """A way through singular zones: asked once per zone of each LIN / CIRC move.

    ``name`` is what the trajectory, the report and auto's comparison call it; ``variant`` tells
    apart objects of one method with different settings ("" when there is one).
    """

    name: str
    variant: str

    def cross(self, ctx: MoveContext, zone: Zone) -> Crossing | None:
        """A crossing for ``zone``, or None to keep the tracked solution (or raise SingularityError)."""
        ...
