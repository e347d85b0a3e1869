"""Angles: wrapping to (-pi, pi] and whole-turn shifts toward a reference (the one home).

Every wrap and every whole-turn shift of the package is written here once: numpy forms for
arrays, compiled scalar kernels for the per-sample loops of other modules (the OPW and UR
closed forms, the singular distances, the tracker). Those callers' cached kernels are keyed on
this file's digest too (:mod:`singplan.kinematics.compiled`): a change here compiles them again.
"""

from __future__ import annotations

import math

import numpy as np

from singplan.kinematics.compiled import jit

TWO_PI = 2.0 * math.pi


def _wrap_half_turn(angles: np.ndarray, turn: float) -> np.ndarray:
    """Angles moved by whole ``turn``s into (-turn / 2, turn / 2]."""
    wrapped = angles - turn * np.round(angles / turn)
    return np.where(wrapped <= -0.5 * turn, wrapped + turn, wrapped)


def wrap_to_pi(angles: np.ndarray) -> np.ndarray:
    """Wrap angles [rad] to the interval (-pi, pi]."""
    return _wrap_half_turn(np.asarray(angles, dtype=float), TWO_PI)


def wrap_deg(angles_deg: np.ndarray) -> np.ndarray:
    """Wrap angles [deg] to the interval (-180, 180]."""
    return _wrap_half_turn(np.asarray(angles_deg, dtype=float), 360.0)


def shifted_toward(angles: np.ndarray, reference: np.ndarray) -> np.ndarray:
    """Each angle [rad] moved by whole turns to the variant nearest its reference (broadcast)."""
    return angles + TWO_PI * np.round((reference - angles) / TWO_PI)


@jit
def wrap(angle: float) -> float:
    """An angle [rad] wrapped to (-pi, pi] (the compiled scalar form of :func:`wrap_to_pi`)."""
    wrapped = angle - TWO_PI * np.rint(angle / TWO_PI)
    return wrapped + TWO_PI if wrapped <= -math.pi else wrapped


@jit
def shift_toward(angle: float, reference: float) -> float:
    """``angle`` [rad] moved by whole turns to the variant nearest ``reference`` (scalar :func:`shifted_toward`)."""
    return angle + TWO_PI * np.rint((reference - angle) / TWO_PI)


@jit
def row_step(row: np.ndarray, reference: np.ndarray) -> float:
    """Max-norm joint step from ``reference`` (n,) to ``row`` (n,) moved by whole turns; inf if NaN."""
    d = 0.0
    for j in range(row.shape[0]):
        diff = abs(shift_toward(row[j], reference[j]) - reference[j])
        if math.isnan(diff):
            return np.inf
        d = max(d, diff)
    return d


@jit
def nearest_row(rows: np.ndarray, reference: np.ndarray) -> tuple[int, float]:
    """The row of ``rows`` (B, n) nearest ``reference`` by :func:`row_step`, and its step; ties keep the first."""
    best, best_step = 0, np.inf
    for r in range(rows.shape[0]):
        step = row_step(rows[r], reference)
        if step < best_step:
            best, best_step = r, step
    return best, best_step


@jit
def shift_row_into(row: np.ndarray, reference: np.ndarray, out: np.ndarray) -> None:
    """``out`` (n,) = ``row`` moved by whole turns next to ``reference``, joint by joint."""
    for j in range(row.shape[0]):
        out[j] = shift_toward(row[j], reference[j])


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
    m, n = candidates.shape[0], candidates.shape[2]
    best, dist, rows = np.empty((m, n)), np.full(m, np.inf), np.zeros(m, dtype=np.int64)
    for i in range(m):
        rows[i], dist[i] = nearest_row(candidates[i], reference[i])
        shift_row_into(candidates[i, rows[i]], reference[i], best[i])
    return best, dist, rows
