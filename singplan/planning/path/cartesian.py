"""Cartesian path geometry: LIN and CIRC pieces, orientation slerp, arc-length sampling.

A piece maps a normalised parameter ``u`` in [0, 1] to a TCP pose. The position moves at
constant speed along the line or arc (``u`` is proportional to arc length ``s = u L``), and
the orientation is slerped with the same parameter:
``R(u) = R_a exp(u log(R_a^T R_b))`` (shortest rotation; exactly 180 deg is ambiguous and
rejected as bad input).
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from functools import cached_property

import numpy as np
import pinocchio as pin

from singplan.errors import TaskError
from singplan.kinematics import reduced
from singplan.kinematics.compiled import jit
from singplan.kinematics.geometry import cross3, rotation_angle, rotation_angles, rpy_deg_to_rotation
from singplan.kinematics.robot import Robot
from singplan.task.schema import Move

AMBIGUOUS_ROTATION_RAD = math.pi - 1e-6
STEP_M = 0.002  # the planner's path sampling: at most 2 mm ...
STEP_RAD = math.radians(0.5)  # ... and 0.5 deg of tool rotation between samples
_DRAW_POINTS = 64  # a replay draws a LIN / CIRC with this many points (a woven one with more)


@jit
def _rodrigues(wx: float, wy: float, wz: float, out: np.ndarray) -> None:
    """``exp([w]x)`` into ``out`` (3, 3): ``I + sin(t) K + (1 - cos(t)) K^2``, K = [w / t]x, t = |w|."""
    theta = math.sqrt(wx * wx + wy * wy + wz * wz)
    s, c = 0.0, 0.0  # below 1e-12 rad: the identity
    kx, ky, kz = 0.0, 0.0, 0.0
    if theta >= 1e-12:
        kx, ky, kz = wx / theta, wy / theta, wz / theta
        s, c = math.sin(theta), 1.0 - math.cos(theta)
    out[0, 0] = 1.0 + c * (kx * kx - 1.0)
    out[1, 1] = 1.0 + c * (ky * ky - 1.0)
    out[2, 2] = 1.0 + c * (kz * kz - 1.0)
    out[0, 1] = c * kx * ky - s * kz
    out[1, 0] = c * kx * ky + s * kz
    out[0, 2] = c * kx * kz + s * ky
    out[2, 0] = c * kx * kz - s * ky
    out[1, 2] = c * ky * kz - s * kx
    out[2, 1] = c * ky * kz + s * kx


@jit
def _poses(u: np.ndarray, R_a: np.ndarray, omega: np.ndarray, p_a: np.ndarray, p_b: np.ndarray,
           center: np.ndarray, arc_axis: np.ndarray, circ: bool) -> np.ndarray:
    """Homogeneous poses (N, 4, 4): ``R_a exp(u omega)`` and the line ``p_a -> p_b`` or, for a
    circle, ``center + exp(u arc_axis) (p_a - center)``."""
    T = np.zeros((u.shape[0], 4, 4))
    E = np.empty((3, 3))
    for i in range(u.shape[0]):
        _rodrigues(u[i] * omega[0], u[i] * omega[1], u[i] * omega[2], E)
        for r in range(3):  # 3 x 3 products written out: numba's matmul allocates and calls BLAS
            for c in range(3):
                T[i, r, c] = R_a[r, 0] * E[0, c] + R_a[r, 1] * E[1, c] + R_a[r, 2] * E[2, c]
        if circ:
            _rodrigues(u[i] * arc_axis[0], u[i] * arc_axis[1], u[i] * arc_axis[2], E)
            for r in range(3):
                T[i, r, 3] = center[r] + E[r, 0] * (p_a[0] - center[0]) + E[r, 1] * (p_a[1] - center[1]) \
                    + E[r, 2] * (p_a[2] - center[2])
        else:
            for r in range(3):
                T[i, r, 3] = p_a[r] + u[i] * (p_b[r] - p_a[r])
        T[i, 3, 3] = 1.0
    return T


@dataclass(frozen=True)
class CartesianPiece:
    """A LIN or CIRC move from ``T_start`` to ``T_end`` (TCP poses in the base frame).

    For a CIRC, ``center``, ``normal`` (unit), ``radius`` and ``arc_rad`` describe the circle
    through start, via and end, traversed from start about ``normal`` by ``arc_rad``.
    """

    kind: str  # "lin" | "circ"
    T_start: pin.SE3
    T_end: pin.SE3
    length_m: float  # arc length of the position path
    rotation_rad: float  # total orientation change
    center: np.ndarray | None = None
    normal: np.ndarray | None = None
    radius: float = 0.0
    arc_rad: float = 0.0

    @cached_property
    def rotation_vector(self) -> np.ndarray:
        """``log(R_start^T R_end)`` (3,): the slerp's whole turn in the start frame [rad]."""
        return np.asarray(pin.log3(self.T_start.rotation.T @ self.T_end.rotation))

    def positions(self, u: np.ndarray) -> np.ndarray:
        """TCP positions (N, 3) [m] at parameters u (N,)."""
        return self.poses(u)[:, :3, 3]

    def rotations(self, u: np.ndarray) -> np.ndarray:
        """TCP orientations (N, 3, 3): slerp from start to end."""
        return self.poses(u)[:, :3, :3]

    @cached_property
    def _pose_arguments(self) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray, np.ndarray, np.ndarray, bool]:
        """What :func:`_poses` needs besides u, formed once per piece."""
        center = self.center if self.center is not None else np.zeros(3)
        arc_axis = self.arc_rad * self.normal if self.normal is not None else np.zeros(3)
        return (np.ascontiguousarray(self.T_start.rotation), self.rotation_vector, np.array(self.T_start.translation),
                np.array(self.T_end.translation), center, arc_axis, self.kind == "circ")

    def poses(self, u: np.ndarray) -> np.ndarray:
        """Homogeneous TCP poses (N, 4, 4)."""
        return _poses(np.ascontiguousarray(u, dtype=float), *self._pose_arguments)

    def velocity(self, u: float) -> np.ndarray:
        """dX/du (6,): the TCP point's velocity [m] and the tool's angular velocity [rad] in the
        base frame, per unit of u. The slerp turns at the constant rate ``R(u) omega = R_start omega``."""
        w = self.T_start.rotation @ self.rotation_vector
        if self.kind == "lin":
            return np.concatenate([self.T_end.translation - self.T_start.translation, w])
        assert self.center is not None and self.normal is not None
        radial = self.poses(np.array([u]))[0, :3, 3] - self.center
        return np.concatenate([cross3(self.arc_rad * self.normal, radial), w])

    def describe(self, u: float) -> str:
        """A point of the path for messages: arc length and position."""
        p = self.positions(np.array([u]))[0]
        return f"s = {u * self.length_m * 1e3:.1f} mm along the path (xyz {p[0]:.4f} {p[1]:.4f} {p[2]:.4f} m)"

    def sample_count(self, step_m: float, step_rad: float) -> int:
        """Number of intervals so that each one moves at most ``step_m`` and turns ``step_rad``."""
        return max(2, math.ceil(self.length_m / step_m), math.ceil(self.rotation_rad / step_rad))

    def grid(self, step_m: float, step_rad: float) -> np.ndarray:
        """The planner's initial path parameters: uniform at the steps [m], [rad]."""
        return np.linspace(0.0, 1.0, self.sample_count(step_m, step_rad) + 1)

    def drawing_count(self) -> int:
        """Points a replay draws of the path."""
        return _DRAW_POINTS


def make_lin(T_start: pin.SE3, T_end: pin.SE3, field: str) -> CartesianPiece:
    """A LIN piece; ``field`` names the move for error messages."""
    angle = _checked_rotation(T_start, T_end, field)
    length = float(np.linalg.norm(T_end.translation - T_start.translation))
    return CartesianPiece("lin", T_start, T_end, length, angle)


def make_circ(T_start: pin.SE3, via: np.ndarray, T_end: pin.SE3, field: str) -> CartesianPiece:
    """A CIRC piece through ``via`` [m]; degenerate circles are bad input."""
    angle = _checked_rotation(T_start, T_end, field)
    pa, pb = T_start.translation, T_end.translation
    u, v = via - pa, pb - pa
    normal = cross3(u, v)
    n2 = float(normal @ normal)
    scale = max(float(u @ u), float(v @ v), 1e-30)
    if n2 < 1e-12 * scale * scale or min(np.linalg.norm(u), np.linalg.norm(v), np.linalg.norm(pb - via)) < 1e-6:
        raise TaskError(f"{field}.via", "start, via and end are collinear or coincide: no unique circle")
    center = pa + (float(v @ v) * cross3(normal, u) + float(u @ u) * cross3(v, normal)) / (2.0 * n2)
    normal = normal / math.sqrt(n2)
    radius = float(np.linalg.norm(pa - center))
    a, b = pa - center, pb - center
    arc = math.atan2(float(cross3(a, b) @ normal), float(a @ b))
    arc = arc if arc >= 0 else arc + 2.0 * math.pi
    return CartesianPiece("circ", T_start, T_end, radius * arc, angle, center, normal, radius, arc)


def _checked_rotation(T_start: pin.SE3, T_end: pin.SE3, field: str) -> float:
    angle = rotation_angle(T_start.rotation, T_end.rotation)
    if angle > AMBIGUOUS_ROTATION_RAD:
        raise TaskError(f"{field}.to.rpy_deg", f"the orientation turns {math.degrees(angle):.4f} deg: a 180 deg "
                                               "turn is ambiguous (which way round?); split the move")
    return angle


def move_target(move: Move, T_start: pin.SE3) -> pin.SE3:
    """A move's Cartesian target; without ``rpy_deg`` the orientation is held from ``T_start``."""
    assert move.to is not None  # LIN / CIRC, or a PTP to a pose
    rotation = rpy_deg_to_rotation(move.to.rpy_deg) if move.to.rpy_deg is not None else T_start.rotation
    return pin.SE3(rotation, np.asarray(move.to.xyz, dtype=float))


_DEVIATION_CHUNK = 65_536  # programmed and reached poses formed at once (~250 bytes a sample)


def sample_deviations(robot: Robot, piece: CartesianPiece | None, u: np.ndarray,
                      q: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Position [m] and orientation [rad] error of each sample q (K, n) against the path at its u
    (for a five-joint arm the angle between the tool z axes)."""
    if piece is None:
        return np.zeros(len(q)), np.zeros(len(q))
    pos, ori = np.empty(len(q)), np.empty(len(q))
    five = reduced.is_reduced(robot)
    for c in range(0, len(q), _DEVIATION_CHUNK):
        want = piece.poses(u[c:c + _DEVIATION_CHUNK])
        p, R = robot.tcp_frames(q[c:c + _DEVIATION_CHUNK])
        pos[c:c + len(p)] = np.linalg.norm(p - want[:, :3, 3], axis=1)
        # reduced order: only the tool's z axis is kept (singplan.kinematics.reduced)
        ori[c:c + len(p)] = reduced.z_angles(R, want[:, :3, :3]) if five else rotation_angles(R, want[:, :3, :3])
    return pos, ori
