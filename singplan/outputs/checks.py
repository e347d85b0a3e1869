"""Checks every export makes of a trajectory before writing anything (a file of the wrong shape
can be loaded: trajectory.json is read back from users' folders)."""

from __future__ import annotations

import math

import numpy as np

from singplan.errors import InputError
from singplan.results.trajectory import Trajectory


def check_trajectory(traj: Trajectory) -> None:
    """Refuse (InputError naming the field) a trajectory no controller format can carry."""
    names = traj.joint_names
    if not names or len(set(names)) != len(names) or not all(isinstance(n, str) and n for n in names):
        raise InputError(f"joint_names: expected distinct non-empty names, got {list(names)!r}")
    if not (math.isfinite(traj.period) and traj.period > 0):
        raise InputError(f"period: expected a positive number of seconds, got {traj.period!r}")
    k, n = len(traj.t), len(names)
    if traj.t.ndim != 1 or k == 0:
        raise InputError(f"t: expected a non-empty list of times, got shape {traj.t.shape}")
    for field in ("q", "qd", "qdd"):
        a = getattr(traj, field)
        if a.shape != (k, n):
            raise InputError(f"{field}: expected {k} rows of {n} values (one per joint name), got shape {a.shape}")
    for field in ("t", "q", "qd", "qdd"):
        bad = np.argwhere(~np.isfinite(getattr(traj, field)))
        if len(bad):
            raise InputError(f"{field}{''.join(f'[{i}]' for i in bad[0])}: not a finite number")
    if np.any(np.diff(traj.t) <= 0):
        i = int(np.argmax(np.diff(traj.t) <= 0)) + 1
        raise InputError(f"t[{i}]: times must increase, got {traj.t[i - 1]!r} then {traj.t[i]!r}")
