"""Moves that stop on their path, timed in pieces from rest to rest.

Two crossings stop the TCP inside a LIN / CIRC: a null-space pause (the TCP waits on the
singular point while the joints turn, :mod:`singplan.planning.crossing.nullspace`) and a PTP jump
(the ``ptp`` baseline, SEEDS 004: the joints run a straight line over the zone, from rest to
rest, as a PTP move does). A joint map has no way to stop inside it (its slope is continuous
where TOPP-RA needs it, and a joint line's ends are kinks no finite acceleration turns at speed),
so the move is timed as pieces that each start and end at rest: the path up to the stop, the
pause or the jump, the path after it, with the same timing as any move. The pieces share their
end samples, and the seams keep the acceleration limit because every piece's end steps do
(:func:`singplan.planning.timing.end_step_ratio`). Every sample of a pause carries the pause's
``u``, so the segment labelling puts it inside its crossing.
"""

from __future__ import annotations

from dataclasses import replace

import numpy as np

from singplan.kinematics.dynamics import move_torque_ratio
from singplan.planning.crossing.base import Crossing
from singplan.planning.crossing.nullspace import PauseMap
from singplan.planning.path.jointmap import JointMap, JointPart
from singplan.planning.timing.move import time_move
from singplan.planning.timing.ratios import sample_ratios
from singplan.planning.timing.records import MoveLimits, TcpTrace, TimedMove, TimingError

Piece = tuple[JointMap, MoveLimits, float, float]  # a piece's map, its limits, and u at its start and end


class _PieceMap(JointMap):
    """A stretch [u0, u1] of a move's joint map, re-parameterised to [0, 1] for the timing."""

    def __init__(self, inner: JointMap, parts: list[JointPart]) -> None:
        super().__init__(inner.robot, inner.poses, parts)
        self.u0, self.u1 = parts[0].u0, parts[-1].u1

    def reference(self) -> tuple[np.ndarray, np.ndarray]:
        u, q = super().reference()
        return (u - self.u0) / (self.u1 - self.u0), q

    def evaluate(self, u: np.ndarray) -> np.ndarray:
        return super().evaluate(self.u0 + np.asarray(u, dtype=float) * (self.u1 - self.u0))


def stops(crossings: tuple[Crossing, ...]) -> bool:
    """Whether a move with these crossings stops on its path (and is timed by :func:`time_in_pieces`)."""
    return any(c.at_rest for c in crossings)


def time_in_pieces(jmap: JointMap, crossings: tuple[Crossing, ...], limits: MoveLimits, period_s: float,
                   move_index: int, max_samples: int) -> TimedMove:
    """Time a move that stops on its path: the pieces between its stops, each from rest to rest, joined.

    Where a piece does not start on the joints the one before ends on and the seam would break the
    joint limits, the two are joined by a short joint line from rest to rest (:func:`_with_bridges`).
    """
    pieces = _pieces(jmap, crossings, limits)
    timed = _joined(pieces, limits, period_s, move_index, max_samples)
    if timed.speed_ratio > 1.0 or timed.accel_ratio > 1.0:
        bridged = _with_bridges(jmap, pieces, limits)
        if len(bridged) > len(pieces):
            timed = _joined(bridged, limits, period_s, move_index, max_samples)
    return timed


def _joined(pieces: list[Piece], limits: MoveLimits, period_s: float, move_index: int,
            max_samples: int) -> TimedMove:
    """Each piece timed, the samples joined (the pieces share their end samples, at rest)."""
    us: list[np.ndarray] = []
    qs: list[np.ndarray] = []
    duration, left = 0.0, max_samples
    for piece_map, piece_limits, u0, u1 in pieces:
        try:
            tm = time_move(piece_map, piece_limits, period_s, move_index, left)
        except TimingError as exc:
            raise TimingError(move_index, u0 + exc.u * (u1 - u0), exc.reason) from exc
        first = 0 if not us else 1
        us.append(u0 + tm.u[first:] * (u1 - u0))
        qs.append(tm.q[first:])
        duration += tm.duration_s
        left -= len(tm.q) - 1
    u, q = np.concatenate(us), np.concatenate(qs)
    speed, accel = sample_ratios(q, period_s, limits.velocity_rad_s, limits.acceleration_rad_s2)
    torque = move_torque_ratio(limits.torque, q, period_s)[0] if limits.torque else 0.0
    return TimedMove(u, q, duration, speed, accel, torque)


def _pieces(jmap: JointMap, crossings: tuple[Crossing, ...], limits: MoveLimits) -> list[Piece]:
    """The move cut at its stops: path pieces, pauses and PTP jumps, in order."""
    pauses = {id(c.blend): c.pause for c in crossings if c.pause is not None}
    jumps = {id(c.blend) for c in crossings if c.stops}
    pieces: list[Piece] = []
    current: list[JointPart] = []
    for part in jmap.parts:
        if id(part) in jumps:
            if current and current[-1].u1 > current[0].u0:  # (a jump at the move's start has no path before it)
                pieces.append(_path_piece(jmap, current, limits))
            pieces.append(_path_piece(jmap, [part], limits))
            current = []
            continue
        current.append(part)
        pause = pauses.get(id(part))
        if pause is not None:
            pieces.append(_path_piece(jmap, current, limits))
            pieces.append((PauseMap(jmap.robot, pause), replace(limits, length_m=0.0, tcp_speed_m_s=None, trace=None),
                           pause.u, pause.u))
            current = []
    if current and current[-1].u1 > current[0].u0:
        pieces.append(_path_piece(jmap, current, limits))
    return pieces


_BRIDGED_RAD = 1e-12  # pieces whose shared sample differs by more are joined by a bridge


def _with_bridges(jmap: JointMap, pieces: list[Piece], limits: MoveLimits) -> list[Piece]:
    """The pieces, with a short joint line from rest to rest wherever one does not start on the joints
    the one before ends on (a null-space turn ends where its pose tolerance let it drift; the path
    after it re-solves the position there, and at the singular point a free joint may land a hair
    away): the seam jumps by the difference otherwise."""
    out: list[Piece] = []
    for piece in pieces:
        if out:
            end = out[-1][0].evaluate(np.array([1.0]))[0]
            start = piece[0].evaluate(np.array([0.0]))[0]
            if float(np.max(np.abs(start - end))) > _BRIDGED_RAD:
                line = JointMap(jmap.robot, None, [JointPart("ptp", np.array([0.0, 1.0]), np.array([end, start]))])
                out.append((line, replace(limits, length_m=0.0, tcp_speed_m_s=None, trace=None), piece[2], piece[2]))
        out.append(piece)
    return out


def _path_piece(jmap: JointMap, parts: list[JointPart], limits: MoveLimits) -> Piece:
    piece = _PieceMap(jmap, parts)
    u0, u1 = piece.u0, piece.u1
    trace = None if limits.trace is None else _trace_piece(limits.trace, u0, u1)
    return piece, replace(limits, length_m=limits.length_m * (u1 - u0), trace=trace), u0, u1


def _trace_piece(trace: TcpTrace, u0: float, u1: float) -> TcpTrace:
    """The trace of the stretch [u0, u1], re-parameterised to [0, 1] and starting at 0."""
    inner = trace.u[(trace.u > u0) & (trace.u < u1)]
    u = np.concatenate([[u0], inner, [u1]])
    s = trace.at(u)
    return TcpTrace(trace.robot, (u - u0) / (u1 - u0), s - s[0])
