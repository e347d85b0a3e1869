"""What a checker measures on timed samples, and the margins an accepted timing keeps under the limits:
joint speed and acceleration by forward differences, the end steps of a move at rest, the worst
sample, and joint jerk by third differences (seams included)."""

from __future__ import annotations

import numpy as np

SPEED_MARGIN = 0.999  # ratios the samples must stay under
ACCEL_MARGIN = 0.995
TCP_MARGIN = 0.999  # an accepted sample step covers at most this many periods of the TCP clock (bound.py)
TORQUE_MARGIN = 0.995
JERK_MARGIN = 0.995


def difference_ratios(q: np.ndarray, period_s: float, vmax: np.ndarray, amax: np.ndarray
                      ) -> tuple[np.ndarray, np.ndarray]:
    """Of samples q (K+1, n), K >= 1: each step's largest |qd| / vmax (K,) and each inner sample's
    largest |qdd| / amax (K-1,), by forward differences (the checker's definition); ``vmax`` (n,)
    or one row a step (K, n)."""
    qd = np.diff(q, axis=0) / period_s
    return np.max(np.abs(qd) / vmax, axis=1), np.max(np.abs(np.diff(qd, axis=0)) / period_s / amax, axis=1)


def sample_ratios(q: np.ndarray, period_s: float, vmax: np.ndarray, amax: np.ndarray) -> tuple[float, float]:
    """Largest |qd|/vmax and |qdd|/amax by finite differences of samples q (K+1, n)."""
    if len(q) < 2:
        return 0.0, 0.0
    speed, accel = difference_ratios(q, period_s, vmax, amax)
    return float(np.max(speed)), float(np.max(accel, initial=0.0))


def end_step_ratio(q: np.ndarray, period_s: float, amax: np.ndarray) -> float:
    """Largest first or last step of samples q (K+1, n) over amax * period^2 / 2.

    A move starts and ends at rest; from rest, an acceleration within amax covers at most
    amax * period^2 / 2 in one period. Keeping both end steps under that bound keeps the second
    difference across any seam (the end of one move, the start of the next, both at rest on the
    shared sample) within amax whatever the neighbouring move does, and each end "at rest" as
    the checker defines it (a step no longer than amax * period^2).
    """
    if len(q) < 2:
        return 0.0
    steps = np.maximum(np.abs(q[1] - q[0]), np.abs(q[-1] - q[-2]))
    return float(np.max(2.0 * steps / (amax * period_s**2)))


def worst_sample(q: np.ndarray, period_s: float, vmax: np.ndarray, amax: np.ndarray) -> int:
    """The sample of q (K, n), at rest before and after, whose speed or acceleration is furthest over its limit
    (end steps included)."""
    # speed: step k -> k+1 of the padded samples; accel: at q[k]
    speed, accel = difference_ratios(np.concatenate([q[:1], q, q[-1:]]), period_s, vmax, amax)
    accel[[0, -1]] *= 2.0  # an end step's bound is amax * period^2 / 2 (end_step_ratio)
    over = np.maximum(accel, np.maximum(speed[:-1], speed[1:]))
    return int(np.argmax(over))


def jerk_ratio(q: np.ndarray, period_s: float, jmax: np.ndarray) -> float:
    """Largest joint jerk of samples q (K+1, n) over jmax, by third differences / period^3, seams included.

    A move starts and ends at rest on a sample, its neighbour too. The third differences across a
    seam mix both moves' end steps: with first steps d1, d2 of this move and the last step e of the
    neighbour, d2 - 2 d1 + e and d1 - 2 e + e'. A move that keeps |d1| <= J P^3 / 6 and
    |d2 - 2 d1| <= 5/6 J P^3 (what any law with zero end acceleration and jerk within J gives)
    keeps both within J P^3 whatever its neighbour does under the same rule.
    """
    steps = np.diff(q, axis=0)
    if len(steps) == 0:
        return 0.0
    unit = jmax * period_s**3
    worst = float(np.max(np.abs(steps[[0, -1]]) / (unit / 6.0)))
    if len(steps) >= 2:
        second = np.abs(np.stack([steps[1] - 2.0 * steps[0], steps[-2] - 2.0 * steps[-1]]))
        worst = max(worst, float(np.max(second / (unit * 5.0 / 6.0))))
    return max(worst, third_difference_ratio(q, period_s, jmax))


_CHUNK_SAMPLES = 65536  # bounds the temporaries of a long trajectory's differences


def third_difference_ratio(q: np.ndarray, period_s: float, jmax: np.ndarray) -> float:
    """Largest |third difference| / (jmax period^3) of samples q (K, n), as a checker measures it.

    A chunk at a time; chunks overlap by the three samples a third difference spans, so the maximum is exact.
    """
    worst = 0.0
    for k in range(0, max(len(q) - 3, 0), _CHUNK_SAMPLES):
        chunk = np.diff(q[k:k + _CHUNK_SAMPLES + 3], n=3, axis=0)
        worst = max(worst, float(np.max(np.abs(chunk) / (jmax * period_s**3))))
    return worst
