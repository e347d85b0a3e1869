"""A trajectory's programmed path: each LIN / CIRC move's piece as the planner makes it (the line or
arc of :mod:`singplan.planning.path.cartesian`, woven where the move weaves), made from the
trajectory's typed task.

trajectory.json records the task, not the pieces, and where a move starts depends on the robot (the
first sample's pose, a PTP target given as joints): :func:`programmed_path` makes the pieces from the
robot's pose at the first sample, each LIN / CIRC starting where the move before it was programmed to
end (after a PTP: at its joint target's pose, or at its target pose). The pages and the controller
programs read them here, so no output parses the task or builds a path itself, and a trajectory
planned and the same trajectory read back from its file give the same path.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from singplan.kinematics.robot import Robot
from singplan.planning.path.cartesian import CartesianPiece, move_target
from singplan.planning.path.pieces import move_piece
from singplan.planning.path.weave import WovenPiece
from singplan.task.schema import Move, Task


@dataclass(frozen=True)
class ProgrammedMove:
    """One task move's programmed path.

    Attributes:
        move: the task's move (typed, as validated).
        piece: a LIN / CIRC's path (a :class:`~singplan.planning.path.weave.WovenPiece` where the
            move weaves: its ``length_m`` and ``u`` are the base path's); None for a PTP (its path is
            a joint motion, drawn as executed).
    """

    move: Move
    piece: CartesianPiece | None

    @property
    def kind(self) -> str:
        return self.move.kind

    @property
    def weave_slope(self) -> float:
        """A woven move's steepest weave slope against its base path
        (:attr:`~singplan.planning.path.weave.WovenPiece.steepest_slope`); 0 without a weave."""
        return self.piece.steepest_slope if isinstance(self.piece, WovenPiece) else 0.0


def programmed_path(task: Task, robot: Robot, q_start: np.ndarray) -> tuple[ProgrammedMove, ...]:
    """Every move's programmed path, in task order (``robot``: the trajectory's, with its tool;
    ``q_start``: its first sample (n,) [rad])."""
    out = []
    T = robot.fk(q_start)
    for i, move in enumerate(task.moves):
        if move.kind == "ptp":
            out.append(ProgrammedMove(move, None))
            T = robot.fk(np.radians(move.to_joints_deg)) if move.to_joints_deg is not None else move_target(move, T)
            continue
        piece = move_piece(i, move, T)
        out.append(ProgrammedMove(move, piece))
        T = piece.T_end
    return tuple(out)


def woven_moves(task: Task) -> frozenset[int]:
    """The indices of the task's moves that weave."""
    return frozenset(i for i, move in enumerate(task.moves) if move.weave is not None)
