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

import contextlib
import math
from collections.abc import Sequence
from dataclasses import dataclass

import coal
import numpy as np

from singplan.kinematics.collision import CollisionModel, Distance, Geom, Pair, ShapeGap, support
from singplan.kinematics.compiled import jit
from singplan.kinematics.geometry import rotation_angles

BETWEEN_TOLERANCE_M = 2e-4  # between samples a pair may come this much closer than the clearance
EXACT_M = 4e-4  # the least clearance reported is at most this above the true least sample distance
BLOCK = 4096  # samples whose frames and bounds are formed at once (~1 kB each)
_PLANES = 8  # separating planes a pair's bounds take per block, and one more per _PLANE_SPAN samples ...
_PLANE_GAIN_M = 1e-3  # ... each from a measurement this far above the bound there (EXACT_M / 2 for the least)
_PLANE_SPAN = 32
_PLANE_REACH = 160  # samples either side of its measurement a plane bounds (further the motion's cones carry it)
_REFINE = 8  # measurements a span's least takes past EXACT_M, where its bounds are least


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
    with contextlib.suppress(_CollidesError):  # only whether it is clear was asked: the first contact answers it
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
    found = capsule_bounds(model.pairs, R, P)
    bounds = np.array([found[pair] for pair in model.pairs])  # (pairs, K)
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
    """One clearance check: the samples block by block, each pair proven or measured."""

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
            _Block(self, s, min(s + BLOCK, n - 1)).check()

    def record(self, pair: Pair, k: int, found: Distance) -> None:
        d = found.distance_m
        if not found.exact:  # a lower bound past what was asked: proven, and not the least
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
        if not self.exact:
            raise _CollidesError


class _CollidesError(Exception):
    """A check of whether the motion is clear found a contact: nothing more to measure."""


class _PairState:
    """One pair over a block: its motion bounds, and its lower bounds at the samples, tightened as it goes.

    Attributes:
        M: (m,) the bound of the bodies' relative motion along the joint motion from the block's first
            sample [m] (between samples only this one holds).
        lower: (m,) lower bounds of its distance at the samples: a sphere around each body, then the
            capsules around their shapes, then the separating planes of its measurements.
        S: (m,) from sample to sample the relative displacement of the two bodies' frames bounds the
            motion too, often far closer (a pose kept while the wrist turns): the smaller of the two per
            step, made with ``relative`` when the pair needs more than its capsules.
        E: (m - 1,) how far the bodies' points move relative to each other along the joint motion from a
            sample to the next, seen from both ends: the smaller of M's step and the displacement plus
            twice the sagitta (:func:`sagittas`), so that the motion between samples k and k + 1 keeps at
            least (d_k + d_{k+1} - E_k) / 2.
        found: its measurements, by sample.
    """

    def __init__(self, pair: Pair, sphere: np.ndarray, M: np.ndarray, dq: np.ndarray) -> None:
        self.pair, self.lower, self.M, self.dq = pair, sphere, M, dq
        self.E = np.diff(M)
        self.capsules = False
        self.relative: _Relative | None = None
        self.S: np.ndarray | None = None
        self.found: dict[int, Distance] = {}
        self._measured = np.full(len(M), -math.inf)  # (m,) the distances of ``found`` (-inf: none)
        self._bound: np.ndarray | None = None

    def bound(self) -> np.ndarray:
        """Lower bounds at every sample, each carried to the others by the motion (cached until tightened)."""
        if self._bound is None:
            bound = np.maximum(self.lower, self._measured)
            steps = self.steps()
            forward = np.maximum.accumulate(bound + steps) - steps
            backward = np.maximum.accumulate((bound - steps)[::-1])[::-1] + steps
            self._bound = np.maximum(bound, np.maximum(forward, backward))
        return self._bound

    def steps(self) -> np.ndarray:
        """(m,) the motion bound the lower bounds are carried along: S where made, else M [m]."""
        return self.S if self.S is not None else self.M

    def measure(self, i: int, found: Distance) -> None:
        """Keep a measurement at sample i; the cached bounds take its cone ``d - |steps - steps[i]|``.

        The same numbers as :meth:`bound` made afresh: ``fl(x - s)`` and ``fl(x + s)`` are monotone in
        x, so the running maxima there commute with them, and a bound raised at one sample raises the
        others by its own cone alone. A measurement below the one it replaces (a hull's bound measured
        again) lowers a bound: then they are made afresh.
        """
        seen = self.found.get(i)
        self.found[i] = found
        d = found.distance_m
        raised = seen is None or seen.distance_m <= d
        self._measured[i] = d
        if self._bound is None:
            return
        if not raised:
            self._bound = None
            return
        bound, steps = self._bound, self.steps()
        s_i = steps[i]
        np.maximum(bound[i:], (d + s_i) - steps[i:], out=bound[i:])
        np.maximum(bound[:i + 1], (d - s_i) + steps[:i + 1], out=bound[:i + 1])
        bound[i] = max(bound[i], d)

    def tightened(self) -> None:
        self._bound = None


class _Block:
    """The samples s .. e of a check (consecutive blocks share a sample) and their joint frames: each pair
    proven clear by bounds or walked (:meth:`_clear`), then, for the least clearance, measured where its
    bound is least until no bound is below the least found (:meth:`_least`)."""

    def __init__(self, walk: _Walk, s: int, e: int) -> None:
        self.walk, self.s = walk, s
        self.R, self.P = walk.model.robot.joint_frames(walk.q[s:e + 1])
        dq = np.abs(np.diff(walk.q[s:e + 1], axis=0))
        pairs = walk.model.pairs
        spheres = sphere_bounds(pairs, self.R, self.P)
        M = np.zeros((len(dq) + 1, len(pairs)))  # each pair's motion bound from the first sample, one column each
        np.cumsum(dq @ np.array([pair.weights for pair in pairs]).T, axis=0, out=M[1:])
        self.states = [_PairState(pair, spheres[pair], M[:, p], dq) for p, pair in enumerate(pairs)]
        self.states.sort(key=lambda st: float(st.lower.min()))
        self.k = s + np.arange(e - s + 1)
        self.ends: dict[int, np.ndarray] = {}  # capsule ends placed at the block's samples, by shape
        self.placed: dict[int, dict[int, coal.Transform3s]] = {}  # shapes placed for coal, by sample and shape

    def check(self) -> None:
        unproven = [st for st in self.states if not self._proven(st)]
        capsules = capsule_bounds([st.pair for st in unproven], self.R, self.P, self.ends)  # in one pass
        for st in unproven:
            st.lower = np.maximum(st.lower, capsules[st.pair])
            st.capsules = True
            st.tightened()
        for st in unproven:
            self._clear(st)
        if self.walk.exact:
            self._least()

    # -- measurements ------------------------------------------------------------------------------------

    def sample(self, st: _PairState, i: int, enough: float, gain: float = _PLANE_GAIN_M) -> float:
        """The pair's distance at local sample i (``enough``: a bound past this will do), measured once;
        a measurement more than ``gain`` above its bound adds its separating planes to the pair's bounds."""
        seen = st.found.get(i)
        if seen is None or (not seen.exact and seen.distance_m < enough):
            walk, k = self.walk, self.s + i
            gaps: list[ShapeGap] = []
            found = walk.model.pair_distance(st.pair, self.R[i], self.P[i], enough, self.placed.setdefault(i, {}),
                                             gaps)
            if k == 0 and walk.start and found.distance_m > 0 and walk.model.inside_mesh(st.pair, self.R[i],
                                                                                         self.P[i]):
                found = Distance(-math.inf, found.point_a, found.point_b)
            st.measure(i, found)
            walk.record(st.pair, k, found)
            if found.exact and found.distance_m - st.lower[i] > gain:
                self._tighten(st, i, gaps)
        return st.found[i].distance_m

    def _tighten(self, st: _PairState, i: int, gaps: list[ShapeGap]) -> None:
        """Raise the pair's lower bounds near sample i by the separating planes of a measurement there
        (unless the pair has used up its planes)."""
        self._relative(st)
        assert st.relative is not None
        if st.relative.planes < _PLANES + len(st.lower) // _PLANE_SPAN:
            planes = st.relative.plane_bounds(i, gaps)
            if planes is not None:
                lo, bounds = planes
                st.lower = st.lower.copy()
                window = st.lower[lo:lo + len(bounds)]
                np.maximum(window, bounds, out=window)
                st.tightened()

    def _relative(self, st: _PairState) -> None:
        if st.relative is None:
            st.relative = _Relative(st.pair, self.R, self.P)
            steps, dM = st.relative.steps(), np.diff(st.M)
            st.S = np.concatenate([[0.0], np.cumsum(np.minimum(dM, steps))])
            st.E = np.minimum(dM, steps + 2.0 * sagittas(st.dq, st.pair.arms))
            st.tightened()

    def _capsules(self, st: _PairState) -> None:
        if not st.capsules:
            st.lower = np.maximum(st.lower, capsule_bounds([st.pair], self.R, self.P, self.ends)[st.pair])
            st.capsules = True
            st.tightened()

    def between(self, st: _PairState, x: float) -> float:
        """The pair's distance at local position x between samples (joint values interpolated)."""
        walk = self.walk
        i = min(math.floor(x), len(self.R) - 2)
        f = x - i
        q = walk.q[self.s + i] + f * (walk.q[self.s + i + 1] - walk.q[self.s + i])
        R, P = walk.model.robot.joint_frames(q[None])
        limit = walk.c - BETWEEN_TOLERANCE_M / 2
        d = walk.model.pair_distance(st.pair, R[0], P[0], limit).distance_m
        if d < limit:
            walk.contact(st.pair, Contact(d, st.pair.names, self.s + i + walk.offset, f))
        return d

    # -- clear: every sample at least the clearance, the motion between at least the floor ---------------

    def _proven(self, st: _PairState) -> bool:
        """Whether its bounds alone prove the pair over the block."""
        lower, walk = st.bound(), self.walk
        return bool(lower.min() >= walk.c and (len(lower) == 1 or (
            (lower[:-1] + lower[1:] - st.E) / 2).min() >= walk.floor))

    def _clear(self, st: _PairState) -> None:
        """Prove or measure one pair over the block: spheres, capsules, the relative displacement and a
        first separating plane, then the walk only where they fall short."""
        if self._proven(st):
            return
        self._capsules(st)
        if self._proven(st):
            return
        self._relative(st)
        if not st.found and st.lower.min() < self.walk.c + _PLANE_GAIN_M:  # a first plane where the bound is least
            self.sample(st, int(np.argmin(st.lower)), self.walk.c)
        bound = st.bound()
        short = bound < self.walk.c
        if len(bound) == 1:
            if short[0]:
                self.sample(st, 0, self.walk.c)
            return
        gap = (bound[:-1] + bound[1:] - st.E) / 2 < self.walk.floor  # the motion to the next sample unproven
        for a, b in _runs(gap | short[:-1] | short[1:]):  # intervals a .. b
            self._walk(st, a, b + 1)

    def _walk(self, st: _PairState, a: int, end: int) -> None:
        """Prove samples a .. end and the motion between them, interval by interval: a measured sample's
        distance carries along S to the samples after it; an interval whose two ends (measured if need
        be) cannot prove it through E is sub-sampled (:meth:`_inside`)."""
        walk, S, E, base = self.walk, st.S, st.E, st.bound()
        assert S is not None
        c, floor = walk.c, walk.floor
        anchor = (-math.inf, 0.0)  # the last distance measured and S there

        def bound(k: int) -> float:
            return max(float(base[k]), anchor[0] - abs(S[k] - anchor[1]))

        def measure(k: int) -> float:
            nonlocal anchor
            d = self.sample(st, k, c)
            anchor = (d, float(S[k]))
            return d

        d0 = bound(a)
        if d0 < c:
            d0 = measure(a)
        for k in range(a, end):
            d1 = bound(k + 1)
            if d1 >= c and (d0 + d1 - E[k]) / 2 >= floor:
                d0 = d1
                continue
            exact0 = k in st.found and st.found[k].exact
            if not exact0 and (d0 + d1 - E[k]) / 2 < floor:
                d0 = measure(k)
            if d1 < c or (d0 + d1 - E[k]) / 2 < floor:
                d1 = measure(k + 1)
            if min(d0, d1) >= floor and (d0 + d1 - E[k]) / 2 < floor:
                self._inside(st, k, d0, d1)
            d0 = d1

    def _inside(self, st: _PairState, k: int, d0: float, d1: float) -> None:
        """The motion from sample k to k + 1 sub-sampled by conservative advancement along M (which bounds
        the path itself): each sub-sample proves the stretch its distance over the floor covers."""
        walk, floor = self.walk, self.walk.floor
        length = float(st.M[k + 1] - st.M[k])
        right = length - (d1 - floor)  # sample k + 1 proves the motion from here on
        m, v = 0.0, d0
        while m + (v - floor) < right:
            m += max(v - floor, BETWEEN_TOLERANCE_M / 2)
            if m >= length:
                return
            v = self.between(st, k + m / length)
            if v < walk.c - BETWEEN_TOLERANCE_M / 2:
                return  # too close between samples (recorded)

    # -- least: each span's closest approach to within EXACT_M -------------------------------------------

    def _least(self) -> None:
        """Each span's least distance: measure where the least bound of any pair is, tightening that pair,
        until no pair's bound anywhere in the span is below the least measured less EXACT_M; then up to
        :data:`_REFINE` more where the least bound is, each adding its planes: tight near their
        measurement, they lead to the least sample distance itself."""
        walk = self.walk
        first, last = walk.first[self.k], walk.last[self.k]
        for span in np.unique(np.concatenate([first, last])):
            if span >= len(walk.least):
                continue
            inside = np.nonzero((first == span) | (last == span))[0]
            local = slice(int(inside[0]), int(inside[-1]) + 1)  # a span's samples are consecutive
            lows = {id(st): _span_low(st, local) for st in self.states}  # each pair's least bound, and where
            states = {id(st): st for st in self.states}
            refine = _REFINE
            while True:
                key = min(lows, key=lambda s: lows[s][0])
                low, j = lows[key]
                within = low >= walk.best[span] - EXACT_M
                if within and refine == 0:
                    break
                st, i = states[key], local.start + j
                if not st.capsules:
                    self._capsules(st)
                elif st.relative is None:
                    self._relative(st)
                elif i in st.found and st.found[i].exact:
                    break  # measured exactly: its bound is its distance (round-off)
                else:
                    refine -= 1 if within else 0
                    self.sample(st, i, walk.best[span] - EXACT_M, gain=0.0 if within else EXACT_M / 2)
                lows[key] = _span_low(st, local)


def _span_low(st: _PairState, local: slice) -> tuple[float, int]:
    """A pair's least bound over a span's samples, and where (relative to the span's first sample)."""
    bound = st.bound()[local]
    j = int(np.argmin(bound))
    return float(bound[j]), j


class _Relative:
    """One pair over a block: the body on the later joint (``b``) placed in the other's joint frame (``a``:
    the cell, or the body nearer the base) at every sample, for separating-plane bounds.

    A measurement's closest points of each pair of shapes give a plane between them; at the samples
    near it the least of ``n . x`` over b's shape less the most over a's (each a support function,
    :func:`support`) bounds that pair's distance from below (for any unit n), exactly at the sample
    measured and to second order in the turn beside it (a tool over a table: exactly while it
    slides). The least over the shape pairs bounds the bodies'.
    """

    def __init__(self, pair: Pair, rotations: np.ndarray, origins: np.ndarray) -> None:
        a, b = pair.a, pair.b
        self.swapped = a.joint is not None and (b.joint is None or b.joint < a.joint)
        if self.swapped:
            a, b = b, a
        assert b.joint is not None
        n = len(rotations)
        self.a, self.b = a, b
        self.Ra = rotations[:, a.joint] if a.joint is not None else np.broadcast_to(np.eye(3), (n, 3, 3))
        self.pa = origins[:, a.joint] if a.joint is not None else np.zeros((n, 3))
        Ra_t = np.swapaxes(self.Ra, 1, 2)
        self.R = Ra_t @ rotations[:, b.joint]  # (N, 3, 3): b's frame in a's
        self.t = (Ra_t @ (origins[:, b.joint] - self.pa)[:, :, None])[:, :, 0]  # (N, 3)
        self.planes = 0

    def steps(self) -> np.ndarray:
        """How far any point of b moves relative to a from each sample to the next (N - 1,) [m]: its frame's
        displacement plus the turn [rad] times b's extent from its frame's origin."""
        turn = rotation_angles(self.R[:-1], self.R[1:])
        return np.linalg.norm(np.diff(self.t, axis=0), axis=1) + turn * self.b.extent_m

    def plane_bounds(self, i: int, gaps: list[ShapeGap]) -> tuple[int, np.ndarray] | None:
        """Lower bounds of the bodies' distance at the samples lo .. lo + len - 1 within
        :data:`_PLANE_REACH` of sample i, from the planes of a measurement's shape pairs there: (lo,
        bounds); None where a shape pair gave no plane (touching shapes, or not all measured)."""
        if len(gaps) != len(self.a.geoms) * len(self.b.geoms):
            return None
        lo, hi = max(i - _PLANE_REACH, 0), min(i + _PLANE_REACH + 1, len(self.R))
        bounds = None
        for gap in gaps:
            ia, ib, point_a, point_b = gap.a, gap.b, gap.point_a, gap.point_b
            if self.swapped:
                ia, ib, point_a, point_b = ib, ia, point_b, point_a
            normal = self.Ra[i].T @ (point_b - point_a)  # from a towards b, in a's frame
            length = float(np.linalg.norm(normal))
            if gap.distance_m <= 0.0 or length < 1e-9:
                return None
            plane = self._bounds(normal / length, self.a.geoms[ia], self.b.geoms[ib], slice(lo, hi))
            bounds = plane if bounds is None else np.minimum(bounds, plane)
        self.planes += 1
        assert bounds is not None
        return lo, bounds

    def _bounds(self, n: np.ndarray, ga: Geom, gb: Geom, at: slice) -> np.ndarray:
        high_a = float(n @ ga.translation - support(ga, -(ga.rotation.T @ n)[None])[0])
        kind, sizes, corners = _support_form(gb)
        return _low_b(self.R[at], self.t[at], n, gb.translation, gb.rotation, kind, sizes, corners) - high_a


_SPHERE, _BOX, _CYLINDER, _CORNERS = 0, 1, 2, 3
_NO_CORNERS = np.zeros((0, 3))


def _support_form(g: Geom) -> tuple[int, np.ndarray, np.ndarray]:
    """A shape's support function as :func:`_low_b` takes it: a kind, its sizes and (meshes) the hull's corners."""
    shape = g.geometry
    if isinstance(shape, coal.Sphere):
        return _SPHERE, np.array([float(shape.radius), 0.0, 0.0]), _NO_CORNERS
    if isinstance(shape, coal.Box):
        return _BOX, np.array(shape.halfSide, dtype=float), _NO_CORNERS
    if isinstance(shape, coal.Cylinder):
        return _CYLINDER, np.array([float(shape.halfLength), float(shape.radius), 0.0]), _NO_CORNERS
    assert g.corners is not None
    return _CORNERS, np.zeros(3), np.ascontiguousarray(g.corners, dtype=float)


@jit
def _low_b(R: np.ndarray, t: np.ndarray, n: np.ndarray, translation: np.ndarray, rotation: np.ndarray, kind: int,
           sizes: np.ndarray, corners: np.ndarray) -> np.ndarray:
    """The least of ``n . x`` (M,) over a shape of b at each sample, in a's frame: b's frame at (R (M, 3, 3),
    t (M, 3)), the shape at (``rotation``, ``translation``) in it; :func:`~singplan.kinematics.collision.support`
    of the direction in the shape's frame."""
    out = np.empty(len(t))
    nb = np.empty(3)
    d = np.empty(3)
    for s in range(len(t)):
        for j in range(3):
            nb[j] = n[0] * R[s, 0, j] + n[1] * R[s, 1, j] + n[2] * R[s, 2, j]
        for j in range(3):
            d[j] = nb[0] * rotation[0, j] + nb[1] * rotation[1, j] + nb[2] * rotation[2, j]
        if kind == _SPHERE:
            low = -sizes[0] * math.sqrt(d[0] * d[0] + d[1] * d[1] + d[2] * d[2])
        elif kind == _BOX:
            low = -(abs(d[0]) * sizes[0] + abs(d[1]) * sizes[1] + abs(d[2]) * sizes[2])
        elif kind == _CYLINDER:
            low = -sizes[0] * abs(d[2]) - sizes[1] * math.hypot(d[0], d[1])
        else:
            low = math.inf
            for v in range(len(corners)):
                low = min(low, d[0] * corners[v, 0] + d[1] * corners[v, 1] + d[2] * corners[v, 2])
        out[s] = (t[s, 0] * n[0] + t[s, 1] * n[1] + t[s, 2] * n[2]
                  + nb[0] * translation[0] + nb[1] * translation[1] + nb[2] * translation[2] + low)
    return out


def sagittas(dq: np.ndarray, arms: np.ndarray) -> np.ndarray:
    """How far (N,) any body point strays from the straight line between its positions at two samples while
    the joints move straight from one sample to the next (dq (N, n): the joint steps, ``arms`` (n,): its
    points' distances from the joints' origins at most [m], 0 for joints that do not move it).

    Along q(t) = q_k + t dq a point's acceleration is, over the joints j that move it (axes a_j through
    origins o_j), sum_j dq_j [d(a_j)/dt x (p - o_j) + a_j x (dp/dt - d(o_j)/dt)], at most
    3 (sum_j |dq_j|)(sum_j |dq_j| arm_j); a curve with acceleration at most A strays at most A / 8 from its
    chord over t in [0, 1].
    """
    moving = (arms > 0).astype(float)
    return 3.0 * (dq @ moving) * (dq @ arms) / 8.0


def _runs(flags: np.ndarray) -> list[tuple[int, int]]:
    """(first, last) index of each run of True in ``flags``."""
    if not flags.any():
        return []
    padded = np.concatenate([[False], flags, [False]]).astype(np.int8)
    edges = np.diff(padded)
    return list(zip(np.nonzero(edges == 1)[0].tolist(), (np.nonzero(edges == -1)[0] - 1).tolist(), strict=True))


def _triple(v: np.ndarray) -> tuple[float, float, float]:
    return float(v[0]), float(v[1]), float(v[2])


_ROWS = 200_000  # segment pairs measured at once by capsule_bounds (~1 kB of temporaries each)


def sphere_bounds(pairs: Sequence[Pair], rotations: np.ndarray, origins: np.ndarray) -> dict[Pair, np.ndarray]:
    """A lower bound of each pair's distance at each sample (N,) from one sphere enclosing each body:
    cheap enough for every pair at every sample, and enough for the pairs that stay far apart.
    ``rotations`` (N, J, 3, 3), ``origins`` (N, J, 3): the joint frames."""
    bodies = list({id(b): b for pair in pairs for b in (pair.a, pair.b)}.values())
    index = {id(b): i for i, b in enumerate(bodies)}
    centres = np.empty((len(bodies), len(rotations), 3))  # (B, N, 3) in the base frame
    for i, body in enumerate(bodies):
        centre = body.sphere[0]
        centres[i] = centre if body.joint is None else rotations[:, body.joint] @ centre + origins[:, body.joint]
    a = np.array([index[id(pair.a)] for pair in pairs])
    b = np.array([index[id(pair.b)] for pair in pairs])
    radii = np.array([pair.a.sphere[1] + pair.b.sphere[1] for pair in pairs])
    gap = np.linalg.norm(centres[a] - centres[b], axis=2) - radii[:, None]  # (P, N)
    return {pair: gap[p] for p, pair in enumerate(pairs)}


def capsule_bounds(pairs: Sequence[Pair], rotations: np.ndarray, origins: np.ndarray,
                   ends: dict[int, np.ndarray] | None = None) -> dict[Pair, np.ndarray]:
    """A lower bound of each pair's distance at each sample (N,): the least distance of the capsules
    enclosing their shapes, every shape pair of the pairs in a few numpy passes. ``ends``: the capsules'
    axis ends already placed at these samples, by shape (filled in as they are made)."""
    n = len(rotations)
    ends = ends if ends is not None else {}  # id(geom) -> (2, N, 3): its capsule's axis ends in the base frame
    rows: list[tuple[int, int, int]] = []  # (pair index, id of a's shape, id of b's shape)
    radii: list[float] = []
    for p, pair in enumerate(pairs):
        for body in (pair.a, pair.b):
            for g in body.geoms:
                if id(g) not in ends:
                    ends[id(g)] = _capsule_ends(g.segment, body.joint, rotations, origins)
        for ga in pair.a.geoms:
            for gb in pair.b.geoms:
                rows.append((p, id(ga), id(gb)))
                radii.append(ga.radius_m + gb.radius_m)
    out = np.full((len(pairs), n), math.inf)
    step = max(1, _ROWS // max(n, 1))
    for c in range(0, len(rows), step):
        chunk = rows[c:c + step]
        a = np.stack([ends[ga] for _, ga, _ in chunk], axis=1).reshape(2, -1, 3)  # (2, len(chunk) * N, 3)
        b = np.stack([ends[gb] for _, _, gb in chunk], axis=1).reshape(2, -1, 3)
        d = segment_distances(a[0], a[1], b[0], b[1]).reshape(len(chunk), n) - np.array(radii[c:c + step])[:, None]
        np.minimum.at(out, np.array([p for p, _, _ in chunk]), d)
    return {pair: out[p] for p, pair in enumerate(pairs)}


def _capsule_ends(segment: np.ndarray, joint: int | None, rotations: np.ndarray, origins: np.ndarray) -> np.ndarray:
    """A capsule axis's ends (2, N, 3) in the base frame."""
    if joint is None:
        return np.broadcast_to(segment[:, None, :], (2, len(rotations), 3))
    return np.moveaxis(rotations[:, joint] @ segment.T, 2, 0) + origins[:, joint]


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
