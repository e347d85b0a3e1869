"""Joint limit defaults that hold before any robot is loaded (no Pinocchio, no numba: the task
schema reads them)."""

from __future__ import annotations

# the joint acceleration limit of every joint when neither the URDF (which has none) nor the
# task's limits.acceleration gives one: a robot loaded without a task, and the task field's default
DEFAULT_ACCELERATION_RAD_S2 = 10.0
