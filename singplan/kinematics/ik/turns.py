"""Whole-turn variants of IK branches inside the joint limits, and the distinct ones, compiled.

A revolute joint whose range exceeds +-180 deg reaches the same pose at ``q + 2 pi k`` for several
k: :func:`solve_all <singplan.kinematics.ik.solve.solve_all>` lists every such variant (no seed),
or the one nearest a seed, of each branch, then drops the rows that repeat an earlier one.
A UR arm (+-360 deg on five joints) has 32 variants a branch, 256 rows a pose: written with
numpy and itertools this cost milliseconds a pose; these loops cost microseconds.
"""

from __future__ import annotations

import math

import numpy as np

from singplan.kinematics.angles import TWO_PI, wrap
from singplan.kinematics.compiled import jit

_EDGE = 1e-12  # in turns: a variant this close outside a limit still counts as inside
_NEAREST_SLACK = 1e-9  # [rad]: the seeded variant may be this far outside a limit (then clipped)
_SAME_ABS, _SAME_REL = 1e-9, 1e-5  # rows within np.allclose(atol=1e-9) (rtol 1e-5) of an earlier one repeat it
# [rad]: more than a seeded variant's clip (_NEAREST_SLACK) and the round-off of a whole-turn shift
# (a few 1e-15 rad) can move two rows' difference
_APART_PAD = 1e-8


def inside_limits(rows: np.ndarray, branches: np.ndarray, lower: np.ndarray, upper: np.ndarray,
                  seed: np.ndarray | None, same_rad: float = 0.0) -> tuple[np.ndarray, np.ndarray]:
    """The distinct whole-turn variants of ``rows`` (B, n) [rad] inside [lower, upper] (n,), in order.

    Without a seed, every variant of each row, joints shifted independently (the first joint
    slowest); with a seed (n,), each row's variant nearest it joint by joint (a row none of whose
    shifts of some joint lies within 1e-9 rad of its limits gives none). Rows with NaN give
    none. A row within ``np.allclose`` (atol 1e-9, rtol 1e-5) of an earlier kept one is dropped.
    An unlimited joint (infinite limits) has one variant without a seed, its angle in (-pi, pi]
    (its other turns are the same solution: a seed picks the turn). With a seed, rows equal up to
    whole turns within ``same_rad`` in every joint are one solution (branches meet on a singular
    pose), the one nearest the seed (max norm; the first among equals) standing for them.

    Returns: joint values (M, n) and the ``branches`` (B,) entry each came from (M,).
    """
    q, origin = variants_inside(np.asarray(rows).reshape(len(branches), len(lower)), lower, upper, seed, same_rad)
    return q, np.asarray(branches)[origin]


def variants_inside(rows: np.ndarray, lower: np.ndarray, upper: np.ndarray, seed: np.ndarray | None,
                    same_rad: float = 0.0) -> tuple[np.ndarray, np.ndarray]:
    """:func:`inside_limits` of rows (B, n) numbered 0..B-1: joint values (M, n) and the row each came from (M,)."""
    rows = np.ascontiguousarray(rows, dtype=float)
    lo, hi = np.ascontiguousarray(lower, dtype=float), np.ascontiguousarray(upper, dtype=float)
    nearest = np.ascontiguousarray(seed if seed is not None else lo, dtype=float)
    q, origin = _inside(rows, lo, hi, nearest, seed is not None, same_rad)
    return q, origin


@jit
def _inside(rows: np.ndarray, lower: np.ndarray, upper: np.ndarray, seed: np.ndarray,
            seeded: bool, same_rad: float) -> tuple[np.ndarray, np.ndarray]:  # pragma: no cover - compiled
    """:func:`inside_limits` in one call (each compiled call's arrays cost microseconds to hand back)."""
    if seeded:
        q, origin, count = _nearest_variants(rows, lower, upper, seed)
        q, origin = q[:count], origin[:count]
        if _branches_apart(rows, q, max(_largest_gap(q), same_rad)):
            return q.copy(), origin.copy()
        keep = _distinct(q)
        q, origin = q[keep], origin[keep]
        keep = _distinct_turns(q, seed, same_rad)
    else:
        q, origin = _all_variants(rows, lower, upper)
        if _branches_apart(rows, q, _largest_gap(q)):
            return q, origin
        keep = _distinct(q)
    return q[keep], origin[keep]


@jit
def _largest_gap(q: np.ndarray) -> float:  # pragma: no cover - compiled
    """The widest gap (rad) two joint values of rows q (M, n) may have and still repeat one another."""
    largest = 0.0
    for value in q.flat:
        largest = max(largest, abs(value))
    return _SAME_ABS + _SAME_REL * largest


@jit
def _branches_apart(rows: np.ndarray, q: np.ndarray, gap: float) -> bool:  # pragma: no cover - compiled
    """Whether no two rows of q (M, n), each a whole-turn variant of a row of ``rows`` (B, n) moved
    by at most :data:`_NEAREST_SLACK` into the limits, can be within ``gap`` of each other in every
    joint (neither within allclose, nor equal up to whole turns within ``gap``): true when every two
    finite ``rows`` are further than ``gap`` apart, up to whole turns, in some joint (then so are
    all their variants: a variant's joint differs from its row's by whole turns, the clip and
    round-off, which :data:`_APART_PAD` covers), and ``gap`` is well under a turn (two variants of
    one row differ by whole turns in some joint). The common case: the repeat searches are skipped.
    """
    if not gap < 1.0:
        return False
    b, n = rows.shape
    for r in range(b):
        if not _finite(rows[r]):
            continue
        for e in range(r):
            if not _finite(rows[e]):
                continue
            near = True
            for j in range(n):
                if abs(wrap(rows[r, j] - rows[e, j])) > gap + _APART_PAD:
                    near = False
                    break
            if near:
                return False
    return True


@jit
def _finite(row: np.ndarray) -> bool:  # pragma: no cover - compiled
    for value in row:  # noqa: SIM110 - numba compiles no generator expressions
        if not math.isfinite(value):
            return False
    return True


@jit
def _shift_range(value: float, lower: float, upper: float) -> tuple[int, int]:  # pragma: no cover - compiled
    """The whole turns k with value + 2 pi k inside [lower, upper] (empty when k_lo > k_hi); an
    unlimited joint's one turn that puts it in (-pi, pi]."""
    if not (math.isfinite(lower) and math.isfinite(upper)):
        k = int(np.rint((wrap(value) - value) / TWO_PI))
        return k, k
    return math.ceil((lower - value) / TWO_PI - _EDGE), math.floor((upper - value) / TWO_PI + _EDGE)


@jit
def _all_variants(rows: np.ndarray, lower: np.ndarray, upper: np.ndarray
                  ) -> tuple[np.ndarray, np.ndarray]:  # pragma: no cover - compiled
    """Every variant of every finite row (M, n), and the row each came from (M,)."""
    b, n = rows.shape
    first = np.zeros((b, n), dtype=np.int64)
    count = np.zeros((b, n), dtype=np.int64)
    products = np.zeros(b, dtype=np.int64)
    for r in range(b):
        if not _finite(rows[r]):
            continue
        products[r] = 1
        for j in range(n):
            k_lo, k_hi = _shift_range(rows[r, j], lower[j], upper[j])
            first[r, j], count[r, j] = k_lo, max(k_hi - k_lo + 1, 0)
            products[r] *= count[r, j]
    out = np.empty((np.sum(products), n))
    origin = np.empty(len(out), dtype=np.int64)
    turn = np.empty(n, dtype=np.int64)
    m = 0
    for r in range(b):
        if products[r] == 0:
            continue
        turn[:] = 0
        for _ in range(products[r]):
            for j in range(n):
                out[m, j] = rows[r, j] + TWO_PI * (first[r, j] + turn[j])
            origin[m] = r
            m += 1
            j = n - 1  # the next turns, the last joint fastest, as itertools.product
            while j >= 0:
                turn[j] += 1
                if turn[j] < count[r, j]:
                    break
                turn[j] = 0
                j -= 1
    return out, origin


@jit
def _nearest_variants(rows: np.ndarray, lower: np.ndarray, upper: np.ndarray, seed: np.ndarray
                      ) -> tuple[np.ndarray, np.ndarray, int]:  # pragma: no cover - compiled
    """Each finite row's variant nearest the seed, joint by joint, clipped to the limits, in the first
    M rows of (B, n); the row each came from, in the first M of (B,); M."""
    b, n = rows.shape
    out = np.empty((b, n))
    origin = np.empty(b, dtype=np.int64)
    m = 0
    for r in range(b):
        found = _finite(rows[r])
        for j in range(n):
            if not found:
                break
            value = rows[r, j]
            k0 = int(np.rint((seed[j] - value) / TWO_PI))  # half to even, as Python's round
            best, best_gap = math.nan, math.inf
            for k in (k0 - 1, k0, k0 + 1):
                candidate = value + TWO_PI * k
                if lower[j] - _NEAREST_SLACK <= candidate <= upper[j] + _NEAREST_SLACK:
                    gap = abs(candidate - seed[j])
                    if gap < best_gap:
                        best, best_gap = candidate, gap
            found = best_gap < math.inf
            out[m, j] = min(max(best, lower[j]), upper[j])
        if found:
            origin[m] = r
            m += 1
    return out, origin, m


@jit
def _distinct(rows: np.ndarray) -> np.ndarray:  # pragma: no cover - compiled
    """Indices (in order) of the rows (M, n) not within allclose of an earlier kept row.

    Rows that close have close keys sum_j w_j q_j (any weights > 0; these keep whole-turn
    shifts of different joints from cancelling): each row is compared with the kept rows in a
    window of keys around its own, wider than any two such rows' keys can differ.
    """
    m, n = rows.shape
    if m == 0:
        return np.zeros(0, dtype=np.int64)
    key = np.zeros(m)
    window = 1e-9
    for j in range(n):
        weight = 1.0 / (1.0 + 0.618034 * j)
        largest = 0.0
        for i in range(m):
            key[i] += weight * rows[i, j]
            largest = max(largest, abs(rows[i, j]))
        window += 2.0 * weight * (_SAME_ABS + _SAME_REL * largest)
    order = np.argsort(key)
    place = np.empty(m, dtype=np.int64)
    for p in range(m):
        place[order[p]] = p
    kept = np.zeros(m, dtype=np.bool_)
    for k in range(m):
        repeat = False
        for step in (-1, 1):
            p = place[k] + step
            while not repeat and 0 <= p < m and abs(key[order[p]] - key[k]) <= window:
                e = order[p]
                repeat = e < k and kept[e] and _close(rows[k], rows[e])
                p += step
        kept[k] = not repeat
    return np.flatnonzero(kept)


@jit
def _close(row: np.ndarray, earlier: np.ndarray) -> bool:  # pragma: no cover - compiled
    for j in range(len(row)):  # noqa: SIM110 - numba compiles no generator expressions
        if not abs(row[j] - earlier[j]) <= _SAME_ABS + _SAME_REL * abs(earlier[j]):
            return False
    return True


@jit
def _distinct_turns(rows: np.ndarray, seed: np.ndarray, same_rad: float) -> np.ndarray:  # pragma: no cover - compiled
    """Indices (in order) of the rows (M, n) that differ from every other up to whole turns by more
    than ``same_rad`` in some joint; of rows equal up to whole turns, the one nearest ``seed`` (max
    norm; the first among equals) stands for them."""
    m = rows.shape[0]
    kept = np.empty(m, dtype=np.int64)
    count = 0
    for k in range(m):
        same = -1
        for i in range(count):
            if _turns_apart(rows[k], rows[kept[i]], same_rad):
                same = i
                break
        if same < 0:
            kept[count] = k
            count += 1
        elif _max_gap(rows[k], seed) < _max_gap(rows[kept[same]], seed):
            kept[same] = k
    return kept[:count]


@jit
def _turns_apart(a: np.ndarray, b: np.ndarray, same_rad: float) -> bool:  # pragma: no cover - compiled
    for j in range(len(a)):  # noqa: SIM110 - numba compiles no generator expressions
        if abs(wrap(a[j] - b[j])) > same_rad:
            return False
    return True


@jit
def _max_gap(a: np.ndarray, b: np.ndarray) -> float:  # pragma: no cover - compiled
    gap = 0.0
    for j in range(len(a)):
        gap = max(gap, abs(a[j] - b[j]))
    return gap
