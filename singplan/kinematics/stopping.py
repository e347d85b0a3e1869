"""Stopping distance: how far the TCP would still travel if the robot braked now (SEEDS 002's glide path).

Definition (per output sample, joints ``q`` [rad], velocities ``qd`` [rad/s]): every joint
brakes at once at its full deceleration ``a_j`` (the task's ``limits.acceleration``) from its
current speed and then stays at rest,

    q_j(t) = q_j + qd_j tau_j - 1/2 a_j sign(qd_j) tau_j^2,   tau_j = min(t, |qd_j| / a_j),

and the stopping distance is the length of the TCP path that motion traces until the last joint
stops, at ``T = max_j |qd_j| / a_j``. Each joint stops independently (the path is not kept while
braking, as in a category 1 stop at full deceleration), so the figure says how far the TCP would
sweep, not how far along the programmed path.

The length is ``integral_0^T |v(t)| dt`` with the TCP velocity v = J(q(t)) qd(t): the braking
time is cut into equal steps so that no joint turns more than :data:`BRAKE_STEP_RAD` in one (one
step for a slow motion, at most :data:`MAX_BRAKE_STEPS`), each step uses the Jacobian at its
middle, and the steps are cut again where a joint stops; on every piece the joint velocities are
then linear in t and the integral of |v| is taken in closed form (:func:`mean_norm`), so a TCP
velocity that turns or reverses while the joints stop at different times is followed exactly.
On random states of three arms (every joint at up to its speed limit, in any direction) the
figure is within 1 % of a 10 000-step polyline of forward kinematics (tests/test_stopping.py
holds it to that). The joint velocities are the trajectory's ``qd`` (central differences of the
samples); the cost is one batch of Jacobians per sample for slow motion (a few us a sample).

``singplan check`` plans nothing; it shows :func:`path_estimate`: the same figure at every path
sample of each LIN / CIRC when the TCP moves at the programmed speed along it (slower where a
joint speed limit would bind, as the timing slows the path there), and for a PTP at the joints'
synchronised cruise speed. The real motion accelerates and brakes around these states, so the
estimate is an upper figure for LIN / CIRC cruising at speed, not a planned result.
"""

from __future__ import annotations

import numpy as np

from singplan.kinematics.robot import Robot

BRAKE_STEP_RAD = 0.025  # the most a joint turns between two Jacobians of the braking motion ...
MAX_BRAKE_STEPS = 64  # ... up to this many (1.6 rad: a joint braking from 5.7 rad/s at 10 rad/s^2; longer steps beyond)
_CHUNK_VALUES = 1_000_000  # floats of per-piece Jacobians formed at once (8 MB)


def braking_joints(q: np.ndarray, qd: np.ndarray, acceleration_rad_s2: np.ndarray, t: np.ndarray) -> np.ndarray:
    """Joints (K, F, n) [rad] of samples q, qd (K, n) braking at ``acceleration_rad_s2`` (n,), at times t (K, F) [s]."""
    stop_s = np.abs(qd) / acceleration_rad_s2
    tau = np.minimum(t[:, :, None], stop_s[:, None, :])
    return q[:, None, :] + qd[:, None, :] * tau - 0.5 * (acceleration_rad_s2 * np.sign(qd))[:, None, :] * tau**2


def braking_velocities(qd: np.ndarray, acceleration_rad_s2: np.ndarray, t: np.ndarray) -> np.ndarray:
    """Joint velocities (K, F, n) [rad/s] of the braking samples qd (K, n) at times t (K, F) [s]."""
    left = np.maximum(np.abs(qd)[:, None, :] - acceleration_rad_s2 * t[:, :, None], 0.0)
    return np.sign(qd)[:, None, :] * left


def brake_steps(qd: np.ndarray, acceleration_rad_s2: np.ndarray) -> np.ndarray:
    """Jacobians per braking motion (K,) for samples qd (K, n): a power of two from 1 to
    :data:`MAX_BRAKE_STEPS`, so that no joint turns more than :data:`BRAKE_STEP_RAD` between two."""
    travel = np.max(qd**2 / (2.0 * acceleration_rad_s2), axis=1)  # the farthest any joint turns
    wanted = np.clip(np.ceil(travel / BRAKE_STEP_RAD), 1, MAX_BRAKE_STEPS)
    return (2 ** np.ceil(np.log2(wanted))).astype(np.int64)


def mean_norm(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """``integral_0^1 |a + (b - a) s| ds`` (...,) of 3-vectors a, b (..., 3), in closed form.

    With d = b - a the integrand is sqrt(|d|^2 x^2 + h^2), x = s + a.d / |d|^2 and h the distance of
    the line from the origin: ``|d| [F(x)]``, F(x) = (x r + k asinh(x / sqrt k)) / 2, r = sqrt(x^2 + k),
    k = (h / |d|)^2 (F = x |x| / 2 when the line passes through 0: the velocity reverses).
    Where d is tiny against a the speed hardly changes and Simpson's rule is exact enough.
    """
    d = b - a
    dd, ad, aa = (np.einsum("...i,...i->...", x, y) for x, y in ((d, d), (a, d), (a, a)))
    steady = dd <= 1e-6 * aa
    dd_safe = np.where(steady, 1.0, dd)
    x0 = ad / dd_safe
    k = np.maximum(aa / dd_safe - x0**2, 0.0)
    with np.errstate(divide="ignore", invalid="ignore"):
        def primitive(x: np.ndarray) -> np.ndarray:
            tail = np.where(k > 0.0, k * np.arcsinh(x / np.sqrt(k)), 0.0)
            return 0.5 * (x * np.sqrt(x**2 + k) + tail)
        exact = np.sqrt(dd_safe) * (primitive(x0 + 1.0) - primitive(x0))
    simpson = (np.linalg.norm(a, axis=-1) + 4.0 * np.linalg.norm(0.5 * (a + b), axis=-1)
               + np.linalg.norm(b, axis=-1)) / 6.0
    return np.where(steady, simpson, exact)


def stopping_distances(robot: Robot, q: np.ndarray, qd: np.ndarray, acceleration_rad_s2: np.ndarray) -> np.ndarray:
    """Stopping distance [m] (K,) of each sample q, qd (K, n), a bounded chunk of samples at a time."""
    n = q.shape[1]
    acc = np.broadcast_to(np.asarray(acceleration_rad_s2, dtype=float), (n,))
    out = np.zeros(len(q))
    moving = np.flatnonzero(np.any(qd != 0.0, axis=1))  # a sample at rest stops where it is
    steps = brake_steps(qd[moving], acc)
    for m in np.unique(steps).tolist():
        group = moving[steps == m]
        rows_per_chunk = max(1, _CHUNK_VALUES // ((m + n) * 3 * n))
        for c in range(0, len(group), rows_per_chunk):
            rows = group[c:c + rows_per_chunk]
            out[rows] = _braking_lengths(robot, q[rows], qd[rows], acc, m)
    return out


def _braking_lengths(robot: Robot, q: np.ndarray, qd: np.ndarray, acc: np.ndarray, m: int) -> np.ndarray:
    """TCP path lengths [m] (K,) of the braking motions of samples q, qd (K, n) with m Jacobians each.

    The braking time [0, T] is cut into m equal steps, each with the Jacobian at its middle, and
    further at every joint's stop time (where its velocity stops falling): on each piece the joint
    velocities are linear in t, so with the step's Jacobian the TCP velocity is linear too and
    :func:`mean_norm` integrates its magnitude exactly.
    """
    k_rows = len(q)
    stop_s = np.abs(qd) / acc
    T = stop_s.max(axis=1)
    step = T[:, None] * (np.arange(m + 1) / m)  # (K, m + 1)
    J = robot.tcp_jacobians(braking_joints(q, qd, acc, 0.5 * (step[:, :-1] + step[:, 1:])).reshape(-1, q.shape[1]))
    J = J.reshape(k_rows, m, 3, q.shape[1])
    cuts = np.sort(np.concatenate([step, stop_s], axis=1), axis=1)  # (K, m + 1 + n)
    t0, t1 = cuts[:, :-1], cuts[:, 1:]
    which = np.minimum((0.5 * (t0 + t1) / np.where(T > 0, T, 1.0)[:, None] * m).astype(np.int64), m - 1)
    J_piece = J[np.arange(k_rows)[:, None], which]  # (K, P, 3, n)
    v0 = np.einsum("kpij,kpj->kpi", J_piece, braking_velocities(qd, acc, t0))
    v1 = np.einsum("kpij,kpj->kpi", J_piece, braking_velocities(qd, acc, t1))
    return np.sum((t1 - t0) * mean_norm(v0, v1), axis=1)


def worst_stopping(distances_m: np.ndarray, t: np.ndarray) -> tuple[float, float]:
    """The worst stopping distance [mm] and when [s] (trajectory.json's metrics); ``t``: the
    sample times (K,)."""
    k = int(np.argmax(distances_m)) if len(distances_m) else 0
    worst = float(distances_m[k]) if len(distances_m) else 0.0
    return worst * 1e3, float(t[k]) if len(t) else 0.0


def path_velocities(u: np.ndarray, q: np.ndarray, length_m: float, speed_m_s: float,
                    velocity_rad_s: np.ndarray) -> np.ndarray:
    """Joint velocities (N, n) [rad/s] at path samples u (N,), q (N, n) of a LIN / CIRC moving at
    ``speed_m_s`` along its base path, slowed where a joint would exceed ``velocity_rad_s`` (a path
    with no length, a pure reorientation, moves as fast as the joints allow)."""
    dq_du = np.gradient(q, u, axis=0)
    over = np.max(np.abs(dq_du) / velocity_rad_s, axis=1)  # joint speed per unit of du/dt
    with np.errstate(divide="ignore"):
        rate = np.minimum(speed_m_s / length_m if length_m > 0 else np.inf, 1.0 / over)  # du/dt
    return dq_du * np.where(np.isfinite(rate), rate, 0.0)[:, None]


def path_estimate(robot: Robot, u: np.ndarray, q: np.ndarray, length_m: float, speed_m_s: float,
                  velocity_rad_s: np.ndarray) -> tuple[float, float]:
    """``singplan check``'s figure for a LIN / CIRC: the largest stopping distance [m] over its path
    samples u, q moving at the programmed speed (:func:`path_velocities`), and the u where."""
    d = stopping_distances(robot, q, path_velocities(u, q, length_m, speed_m_s, velocity_rad_s),
                           robot.acceleration_rad_s2)
    k = int(np.argmax(d))
    return float(d[k]), float(u[k])


def ptp_estimate(robot: Robot, q_from: np.ndarray, q_to: np.ndarray, velocity_rad_s: np.ndarray,
                 points: int = 33) -> tuple[float, float]:
    """``singplan check``'s figure for a PTP: the largest stopping distance [m] at ``points`` states
    along the joint line, cruising synchronised (the slowest joint at its limit), and the fraction where."""
    dq = q_to - q_from
    duration_s = float(np.max(np.abs(dq) / velocity_rad_s))
    if duration_s == 0.0:
        return 0.0, 0.0
    s = np.linspace(0.0, 1.0, points)
    d = stopping_distances(robot, q_from + s[:, None] * dq, np.tile(dq / duration_s, (points, 1)),
                           robot.acceleration_rad_s2)
    k = int(np.argmax(d))
    return float(d[k]), float(s[k])
