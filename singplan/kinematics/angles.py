"""Angles: wrapping to (-pi, pi] and whole-turn shifts toward a reference (the one home).

numba caches a kernel against its own source file only, so a compiled loop elsewhere that needs
a whole-turn shift keeps its own scalar copy of the formula; tests check those copies against
:func:`nearest_shifted`.
"""

from __future__ import annotations

import math

import numpy as np

from singplan.kinematics.compiled import jit

TWO_PI = 2.0 * math.pi


def wrap_to_pi(angles: np.ndarray) -> np.ndarray:
    """Wrap angles [rad] to the interval (-pi, pi]."""
    wrapped = angles - TWO_PI * np.round(angles / TWO_PI)
    return np.where(wrapped <= -math.pi, wrapped + TWO_PI, wrapped)


def nearest_shifted(candidates: np.ndarray, reference: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """For each reference (..., n), its candidates (..., B, n) moved by whole turns toward it:
    the nearest (..., n), its max-norm distance (...) (inf where no row is finite) and its row (...)."""
    lead, (b, n) = reference.shape[:-1], candidates.shape[-2:]
    best, dist, k = _nearest_rows(np.ascontiguousarray(candidates, dtype=float).reshape(-1, b, n),
                                  np.ascontiguousarray(reference, dtype=float).reshape(-1, n))
    return best.reshape(*lead, n), dist.reshape(lead), k.reshape(lead)


@jit
def _nearest_rows(candidates: np.ndarray, reference: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """:func:`nearest_shifted` for candidates (M, B, n) and references (M, n); ties keep the first row."""
    m, b, n = candidates.shape
    best, dist, rows = np.empty((m, n)), np.full(m, np.inf), np.zeros(m, dtype=np.int64)
    for i in range(m):
        for r in range(b):
            d = 0.0
            for j in range(n):
                c = candidates[i, r, j]
                diff = abs(c + TWO_PI * np.rint((reference[i, j] - c) / TWO_PI) - reference[i, j])
                if math.isnan(diff):
                    d = np.inf
                    break
                d = max(d, diff)
            if d < dist[i]:
                dist[i], rows[i] = d, r
        for j in range(n):
            c = candidates[i, rows[i], j]
            best[i, j] = c + TWO_PI * np.rint((reference[i, j] - c) / TWO_PI)
    return best, dist, rows
