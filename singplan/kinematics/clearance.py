"""Clearance along a joint motion: every checked pair at least ``clearance`` apart at every sample and
along the straight joint motion between samples (DESIGN.md, "Collision").

The distance of two bodies cannot shrink faster than their points move relative to each other, and
between two joint samples no point of a body moves farther than ``sum_j |dq_j| * reach_j`` (its
reach per joint, :class:`~singplan.kinematics.collision.Body`). With ``M`` that bound accumulated
along the samples, a distance ``d`` measured at motion ``M0`` proves ``d - |M - M0|`` everywhere else:
conservative advancement (Mirtich 1996). So for each pair:

1. a lower bound at every sample from capsules enclosing the shapes (numpy, all samples at once),
   carried along by the motion bound; where it proves the sample (at least the clearance, and for
   the least clearance reported, at least the least distance found so far less :data:`EXACT_M`) and
   the motion to the next sample (at least the clearance less :data:`BETWEEN_TOLERANCE_M`), coal is
   never asked;
2. elsewhere the motion is walked: a sample whose bound proves too little is measured with coal, and
   where the stretch one measurement proves ends before the next sample, the motion is measured there
   (a sub-sample between samples), each step at least half :data:`BETWEEN_TOLERANCE_M` of motion.

The least distance reported per span of samples (a move) is the least measured there, at most
:data:`EXACT_M` above the true least sample distance. Samples are handled :data:`BLOCK` at a time,
so memory stays bounded on long programs.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from singplan.kinematics.collision import CollisionModel, Distance, Pair

BETWEEN_TOLERANCE_M = 2e-4  # between samples a pair may come this much closer than the clearance
EXACT_M = 2.5e-4  # the least clearance reported is at most this above the true least sample distance
BLOCK = 4096  # samples whose frames and bounds are formed at once (~1 kB each)
_SEEDS = 2  # pairs measured first in each span, where their bound is least: an early least distance


@dataclass(frozen=True)
class Approach:
    """The closest approach within a span of samples.

    Attributes:
        distance_m: the least distance measured [m] (at most :data:`EXACT_M` above the true least).
        bodies: the two bodies.
        sample: where (the index among the samples checked, plus the offset given).
        point_a, point_b: the closest points of the two bodies there, in the base frame [m].
    """

    distance_m: float
    bodies: tuple[str, str]
    sample: int
    point_a: tuple[float, float, float]
    point_b: tuple[float, float, float]


@dataclass(frozen=True)
class Contact:
    """Where a pair comes closer than allowed: the worst place found.

    Attributes:
        distance_m: the distance there [m]: negative is a penetration depth, -inf meshes intersecting.
        bodies: the two bodies.
        sample: the sample (plus the offset given), or the one before the point between samples.
        fraction: 0 at the sample; between 0 and 1, that far along the motion to the next sample.
    """

    distance_m: float
    bodies: tuple[str, str]
    sample: int
    fraction: float = 0.0

    @property
    def between(self) -> bool:
        return self.fraction > 0.0


@dataclass(frozen=True)
class Clearance:
    """The outcome of a clearance check.

    Attributes:
        clearance_m: the clearance asked for [m].
        least: per span of samples, its closest approach (None: nothing was checked).
        contacts: each pair that came too close, its worst place; worst first (empty: clear).
        distance_calls: coal distance queries made.
    """

    clearance_m: float
    least: tuple[Approach | None, ...]
    contacts: tuple[Contact, ...] = ()
    distance_calls: int = 0

    @property
    def clear(self) -> bool:
        return not self.contacts

    @property
    def closest(self) -> Approach | None:
        """The closest approach of all spans."""
        found = [a for a in self.least if a is not None]
        return min(found, key=lambda a: a.distance_m) if found else None


def check_clearance(model: CollisionModel, q: np.ndarray, spans: Sequence[tuple[int, int]] | None = None,
                    offset: int = 0, start: bool = False, exact: bool = True) -> Clearance:
    """Check the joint samples ``q`` (N, n) [rad] and the straight motion between them.

    Args:
        spans: (first, last) sample of each span whose closest approach is reported (moves share
            their boundary sample); default one span of all samples.
        offset: added to every sample index reported (where these samples start in a trajectory).
        start: the first sample starts the trajectory: a body wholly inside a mesh is looked for
            there (later it cannot get inside without crossing the surface, which is measured).
        exact: find each span's closest approach (to :data:`EXACT_M`); False: only whether the motion
            is clear (``least`` is then the least distance that happened to be measured, an upper bound).
    """
    q = np.asarray(q, dtype=float).reshape(-1, model.robot.n_joints)
    spans = list(spans) if spans is not None else [(0, len(q) - 1)]
    if not model.active or len(q) == 0:
        return Clearance(model.clearance_m, tuple(None for _ in spans))
    calls = model.distance_calls
    walk = _Walk(model, q, spans, offset, start, exact)
    walk.run()
    contacts = sorted(walk.contacts.values(), key=lambda c: c.distance_m)
    return Clearance(model.clearance_m, tuple(walk.least), tuple(contacts), model.distance_calls - calls)


def clearance_curve(model: CollisionModel, q: np.ndarray, count: int) -> tuple[np.ndarray, np.ndarray]:
    """The least distance of all checked pairs [m] at about ``count`` samples spread over q (N, n):
    (sample indices (K,), distances (K,)), for plotting. Pairs are measured closest bound first, and
    one whose bound is past the least found is not measured."""
    q = np.asarray(q, dtype=float).reshape(-1, model.robot.n_joints)
    picks = np.unique(np.linspace(0, len(q) - 1, min(count, len(q))).round().astype(int))
    if not model.active:
        return picks, np.full(len(picks), np.nan)
    R, P = model.robot.joint_frames(q[picks])
    bounds = np.array([_lower_bounds(pair, R, P) for pair in model.pairs])  # (pairs, K)
    out = np.empty(len(picks))
    for i in range(len(picks)):
        best = math.inf
        for p in np.argsort(bounds[:, i]):
            if bounds[p, i] >= best:
                break
            best = min(best, model.pair_distance(model.pairs[p], R[i], P[i]).distance_m)
        out[i] = best
    return picks, out


class _Walk:
    """One clearance check: the pairs walked over the samples, block by block."""

    def __init__(self, model: CollisionModel, q: np.ndarray, spans: list[tuple[int, int]], offset: int,
                 start: bool, exact: bool) -> None:
        self.model, self.q, self.offset, self.start, self.exact = model, q, offset, start, exact
        self.c = model.clearance_m
        self.floor = self.c - BETWEEN_TOLERANCE_M  # the least distance allowed between samples
        n = len(q)
        self.first = np.full(n, len(spans))  # each sample's first and last span (len(spans): none)
        self.last = np.full(n, len(spans))
        for s, (k0, k1) in enumerate(spans):
            self.first[k0:k1 + 1] = np.minimum(self.first[k0:k1 + 1], s)
            self.last[k0:k1 + 1] = s
        self.best = np.full(len(spans) + 1, math.inf)  # least distance measured per span (+ none)
        self.least: list[Approach | None] = [None] * len(spans)
        self.contacts: dict[tuple[str, str], Contact] = {}

    def run(self) -> None:
        n = len(self.q)
        for s in range(0, max(n - 1, 1), BLOCK):
            e = min(s + BLOCK, n - 1)
            self._block(s, e)

    # -- one block of samples s .. e (consecutive blocks share a sample) ---------------------------------

    def _block(self, s: int, e: int) -> None:
        R, P = self.model.robot.joint_frames(self.q[s:e + 1])
        dq = np.abs(np.diff(self.q[s:e + 1], axis=0))
        lower = {pair: _lower_bounds(pair, R, P) for pair in self.model.pairs}
        order = sorted(self.model.pairs, key=lambda pair: float(lower[pair].min()))
        block = _Block(self, s, R, P)
        if self.exact:
            self._seed(block, order, lower, s, e)
        for pair in order:
            M = np.concatenate([[0.0], np.cumsum(dq @ pair.weights)])
            block.pair(pair, lower[pair], M)

    def _seed(self, block: _Block, order: list[Pair], lower: dict[Pair, np.ndarray], s: int, e: int) -> None:
        """A first least distance of each span in the block: its closest pairs where their bound is least."""
        for span in np.unique(self.first[s:e + 1]):
            local = np.nonzero(self.first[s:e + 1] == span)[0]
            for pair in sorted(order, key=lambda p: float(lower[p][local].min()))[:_SEEDS]:
                block.sample(pair, int(local[np.argmin(lower[pair][local])]))

    def threshold(self, k: np.ndarray) -> np.ndarray:
        """What a sample's distance must be proven to be (global indices k): the clearance, and the least
        found in its spans less EXACT_M (so that the least reported is within EXACT_M of the true)."""
        return np.maximum(self.c, np.minimum(self.best[self.first[k]], self.best[self.last[k]]) - EXACT_M)

    def record(self, pair: Pair, k: int, found: Distance) -> None:
        d = found.distance_m
        if not found.exact:  # a lower bound past the threshold: proven, and not the least
            return
        for span in {int(self.first[k]), int(self.last[k])}:
            if span < len(self.least) and d < self.best[span]:
                self.best[span] = d
                self.least[span] = Approach(d, pair.names, k + self.offset, _triple(found.point_a),
                                            _triple(found.point_b))
        if d < self.c:
            self.contact(pair, Contact(d, pair.names, k + self.offset))

    def contact(self, pair: Pair, contact: Contact) -> None:
        seen = self.contacts.get(pair.names)
        if seen is None or contact.distance_m < seen.distance_m:
            self.contacts[pair.names] = contact


class _Block:
    """The samples s .. s + m - 1 of a check, their joint frames, and the walk of each pair over them."""

    def __init__(self, walk: _Walk, s: int, rotations: np.ndarray, origins: np.ndarray) -> None:
        self.walk, self.s, self.R, self.P = walk, s, rotations, origins
        self.measured: dict[tuple[Pair, int], float] = {}

    def sample(self, pair: Pair, i: int) -> float:
        """The pair's distance at local sample i (measured once)."""
        key = (pair, i)
        if key not in self.measured:
            model, k = self.walk.model, self.s + i
            found = model.pair_distance(pair, self.R[i], self.P[i], float(self.walk.threshold(np.array([k]))[0]))
            if k == 0 and self.walk.start and found.distance_m > 0 and model.inside_mesh(pair, self.R[i], self.P[i]):
                found = Distance(-math.inf, found.point_a, found.point_b)
            self.walk.record(pair, k, found)
            self.measured[key] = found.distance_m
        return self.measured[key]

    def between(self, pair: Pair, x: float) -> float:
        """The pair's distance at local position x between samples (joint values interpolated)."""
        walk = self.walk
        i = min(math.floor(x), len(self.R) - 2)
        f = x - i
        q = walk.q[self.s + i] + f * (walk.q[self.s + i + 1] - walk.q[self.s + i])
        R, P = walk.model.robot.joint_frames(q[None])
        d = walk.model.pair_distance(pair, R[0], P[0], walk.c - BETWEEN_TOLERANCE_M / 2).distance_m
        if d < walk.c - BETWEEN_TOLERANCE_M / 2:
            walk.contact(pair, Contact(d, pair.names, self.s + i + walk.offset, f))
        return d

    def pair(self, pair: Pair, lower: np.ndarray, M: np.ndarray) -> None:
        """Prove or measure one pair over the block: bounds first, the walk only where they fall short."""
        walk = self.walk
        m = len(lower)
        k = self.s + np.arange(m)
        known = np.array([self.measured.get((pair, i), -math.inf) for i in range(m)]) if self.measured else None
        bound = lower if known is None else np.maximum(lower, known)
        forward = np.maximum.accumulate(bound + M) - M
        backward = np.maximum.accumulate((bound - M)[::-1])[::-1] + M
        bound = np.maximum(bound, np.maximum(forward, backward))
        short = bound < walk.threshold(k)
        if m == 1:
            if short[0]:
                self.sample(pair, 0)
            return
        gap = (bound[:-1] + bound[1:] - np.diff(M)) / 2 < walk.floor  # the motion to the next sample unproven
        touched = gap | short[:-1] | short[1:]  # intervals i .. i + 1 to walk
        for a, b in _runs(touched):
            self._walk(pair, a, b + 1, float(bound[a]), lower, M)

    def _walk(self, pair: Pair, i_from: int, i_to: int, v: float, lower: np.ndarray, M: np.ndarray) -> None:
        """Conservative advancement from sample i_from (distance at least v) to sample i_to."""
        walk = self.walk
        floor, c = walk.floor, walk.c
        step_min = BETWEEN_TOLERANCE_M / 2
        x = float(i_from)
        if v < walk.threshold(np.array([self.s + i_from]))[0]:
            v = self.sample(pair, i_from)
        while x < i_to:
            i = math.floor(x)
            if v < floor:  # too close here (recorded): on to the next sample
                x, v = float(i + 1), self.sample(pair, i + 1)
                continue
            Mx = M[i] + (x - i) * (M[min(i + 1, len(M) - 1)] - M[i])
            cover = Mx + (v - floor)  # everything up to this motion is proven at least `floor`
            hi = min(i_to, int(np.searchsorted(M, cover, side="right")))
            ks = np.arange(i + 1, hi + 1)
            bound = np.maximum(lower[ks], v - (M[ks] - Mx))
            need = bound < walk.threshold(self.s + ks)
            if need.any() and M[ks[np.argmax(need)]] <= cover:  # proven stretch, but the sample needs more
                x = float(ks[np.argmax(need)])
                v = self.sample(pair, int(x))
                continue
            if M[hi] <= cover:  # proven to the walk's end
                return
            v_hi = self.sample(pair, hi) if need[-1] else float(bound[-1])
            if M[hi] - (v_hi - floor) > cover and not need[-1]:
                v_hi = self.sample(pair, hi)  # a measurement may close the gap from the right
            if M[hi] - (v_hi - floor) <= cover:
                x, v = float(hi), v_hi
                continue
            target = Mx + max(cover - Mx, step_min)  # a sub-sample where the proven stretch ends
            j = int(np.searchsorted(M, target, side="right")) - 1
            if j >= hi or M[j + 1] <= M[j]:
                x, v = float(hi), v_hi
                continue
            x = j + (target - M[j]) / (M[j + 1] - M[j])
            v = self.between(pair, x)
            if v < c - BETWEEN_TOLERANCE_M / 2:  # too close between samples (recorded): on to the next sample
                x, v = float(j + 1), self.sample(pair, j + 1)


def _runs(flags: np.ndarray) -> list[tuple[int, int]]:
    """(first, last) index of each run of True in ``flags``."""
    if not flags.any():
        return []
    padded = np.concatenate([[False], flags, [False]]).astype(np.int8)
    edges = np.diff(padded)
    return list(zip(np.nonzero(edges == 1)[0].tolist(), (np.nonzero(edges == -1)[0] - 1).tolist(), strict=True))


def _triple(v: np.ndarray) -> tuple[float, float, float]:
    return float(v[0]), float(v[1]), float(v[2])


def _lower_bounds(pair: Pair, rotations: np.ndarray, origins: np.ndarray) -> np.ndarray:
    """A lower bound of the pair's distance at each sample (N,): the least distance of the capsules
    enclosing their shapes. ``rotations`` (N, J, 3, 3), ``origins`` (N, J, 3): the joint frames."""
    ends_a = [_capsule_ends(g.segment, pair.a.joint, rotations, origins) for g in pair.a.geoms]
    ends_b = [_capsule_ends(g.segment, pair.b.joint, rotations, origins) for g in pair.b.geoms]
    out = np.full(len(rotations), math.inf)
    for ga, (a0, a1) in zip(pair.a.geoms, ends_a, strict=True):
        for gb, (b0, b1) in zip(pair.b.geoms, ends_b, strict=True):
            out = np.minimum(out, segment_distances(a0, a1, b0, b1) - ga.radius_m - gb.radius_m)
    return out


def _capsule_ends(segment: np.ndarray, joint: int | None, rotations: np.ndarray,
                  origins: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """A capsule axis's ends (N, 3) each in the base frame."""
    if joint is None:
        n = len(rotations)
        return np.broadcast_to(segment[0], (n, 3)), np.broadcast_to(segment[1], (n, 3))
    R, P = rotations[:, joint], origins[:, joint]
    return (np.einsum("nij,j->ni", R, segment[0]) + P, np.einsum("nij,j->ni", R, segment[1]) + P)


def segment_distances(p1: np.ndarray, q1: np.ndarray, p2: np.ndarray, q2: np.ndarray) -> np.ndarray:
    """Least distances (N,) between segments p1-q1 and p2-q2 (N, 3) each, degenerate ones (points) too:
    the closest points' parameters clamped to the segments (Ericson, Real-Time Collision Detection, 5.1.9)."""
    d1, d2, r = q1 - p1, q2 - p2, p1 - p2
    a = np.einsum("ij,ij->i", d1, d1)
    e = np.einsum("ij,ij->i", d2, d2)
    f = np.einsum("ij,ij->i", d2, r)
    c = np.einsum("ij,ij->i", d1, r)
    b = np.einsum("ij,ij->i", d1, d2)
    tiny = 1e-18
    a_ok, e_ok = a > tiny, e > tiny
    denom = a * e - b * b
    # both segments proper: the lines' closest parameters, s clamped, t from s, then s again from t
    s = np.where(denom > 1e-12 * a * e, np.clip(_div(b * f - c * e, denom), 0.0, 1.0), 0.0)  # parallel: s = 0
    t = _div(b * s + f, e)
    s = np.where(t < 0.0, np.clip(_div(-c, a), 0.0, 1.0), np.where(t > 1.0, np.clip(_div(b - c, a), 0.0, 1.0), s))
    t = np.clip(t, 0.0, 1.0)
    # the second a point: t = 0; the first a point: s = 0 (both points: both 0)
    s = np.where(e_ok, s, np.clip(_div(-c, a), 0.0, 1.0))
    t = np.where(e_ok, t, 0.0)
    s = np.where(a_ok, s, 0.0)
    t = np.where(a_ok, t, np.where(e_ok, np.clip(_div(f, e), 0.0, 1.0), 0.0))
    gap = (p1 + d1 * s[:, None]) - (p2 + d2 * t[:, None])
    return np.sqrt(np.einsum("ij,ij->i", gap, gap))


def _div(num: np.ndarray, den: np.ndarray) -> np.ndarray:
    return np.divide(num, den, out=np.zeros_like(num), where=den != 0)
