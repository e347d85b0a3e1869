"""Small rotation and vector helpers shared by kinematics and planning."""

from __future__ import annotations

import numpy as np
import pinocchio as pin


def rpy_deg_to_rotation(rpy_deg: tuple[float, float, float] | np.ndarray) -> np.ndarray:
    """URDF fixed-axis roll-pitch-yaw [deg] to a rotation matrix: Rz(yaw) Ry(pitch) Rx(roll)."""
    r, p, y = np.radians(np.asarray(rpy_deg, dtype=float))
    return np.asarray(pin.rpy.rpyToMatrix(float(r), float(p), float(y)))


def cross3(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """3-vector cross product (np.cross costs ten times more on single vectors)."""
    return np.array([a[1] * b[2] - a[2] * b[1], a[2] * b[0] - a[0] * b[2], a[0] * b[1] - a[1] * b[0]])


def rotation_angle(R_a: np.ndarray, R_b: np.ndarray) -> float:
    """Angle [rad] of the rotation from R_a to R_b."""
    return float(np.linalg.norm(pin.log3(R_a.T @ R_b)))


def relative_rotations(R_a: np.ndarray, R_b: np.ndarray) -> np.ndarray:
    """R_a^T R_b of each pair of rotations (N, 3, 3): the rotation from R_a to R_b, in R_a's frame."""
    return np.einsum("nji,njk->nik", R_a, R_b)


def rotation_angles(R_a: np.ndarray, R_b: np.ndarray) -> np.ndarray:
    """Angles [rad] (N,) of the rotations from R_a to R_b, (N, 3, 3) each: :func:`rotation_angle` of
    each pair at once, as atan2(sin, cos) of M = R_a^T R_b (sin from its skew part, cos from its
    trace), which keeps small angles as exactly as Pinocchio's log3 and costs no call per pair."""
    M = relative_rotations(R_a, R_b)
    sin = 0.5 * np.sqrt((M[:, 2, 1] - M[:, 1, 2]) ** 2 + (M[:, 0, 2] - M[:, 2, 0]) ** 2
                        + (M[:, 1, 0] - M[:, 0, 1]) ** 2)
    cos = 0.5 * (M[:, 0, 0] + M[:, 1, 1] + M[:, 2, 2] - 1.0)
    return np.arctan2(sin, cos)


# within this of a half turn theta / sin(theta) (over 1000) costs more digits than Pinocchio's log3,
# which works from the symmetric part there: its log3 per pair (at pi - 1e-3 both err by ~1e-12 rad)
_NEAR_PI_RAD = 1e-3
_SMALL_RAD = 1e-4  # under this, the closed forms of Jlog3 cancel: their Taylor series instead


def rotation_logs(M: np.ndarray) -> np.ndarray:
    """log3 (N, 3) [rad] of rotations M (N, 3, 3): the rotation vector theta * axis, as Pinocchio's
    ``log3`` of each, without a call per rotation. ``theta / sin(theta)`` times the skew part
    (``sin(theta) * axis``), theta from :func:`rotation_angles`' atan2; rotations near a half turn
    (where that ratio loses digits) go to ``pin.log3`` one by one."""
    skew = 0.5 * np.stack([M[:, 2, 1] - M[:, 1, 2], M[:, 0, 2] - M[:, 2, 0], M[:, 1, 0] - M[:, 0, 1]], axis=1)
    sin = np.sqrt(np.sum(skew**2, axis=1))
    theta = np.arctan2(sin, 0.5 * (M[:, 0, 0] + M[:, 1, 1] + M[:, 2, 2] - 1.0))
    half_turn = theta > np.pi - _NEAR_PI_RAD  # sin may be 0 there: no division, Pinocchio instead
    small = theta <= _SMALL_RAD
    big = ~small & ~half_turn
    ratio = np.ones_like(theta)  # theta / sin(theta), 1 + theta^2 / 6 near 0
    ratio[big] = theta[big] / sin[big]
    ratio[small] += theta[small] ** 2 / 6.0
    logs = skew * ratio[:, None]
    for k in np.flatnonzero(half_turn):
        logs[k] = pin.log3(M[k])
    return logs


def rotation_log_jacobians(logs: np.ndarray) -> np.ndarray:
    """Pinocchio's ``Jlog3`` (N, 3, 3) at rotation vectors ``logs`` (N, 3) (:func:`rotation_logs`):
    d log3(R exp(dw)) / dw = (theta/2) cot(theta/2) I + (1/theta^2 - cot(theta/2) / (2 theta)) r r^T
    + [r]x / 2, r = logs (Bullo and Murray 1995; Pinocchio's ``Jlog3``); Taylor series for small theta."""
    theta = np.linalg.norm(logs, axis=1)
    diag = np.empty_like(theta)  # (theta/2) cot(theta/2)
    outer = np.empty_like(theta)  # 1/theta^2 - cot(theta/2) / (2 theta)
    big = theta > _SMALL_RAD
    half_cot = 0.5 / np.tan(0.5 * theta[big])
    diag[big] = theta[big] * half_cot
    outer[big] = (1.0 - diag[big]) / theta[big] ** 2
    small = theta[~big] ** 2
    diag[~big] = 1.0 - small / 12.0
    outer[~big] = 1.0 / 12.0 + small / 720.0
    J = diag[:, None, None] * np.eye(3) + outer[:, None, None] * logs[:, :, None] * logs[:, None, :]
    x, y, z = logs.T
    J[:, 0, 1] -= 0.5 * z
    J[:, 0, 2] += 0.5 * y
    J[:, 1, 0] += 0.5 * z
    J[:, 1, 2] -= 0.5 * x
    J[:, 2, 0] -= 0.5 * y
    J[:, 2, 1] += 0.5 * x
    return J
