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
