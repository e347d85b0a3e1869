"""Moves joined by fly-by corners, as one path for one timing pass, and the timed chain split
back into its moves.

A chain is move a's path up to its corner, the corner's blend, move a+1's path from the end
of that blend to its own corner, ... (:mod:`singplan.planning.orchestration.blending`). Its parameter ``w``
in [0, 1] is shared out so the joint path is C1 at every seam: a blend's ramps start and end
with slope 2 in v, so a blend gets ``2 (1 - u_leave)`` times the share per unit u of the move
before it, and the move after it gets the blend's share over ``2 u_join`` per unit u. The TCP
speed cap follows each piece's programmed speed through the chain's clock (time at programmed
speed), and each move keeps its own joint speed limits (a PTP's ``velocity_scale``); a corner
takes the lower of its two moves'.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass, replace

import numpy as np

from singplan.planning.orchestration.blending import Blend
from singplan.planning.orchestration.records import PlannedMove
from singplan.planning.path.jointmap import JointMap
from singplan.planning.timing.ratios import sample_ratios
from singplan.planning.timing.records import MoveLimits, TimedMove


@dataclass(frozen=True)
class Piece:
    """A stretch of a chain: part of a move's joint map, or a whole blend."""

    jmap: JointMap
    x0: float  # the stretch of the map's own parameter
    x1: float
    w0: float  # its share of the chain's parameter
    w1: float
    move: int
    blend: Blend | None  # the corner this piece flies (None: the move's own path)
    clock0_s: float  # the chain's clock at the piece's start
    clock_rate: float  # seconds at programmed speed per unit x (moves); unused for blends
    velocity_rad_s: np.ndarray  # (n,) the joint speed limits along the piece

    def x_of(self, w: np.ndarray) -> np.ndarray:
        return self.x0 + (w - self.w0) / (self.w1 - self.w0) * (self.x1 - self.x0)

    def clock(self, x: np.ndarray) -> np.ndarray:
        if self.blend is None:
            return self.clock0_s + (x - self.x0) * self.clock_rate
        b = self.blend
        if b.speed_m_s is None:
            return np.full(len(x), self.clock0_s)
        arc = np.interp(x, np.linspace(0.0, 1.0, len(b.arc_m)), b.arc_m)
        return self.clock0_s + arc / b.speed_m_s

    @property
    def clock1_s(self) -> float:
        return float(self.clock(np.array([self.x1]))[0])


class ChainMap(JointMap):
    """The joint path of a chain over w in [0, 1], evaluated piece by piece."""

    def __init__(self, pieces: list[Piece]) -> None:
        super().__init__(pieces[0].jmap.robot, None, [])
        self.pieces = pieces
        self._ends = np.array([p.w1 for p in pieces[:-1]])  # (P - 1,) the inner piece boundaries
        self._velocity = np.array([p.velocity_rad_s for p in pieces])  # (P, n)

    @property
    def straight(self) -> bool:
        return False

    def piece_at(self, w: np.ndarray) -> np.ndarray:
        """Index of the piece each w (N,) falls in."""
        return np.searchsorted(self._ends, w, side="left")

    def _per_piece(self, u: np.ndarray, of: Callable[[Piece, np.ndarray], np.ndarray],
                   shape: tuple[int, ...]) -> np.ndarray:
        """``of(piece, x)`` at each parameter u (N,), x being u in the piece's own parameter."""
        w = np.minimum(np.maximum(np.asarray(u, dtype=float), 0.0), 1.0)
        out = np.empty((len(w), *shape))
        which = self.piece_at(w)
        for k in np.unique(which):
            mask = which == k
            piece = self.pieces[int(k)]
            out[mask] = of(piece, piece.x_of(w[mask]))
        return out

    def evaluate(self, u: np.ndarray) -> np.ndarray:
        return self._per_piece(u, lambda piece, x: piece.jmap.evaluate(x), (self.robot.n_joints,))

    def reference(self) -> tuple[np.ndarray, np.ndarray]:
        ws, qs = [], []
        for n, p in enumerate(self.pieces):
            x, q = p.jmap.reference()
            inside = (x > p.x0) & (x < p.x1)
            x = np.concatenate([[p.x0], x[inside], [p.x1]])
            q = np.concatenate([p.jmap.evaluate(np.array([p.x0])), q[inside], p.jmap.evaluate(np.array([p.x1]))])
            w = p.w0 + (x - p.x0) / (p.x1 - p.x0) * (p.w1 - p.w0)
            first = 0 if n == 0 else 1  # neighbours share their end point
            ws.append(w[first:])
            qs.append(q[first:])
        w, q = np.concatenate(ws), np.concatenate(qs)
        keep = np.concatenate([[True], np.diff(w) > 1e-12])
        return w[keep], q[keep]

    def velocities(self, u: np.ndarray) -> np.ndarray:
        """Joint speed limits (N, n) [rad/s] at parameters u (N,): each move's own; a corner the
        lower of its two moves'."""
        return self._velocity[self.piece_at(np.minimum(np.maximum(np.asarray(u, dtype=float), 0.0), 1.0))]

    def clock(self, u: np.ndarray) -> np.ndarray:
        """The chain's TCP clock (N,) [s] at parameters u (N,)."""
        return self._per_piece(u, lambda piece, x: piece.clock(x), ())


def chains(planned: list[PlannedMove], blends: dict[int, Blend]) -> list[list[int]]:
    """The moves grouped into chains: runs joined by flown corners (a single move is a chain of one)."""
    out: list[list[int]] = [[0]]
    for i in range(1, len(planned)):
        b = blends.get(i - 1)
        if b is not None and b.jmap is not None:
            out[-1].append(i)
        else:
            out.append([i])
    return out


def chain_map(members: list[PlannedMove], blends: dict[int, Blend]) -> ChainMap:
    """The chain of ``members`` (consecutive moves, each but the last flying its corner)."""
    pieces: list[Piece] = []
    w, rate, clock = 0.0, 1.0, 0.0  # rate: the chain's parameter per unit of the current move's u
    u_from = 0.0
    for n, pm in enumerate(members):
        b = blends.get(pm.index) if n + 1 < len(members) else None
        u_to = b.u_leave if b is not None else 1.0
        move = Piece(pm.jmap, u_from, u_to, w, w + rate * (u_to - u_from), pm.index, None, clock, _clock_rate(pm),
                     pm.limits.velocity_rad_s)
        pieces.append(move)
        w, clock = move.w1, move.clock1_s
        if b is None or b.jmap is None:
            break
        width = 2.0 * (1.0 - b.u_leave) * rate  # the ramps' slope 2 in v continues the move's slope
        slower = np.minimum(pm.limits.velocity_rad_s, members[n + 1].limits.velocity_rad_s)
        corner = Piece(b.jmap, 0.0, 1.0, w, w + width, pm.index, b, clock, 0.0, slower)
        pieces.append(corner)
        w, clock = corner.w1, corner.clock1_s
        rate, u_from = width / (2.0 * b.u_join), b.u_join
    return ChainMap([_scaled(p, 1.0 / w) for p in pieces])


def _scaled(p: Piece, factor: float) -> Piece:
    return replace(p, w0=p.w0 * factor, w1=p.w1 * factor)


def _clock_rate(pm: PlannedMove) -> float:
    lim = pm.limits
    return lim.length_m / lim.tcp_speed_m_s if lim.tcp_speed_m_s and lim.length_m > 0 else 0.0


def chain_limits(members: list[PlannedMove], chain: ChainMap) -> MoveLimits:
    """The chain's limits: each member's joint speed limits along its stretch, the TCP clock with the
    fastest programmed speed as its reference."""
    first = members[0].limits
    speeds = [pm.limits.tcp_speed_m_s for pm in members if pm.limits.tcp_speed_m_s]
    velocity = np.max(np.array([pm.limits.velocity_rad_s for pm in members]), axis=0)
    length = sum(pm.limits.length_m for pm in members)
    return replace(first, velocity_rad_s=velocity, length_m=length, tcp_speed_m_s=max(speeds) if speeds else None,
                   quintic=False, clock=chain.clock, velocity_at=chain.velocities)


def starved(chain: ChainMap, timed: TimedMove) -> tuple[int, str] | None:
    """The first stretch of the chain that holds no output sample, as the move whose corner must
    be stopped at and why; None if every stretch has one.

    A move whose own stretch has none (its two corners meet within one period) cannot be told
    apart from its corners: the corner into it is stopped at. A corner with no sample strictly
    inside (crossed within one period) has none inside its sphere to show it kept there: it is.
    """
    w = timed.u
    for p in chain.pieces:
        if p.blend is None and not np.any((w >= p.w0 - 1e-15) & (w <= p.w1 + 1e-15)):
            return p.move - 1, f"move {p.move}'s own path between its corners is shorter than one period at its speed"
        if p.blend is not None and not np.any((w > p.w0) & (w < p.w1 - 1e-15)):
            return p.move, "the corner is crossed within one output period: no sample falls inside its sphere"
    return None


def split(chain: ChainMap, timed: TimedMove, limits: MoveLimits, period_s: float) -> list[TimedMove]:
    """The timed chain as one TimedMove per move: each runs to the end of the corner it flies
    (its ``blend_from`` marks where that corner starts); neighbours share that sample. Every
    move's own stretch must hold a sample (:func:`starved`)."""
    w = timed.u
    u = np.ones(len(w))  # a corner's samples: the incoming move's end
    starts: dict[int, int] = {}
    blend_from: dict[int, int] = {}
    for p in chain.pieces:
        if p.blend is None:
            inside = np.flatnonzero((w >= p.w0 - 1e-15) & (w <= p.w1 + 1e-15))
            u[inside] = np.minimum(p.x_of(w[inside]), 1.0)
            starts.setdefault(p.move, int(inside[0]))
        else:
            blend_from[p.move] = int(np.flatnonzero(w <= p.w0)[-1])
    moves = sorted(starts)
    # a move runs until the next one's first sample on its own path, the last to the chain's end
    ends = dict(zip(moves, [starts[m] for m in moves[1:]] + [len(w) - 1], strict=True))
    total = timed.optimal_duration_s if timed.optimal_duration_s is not None else timed.duration_s
    out = []
    for m in moves:
        a, b = starts[m], ends[m]
        q = timed.q[a:b + 1]
        uu = u[a:b + 1].copy()
        if m in blend_from:  # its corner's samples, the last shared with the next move
            uu[blend_from[m] - a + 1:] = 1.0
        speed, accel = sample_ratios(q, period_s, limits.step_velocities(w[a:b + 1]), limits.acceleration_rad_s2)
        duration = (b - a) * period_s
        share = duration * total / timed.duration_s if timed.duration_s > 0 else duration
        out.append(TimedMove(uu, q, duration, speed, accel, timed.torque_ratio, timed.jerk_ratio,
                             share if timed.optimal_duration_s is not None else None,
                             blend_from[m] - a if m in blend_from else None))
    return out


def describe_chain_point(chain: ChainMap, members: list[PlannedMove], w: float) -> tuple[int, str]:
    """The move and the point of it (or of its corner) at chain parameter w, for messages."""
    p = chain.pieces[int(chain.piece_at(np.array([w]))[0])]
    x = float(p.x_of(np.array([w]))[0])
    if p.blend is not None:
        return p.move, f"{x:.3f} of the fly-by corner after move {p.move} (radius {p.blend.radius_m * 1e3:.3f} mm)"
    pm = next(m for m in members if m.index == p.move)
    return p.move, pm.describe(x)

