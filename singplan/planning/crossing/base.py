"""What a crossing method sees and returns, and the protocol every method (built-in or a user's) follows."""

from __future__ import annotations

from dataclasses import dataclass
from typing import Protocol

import numpy as np

from singplan.kinematics.robot import Robot
from singplan.planning.path.cartesian import CartesianPiece
from singplan.planning.path.jointmap import JointPart
from singplan.planning.path.tracking import BranchCandidates, TrackedPath
from singplan.planning.path.zones import Zone


@dataclass(frozen=True)
class MoveContext:
    """What a method may look at: one LIN/CIRC move tracked in its current branch.

    auto's candidates are handed the same context (the planner tracks each stretch once): a method
    reads its arrays and never changes them (``branches``, the branches solved so far, only grows).
    """

    robot: Robot
    move_index: int
    move_kind: str
    piece: CartesianPiece
    tracked: TrackedPath
    distances: np.ndarray  # (N, 3) signed (wrist, shoulder, elbow) at tracked.u
    position_tolerance_m: float  # the task's tolerances, the most a crossing may deviate
    orientation_tolerance_rad: float
    thresholds: np.ndarray  # (3,) zone detection thresholds: wrist [rad], shoulder [m], elbow [rad]
    # the IK branches of the move's poses solved so far (shared with the tracking: a re-track of the
    # rest of the move after a crossing solves only the parameters not solved yet); None: its own
    branches: BranchCandidates | None = None


@dataclass(frozen=True)
class Pause:
    """The TCP waits at path parameter ``u`` while the joints move from ``q[0]`` to ``q[-1]``.

    Attributes:
        u: where on the move the pause happens (the singular point).
        q: reference joint values of the null-space motion [rad], shape (K, n), every one at the
            path pose of ``u``; the driven joint is linear in the sample index.
        after: the joint-map part from ``q[-1]`` at ``u`` to the crossing's exit.
        joint: index of the driven joint (A4 at the wrist, A1 at the shoulder).
        turn_rad: how far it turns.
        T_target: the pose kept (4, 4).
    """

    u: float
    q: np.ndarray
    after: JointPart
    joint: int
    turn_rad: float
    T_target: np.ndarray


@dataclass(frozen=True)
class Crossing:
    """A crossing that replaces the tracked joints on [u_a, u_b] and changes branch.

    ``blend`` covers the zone; the move continues from ``q_exit`` at ``u_b`` in the new branch.
    """

    zone: Zone
    method: str
    blend: JointPart
    q_exit: np.ndarray  # (n,)
    # null-space: the TCP waits at the end of ``blend`` while the joints move; ``pause.after`` goes on
    pause: Pause | None = None
    # a PTP jump (SEEDS 004): ``blend`` is a joint line that starts and ends at rest, as a PTP move does
    stops: bool = False

    @property
    def at_rest(self) -> bool:
        """Whether the move stops inside this crossing (a pause or a PTP jump): it is timed in pieces
        from rest to rest (:mod:`singplan.planning.orchestration.stops`) and cannot be flown through."""
        return self.pause is not None or self.stops

    @property
    def parts(self) -> list[JointPart]:
        """The joint-map parts that replace the zone (two around a pause)."""
        return [self.blend] if self.pause is None else [self.blend, self.pause.after]


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
