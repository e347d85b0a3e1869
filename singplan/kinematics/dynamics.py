"""Joint torques along a trajectory by inverse dynamics (SEEDS 003), and the effort limits.

Torques come from Pinocchio's recursive Newton-Euler algorithm (``pinocchio.rnea``) on the
robot's reduced model: the chain from the base to the tip, with every joint off the chain
(gripper fingers) locked and its link's inertia carried by the chain link it hangs on. A sample's
velocity and acceleration are the central differences of the output samples, as a checker
reads them, so the torques reported are those of the samples a controller receives.

Torques are computed only for a robot with dynamics: every chain link with a mass, every chain
joint with an effort limit, and a URDF that does not declare its dynamics invented. The bundled
industrial arms are such URDFs: their masses and inertias are estimates (solid cylinders) and
most efforts are 1000 N m placeholders, and robots/generate_urdfs.py writes
:data:`NO_DYNAMICS_MARK` into their headers. A file is judged by its content, so the same URDF
gets the same answer by name and by path.
"""

from __future__ import annotations

import logging
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
import pinocchio as pin

from singplan.errors import TaskError
from singplan.kinematics.robot import Robot

logger = logging.getLogger(__name__)

NO_DYNAMICS_MARK = "singplan: no published dynamics"  # robots/generate_urdfs.py writes it
_HEADER_BYTES = 8192  # the generator's header comes first in the file
_CHUNK = 65_536  # samples whose velocities and accelerations are formed at once (~100 bytes each)
_DIFFERENCES_CHUNK = 16_384  # ... and for the trajectory's own qd, qdd (~400 bytes of temporaries each)


def no_dynamics_reason(robot: Robot) -> str | None:
    """Why torques cannot be computed for ``robot`` (None when they can)."""
    try:
        with Path(robot.urdf_path).open("rb") as f:
            header = f.read(_HEADER_BYTES).decode("utf-8", "replace")
    except OSError:
        header = ""
    if NO_DYNAMICS_MARK in header:
        return f"{robot.name} has no published dynamics (its URDF's masses and inertias are estimates)"
    model = robot.model
    for j in range(1, model.njoints):
        if not model.inertias[j].mass > 0.0:
            return f"the URDF gives no mass for the link moved by {model.names[j]}"
    efforts = np.asarray(model.effortLimit, dtype=float)
    for j in range(model.nv):
        if not efforts[j] > 0.0:
            return f"the URDF gives no effort limit for {model.names[j + 1]}"
    return None


def has_inertias(robot: Robot) -> bool:
    """True when the robot's URDF carries real inertias and effort limits (torques can be computed)."""
    return no_dynamics_reason(robot) is None


def effort_limits_nm(robot: Robot) -> np.ndarray:
    """The URDF effort limits [N m] of the chain joints (n,)."""
    return np.array(robot.model.effortLimit, dtype=float)


def require_dynamics(robot: Robot, field_name: str = "limits.torque_scale") -> None:
    """Bad input (TaskError on ``field_name``) when torques cannot be computed for ``robot``."""
    reason = no_dynamics_reason(robot)
    if reason is not None:
        raise TaskError(field_name, f"torques cannot be limited: {reason}")


@dataclass(frozen=True)
class TorqueLimit:
    """The torque bound a move is timed under: |tau_j| <= limit_nm[j]."""

    robot: Robot
    limit_nm: np.ndarray  # (n,) effort x torque_scale
    _data: pin.Data = field(init=False, repr=False, compare=False)

    def __post_init__(self) -> None:
        object.__setattr__(self, "_data", self.robot.model.createData())  # not the FK's data

    def rnea(self, q: np.ndarray, qd: np.ndarray, qdd: np.ndarray) -> np.ndarray:
        """Joint torques [N m] (n,) at one state."""
        return np.array(pin.rnea(self.robot.model, self._data, q, qd, qdd))


def torques_nm(robot: Robot, q: np.ndarray, qd: np.ndarray, qdd: np.ndarray) -> np.ndarray:
    """Inverse-dynamics torques [N m] (K, n) of states q, qd, qdd (K, n) (gravity from the URDF)."""
    model, data = robot.model, robot.model.createData()
    out = np.empty_like(q)
    for k in range(len(q)):
        out[k] = pin.rnea(model, data, q[k], qd[k], qdd[k])
    return out


@dataclass(frozen=True)
class TorquePeaks:
    """Largest |tau| / limit over the samples, where it happens, and each joint's largest |tau|."""

    ratio: float
    sample: int
    joint: int
    peak_nm: np.ndarray  # (n,)


def trajectory_torques(robot: Robot, q: np.ndarray, period_s: float, limit_nm: np.ndarray,
                       series: bool = False, ends_from_rest: bool = False) -> tuple[TorquePeaks, np.ndarray | None]:
    """Torque peaks of output samples q (K, n), and with ``series`` the ratios |tau| / limit (K, n).

    Velocities and accelerations are central differences, formed a chunk at a time so the work
    space stays bounded. The two end samples are at rest: zero acceleration (the trajectory's
    own ``qdd``), or with ``ends_from_rest`` the acceleration their step implies from rest.
    """
    n = q.shape[1]
    peak = np.zeros(n)
    best = (0.0, 0, 0)
    ratios = np.empty(q.shape, dtype=np.float32) if series else None  # for plots: half the memory
    for c in range(0, len(q), _CHUNK):
        end = min(c + _CHUNK, len(q))
        qd, qdd = span_differences(q, period_s, c, end, ends_from_rest)
        tau = np.abs(torques_nm(robot, q[c:end], qd, qdd))
        peak = np.maximum(peak, tau.max(axis=0))
        r = tau / limit_nm
        k, j = np.unravel_index(int(np.argmax(r)), r.shape)
        if r[k, j] > best[0] or np.isnan(r[k, j]):  # a NaN torque is the worst of all
            best = (float(r[k, j]), c + int(k), int(j))
        if ratios is not None:
            ratios[c:end] = r
    return TorquePeaks(best[0], best[1], best[2], peak), ratios


def central_differences(q: np.ndarray, period_s: float) -> tuple[np.ndarray, np.ndarray]:
    """Velocities [rad/s] and accelerations [rad/s^2] (K, n) of samples q (K, n): :func:`span_differences`
    of all samples, written into whole arrays a chunk at a time (its temporaries stay bounded)."""
    qd, qdd = np.empty(q.shape), np.empty(q.shape)
    for c in range(0, len(q), _DIFFERENCES_CHUNK):
        end = min(c + _DIFFERENCES_CHUNK, len(q))
        qd[c:end], qdd[c:end] = span_differences(q, period_s, c, end)
    return qd, qdd


def span_differences(q: np.ndarray, period_s: float, start: int, stop: int,
                     ends_from_rest: bool = False) -> tuple[np.ndarray, np.ndarray]:
    """qd [rad/s], qdd [rad/s^2] (stop - start, n) of samples start .. stop - 1 of q (K, n).

    The velocities and accelerations a checker reads from the samples: central differences, and
    zero speed and acceleration at the first and last sample of q (at rest). With
    ``ends_from_rest`` those two get the acceleration their step implies from rest instead.
    """
    qd, qdd = np.zeros((stop - start, q.shape[1])), np.zeros((stop - start, q.shape[1]))
    a, b = max(start, 1), min(stop, len(q) - 1)  # interior samples in this span
    if b > a:
        qd[a - start:b - start] = (q[a + 1:b + 1] - q[a - 1:b - 1]) / (2 * period_s)
        qdd[a - start:b - start] = (q[a + 1:b + 1] - 2 * q[a:b] + q[a - 1:b - 1]) / period_s**2
    if ends_from_rest and len(q) > 1:
        if start == 0:
            qdd[0] = 2.0 * (q[1] - q[0]) / period_s**2
        if stop == len(q):
            qdd[-1] = 2.0 * (q[-2] - q[-1]) / period_s**2
    return qd, qdd


def move_torque_ratio(limit: TorqueLimit, q: np.ndarray, period_s: float) -> tuple[float, int]:
    """Largest |tau| / limit on one move's samples q (K + 1, n), and the sample where.

    Interior samples use central differences, as a checker does. A move starts and ends at
    rest; its end samples are judged with the acceleration the first (last) step implies from
    rest, 2 * step / period^2. Where two moves meet, the checker's central difference is the mean
    of the two moves' such accelerations, so its torque is the mean of two torques within the
    bound, hence within it too.
    """
    peaks, _ = trajectory_torques(limit.robot, q, period_s, limit.limit_nm, ends_from_rest=True)
    return peaks.ratio, peaks.sample


class PathDynamics:
    """TOPP-RA's ``inv_dyn`` for a move's path made dimensionless (see timing._toppra_profile).

    The path's coordinates are x = ((q - q0) / L, arc / L) in the time t / tau; the torque of a
    state (x, x', x'') is rnea(q0 + L x, (L / tau) x', (L / tau^2) x'') in N m, and 0 for the
    arc-length coordinate (it has no actuator).
    """

    def __init__(self, limit: TorqueLimit, q0: np.ndarray, length: float, tau_s: float) -> None:
        self.limit = limit
        self.q0 = q0
        self.length = length
        self.tau_s = tau_s
        self.n = len(q0)

    def __call__(self, x: np.ndarray, xd: np.ndarray, xdd: np.ndarray) -> np.ndarray:
        n, scale = self.n, self.length
        tau = self.limit.rnea(self.q0 + scale * x[:n], scale / self.tau_s * xd[:n], scale / self.tau_s**2 * xdd[:n])
        return np.append(tau, 0.0)
