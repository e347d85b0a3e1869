"""A move's Cartesian piece: its LIN or CIRC (:mod:`singplan.planning.path.cartesian`), woven when the move
asks for it (:mod:`singplan.planning.path.weave`); the one home of a move's geometry for the planner,
the budget and the replay."""

from __future__ import annotations

import numpy as np
import pinocchio as pin

from singplan.planning.path.cartesian import CartesianPiece, make_circ, make_lin, move_target
from singplan.planning.path.weave import woven
from singplan.task.schema import Move


def move_piece(i: int, move: Move, T_start: pin.SE3) -> CartesianPiece:
    """The LIN / CIRC geometry of move ``i`` starting at ``T_start``, with its weave if it has one."""
    field_name = f"moves[{i}].{move.kind}"
    if move.kind == "lin":
        piece = make_lin(T_start, move_target(move, T_start), field_name)
    else:
        piece = make_circ(T_start, np.asarray(move.via_xyz, dtype=float), move_target(move, T_start), field_name)
    return piece if move.weave is None else woven(piece, move.weave, field_name)
