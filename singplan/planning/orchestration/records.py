"""Records the planning stages hand forward: one move's joint map and what was found along it."""

from __future__ import annotations

from dataclasses import dataclass, replace

import numpy as np

from singplan.planning.crossing.methods import Crossing
from singplan.planning.orchestration.alternatives import Alternative
from singplan.planning.path.cartesian import CartesianPiece
from singplan.planning.path.jointmap import JointMap
from singplan.planning.path.zones import Zone
from singplan.planning.timing.records import MoveLimits


@dataclass(frozen=True)
class SampleDeviations:
    """How far a timed move's samples leave the path, measured once when the move was checked."""

    u: np.ndarray  # (K+1,) the samples' path parameters and joints, as timed
    q: np.ndarray  # (K+1, n)
    position_m: np.ndarray  # (K+1,) position error of each sample [m]
    orientation_rad: np.ndarray  # (K+1,) orientation error [rad] (five joints: between the tool z axes)
    tcp_speed_ratio: np.ndarray  # (K,) each step's TCP speed over the move's programmed speed

    def of(self, u: np.ndarray, q: np.ndarray) -> SampleDeviations | None:
        """These figures, if they are of these samples; None for any other samples."""
        if np.array_equal(u, self.u) and np.array_equal(q, self.q):
            return self
        return None


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
    deviations: SampleDeviations | None = None  # of the samples the move was checked on (LIN / CIRC)

    def without_joint_map(self) -> PlannedMove:
        """A LIN / CIRC without its joint map's parts, once nothing evaluates it again (it is described
        by its piece; its record is made from its samples, zones and crossings): a long program keeps
        every move, and the parts are a third of what one keeps. A PTP as it is (its map: two ends)."""
        if self.piece is None:
            return self
        return replace(self, jmap=JointMap(self.jmap.robot, self.jmap.poses, []))

    def for_messages(self) -> PlannedMove:
        """The move as the trajectory's final gate still needs it once the record has its samples'
        figures: index, kind, limits, and where a point of it is (:meth:`describe`); a LIN / CIRC
        without its joint map's parts, zones, crossings and deviations. A long program's record is
        built a move at a time and these are freed as it goes."""
        return replace(self.without_joint_map(), zones=(), crossings=(), deviations=None)

    def describe(self, u: float) -> str:
        """A point of the move for messages: the path point of a LIN / CIRC, the fraction and joints of a PTP."""
        if self.piece is not None:
            return self.piece.describe(u)
        q = self.jmap.evaluate(np.array([u]))[0]
        return f"{u:.3f} of the joint motion (joints_deg {np.round(np.degrees(q), 3).tolist()})"
