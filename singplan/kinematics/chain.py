"""The serial chain's transforms composed sample by sample, compiled, with numpy's own numbers.

:class:`~singplan.kinematics.robot.Robot` composes the chain (joint placements, turns about the
joint axes, the tool) for many samples at once. In numpy each 3 x 3 product of a stack is one BLAS
call (``gemm`` or ``gemv`` per sample), which makes that composition a few microseconds a sample
and the largest cost of planning. The kernels here do the same products in one compiled loop.

They must give numpy's numbers to the last bit: every durations, sample and figure singplan writes
follows from them. BLAS forms a 3 x 3 product with fused multiply-adds in an order of its own; the
kernels follow the order of the OpenBLAS kernels singplan is installed with (``gemv``: k = 0, 1, 2;
``gemm``: k = 1, 0, 2, each term fused into the sum before it). Another BLAS, or another CPU's kernel,
may sum otherwise, so :func:`faithful` compares the kernels with numpy on seeded random products once
per process, and :class:`~singplan.kinematics.robot.Robot` uses them only where they agree bit for
bit (numpy's products elsewhere). The turns about the axes are Rodrigues' formula with the sines and
cosines numpy computed, element by element as numpy forms them (no fused operation there).
"""

from __future__ import annotations

from functools import cache

import numpy as np

from singplan.kinematics.compiled import jit, jit_fused

_PROBE = 4096  # seeded random products compared with numpy's


@jit_fused
def _matvec(R: np.ndarray, t: np.ndarray, out: np.ndarray) -> None:
    """out (3,) = R (3, 3) @ t (3,), summed as BLAS gemv does."""
    for i in range(3):
        acc = R[i, 0] * t[0]
        acc = acc + R[i, 1] * t[1]
        acc = acc + R[i, 2] * t[2]
        out[i] = acc


@jit_fused
def _matmul(A: np.ndarray, B: np.ndarray, out: np.ndarray) -> None:
    """out (3, 3) = A (3, 3) @ B (3, 3), summed as BLAS gemm does."""
    for i in range(3):
        for j in range(3):
            acc = A[i, 1] * B[1, j]
            acc = acc + A[i, 0] * B[0, j]
            acc = acc + A[i, 2] * B[2, j]
            out[i, j] = acc


@jit
def _turn(sin: float, cos: float, k: np.ndarray, kk: np.ndarray, out: np.ndarray) -> None:
    """out (3, 3): the rotation ``I + sin K + (1 - cos) K^2`` about a unit axis (K its skew matrix)."""
    for a in range(3):
        for b in range(3):
            out[a, b] = ((1.0 if a == b else 0.0) + sin * k[a, b]) + (1.0 - cos) * kk[a, b]


@jit
def _tcp_chain(sin: np.ndarray, cos: np.ndarray, translations: np.ndarray, rotations: np.ndarray, ks: np.ndarray,
               kks: np.ndarray, axes: np.ndarray, tool_t: np.ndarray, tool_R: np.ndarray, joints: bool
               ) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """TCP positions (N, 3) and rotations (N, 3, 3); with ``joints`` each chain joint's origin (J, N, 3) and
    unit axis (J, N, 3) in the base frame. sin, cos (J, N): of each chain joint's angle per sample."""
    n_chain, n = sin.shape
    position, rotation = np.empty((n, 3)), np.empty((n, 3, 3))
    origins = np.empty((n_chain if joints else 0, n, 3))
    axes_base = np.empty((n_chain if joints else 0, n, 3))
    R, R2, T = np.empty((3, 3)), np.empty((3, 3)), np.empty((3, 3))
    p, y = np.empty(3), np.empty(3)
    for s in range(n):
        for a in range(3):
            p[a] = 0.0
            for b in range(3):
                R[a, b] = 1.0 if a == b else 0.0
        for j in range(n_chain):
            _matvec(R, translations[j], y)
            for a in range(3):
                p[a] = p[a] + y[a]
            _matmul(R, rotations[j], R2)
            if joints:
                _matvec(R2, axes[j], y)
                for a in range(3):
                    origins[j, s, a] = p[a]
                    axes_base[j, s, a] = y[a]
            _turn(sin[j, s], cos[j, s], ks[j], kks[j], T)
            _matmul(R2, T, R)
        _matvec(R, tool_t, y)
        _matmul(R, tool_R, R2)
        for a in range(3):
            position[s, a] = p[a] + y[a]
            for b in range(3):
                rotation[s, a, b] = R2[a, b]
    return position, rotation, origins, axes_base


@jit
def _joint_chain(sin: np.ndarray, cos: np.ndarray, translations: np.ndarray, rotations: np.ndarray,
                 ks: np.ndarray, kks: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Rotations (N, J + 1, 3, 3) and origins (N, J + 1, 3) of the base and each chain joint's frame."""
    n_chain, n = sin.shape
    rotation, origin = np.empty((n, n_chain + 1, 3, 3)), np.empty((n, n_chain + 1, 3))
    R2, T, y = np.empty((3, 3)), np.empty((3, 3)), np.empty(3)
    for s in range(n):
        for a in range(3):
            origin[s, 0, a] = 0.0
            for b in range(3):
                rotation[s, 0, a, b] = 1.0 if a == b else 0.0
        for j in range(n_chain):
            _matvec(rotation[s, j], translations[j], y)
            for a in range(3):
                origin[s, j + 1, a] = origin[s, j, a] + y[a]
            _matmul(rotation[s, j], rotations[j], R2)
            _turn(sin[j, s], cos[j, s], ks[j], kks[j], T)
            _matmul(R2, T, rotation[s, j + 1])
    return rotation, origin


@jit
def placed(R: np.ndarray, origin: np.ndarray, rotation: np.ndarray, translation: np.ndarray
           ) -> tuple[np.ndarray, np.ndarray]:
    """A frame (R (3, 3), origin (3,)) times a placement in it: ``R @ rotation`` and ``origin + R @ translation``,
    numpy's numbers where :func:`faithful` (a shape placed for coal, one sample at a time)."""
    out_R, out_t = np.empty((3, 3)), np.empty(3)
    _matmul(R, rotation, out_R)
    _matvec(R, translation, out_t)
    for a in range(3):
        out_t[a] = origin[a] + out_t[a]
    return out_R, out_t


class ChainArrays:
    """A chain's constant arrays, read from Pinocchio once: per chain joint its placement in its parent's
    frame (translation (J, 3), rotation (J, 3, 3)), unit axis (J, 3), skew matrix K and K @ K (J, 3, 3)
    (numpy's product, as the numpy composition forms it), q index (J,); the TCP in the last joint's frame."""

    def __init__(self, translations: np.ndarray, rotations: np.ndarray, axes: np.ndarray, ks: np.ndarray,
                 iqs: list[int], tool_t: np.ndarray, tool_R: np.ndarray) -> None:
        self.translations = np.ascontiguousarray(translations, dtype=float)
        self.rotations = np.ascontiguousarray(rotations, dtype=float)
        self.axes = np.ascontiguousarray(axes, dtype=float)
        self.ks = np.ascontiguousarray(ks, dtype=float)
        self.kks = np.array([k @ k for k in ks])
        self.iqs = iqs
        self.tool_t, self.tool_R = np.ascontiguousarray(tool_t, dtype=float), np.ascontiguousarray(tool_R, dtype=float)

    def angles(self, q: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """sin and cos (J, N) of each chain joint's angle, each column's as numpy gives it for ``q[:, iq]``."""
        return (np.array([np.sin(q[:, iq]) for iq in self.iqs]).reshape(len(self.iqs), len(q)),
                np.array([np.cos(q[:, iq]) for iq in self.iqs]).reshape(len(self.iqs), len(q)))

    def tcp(self, q: np.ndarray, joints: list[tuple[int, np.ndarray, np.ndarray]] | None
            ) -> tuple[np.ndarray, np.ndarray]:
        """TCP positions (N, 3) and rotations (N, 3, 3) of samples q (N, n); with ``joints`` each chain
        joint's (q index, origin (N, 3), unit axis (N, 3)) appended, as ``Robot._tcp_chunk`` gives them."""
        sin, cos = self.angles(q)
        position, rotation, origins, axes = _tcp_chain(sin, cos, self.translations, self.rotations, self.ks, self.kks,
                                                       self.axes, self.tool_t, self.tool_R, joints is not None)
        if joints is not None:
            joints.extend((iq, origins[j], axes[j]) for j, iq in enumerate(self.iqs))
        return position, rotation

    def kinematics(self, q: np.ndarray, rows: int, n: int) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """TCP positions (N, 3), rotations (N, 3, 3) and the Jacobian's first ``rows`` rows (N, rows, n) of
        samples q (N, n), as ``Robot.tcp_kinematics`` forms them in numpy (each column ``axis x arm``
        with the same roundings: no fused products)."""
        sin, cos = self.angles(q)
        position, rotation, origins, axes = _tcp_chain(sin, cos, self.translations, self.rotations, self.ks, self.kks,
                                                       self.axes, self.tool_t, self.tool_R, True)
        return position, rotation, _jacobian(position, origins, axes, np.array(self.iqs, dtype=np.int64), rows, n)

    def frames(self, q: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Rotations (N, J + 1, 3, 3) and origins (N, J + 1, 3) of the base and the joint frames."""
        sin, cos = self.angles(q)
        return _joint_chain(sin, cos, self.translations, self.rotations, self.ks, self.kks)


@jit
def _jacobian(position: np.ndarray, origins: np.ndarray, axes: np.ndarray, iqs: np.ndarray, rows: int,
              n: int) -> np.ndarray:
    """Jacobian rows (N, rows, n): column iq of each chain joint ``(axis x (p_tcp - origin), axis)``."""
    samples = position.shape[0]
    out = np.zeros((samples, rows, n))
    for j in range(len(iqs)):
        iq = iqs[j]
        for s in range(samples):
            a0 = position[s, 0] - origins[j, s, 0]
            a1 = position[s, 1] - origins[j, s, 1]
            a2 = position[s, 2] - origins[j, s, 2]
            x0, x1, x2 = axes[j, s, 0], axes[j, s, 1], axes[j, s, 2]
            out[s, 0, iq] = x1 * a2 - x2 * a1
            out[s, 1, iq] = x2 * a0 - x0 * a2
            out[s, 2, iq] = x0 * a1 - x1 * a0
            for r in range(rows - 3):
                out[s, 3 + r, iq] = axes[j, s, r]
    return out


@cache
def faithful() -> bool:
    """Whether the kernels' products are numpy's here, bit for bit (seeded random stacks of each kind the
    chain composes: gemm with C- and Fortran-ordered right factors, gemv)."""
    rng = np.random.default_rng(24)
    A, B, t = rng.normal(size=(_PROBE, 3, 3)), rng.normal(size=(_PROBE, 3, 3)), rng.normal(size=3)
    F = np.asfortranarray(B[0])
    mm, mf, mv = _products(A, B, F, t)
    return bool(np.array_equal(mm, A @ B) and np.array_equal(mf, A @ F) and np.array_equal(mv, A @ t))


@jit
def _products(A: np.ndarray, B: np.ndarray, F: np.ndarray, t: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The kernels' A @ B, A @ F and A @ t of stacks A, B (N, 3, 3), F (3, 3), t (3,)."""
    mm, mf, mv = np.empty(A.shape), np.empty(A.shape), np.empty((A.shape[0], 3))
    for s in range(A.shape[0]):
        _matmul(A[s], B[s], mm[s])
        _matmul(A[s], F, mf[s])
        _matvec(A[s], t, mv[s])
    return mm, mf, mv
