"""singplan: plan industrial robot motions through kinematic singularities.

Quaternions, where they appear, are (x, y, z, w). Units are SI (m, rad, s) inside the code;
degrees only at the edges, in names that say so (``rpy_deg``, ``joints_deg``).
"""

from __future__ import annotations

import logging

from singplan.configuration import Configuration, SingularityDistances, classify, singularity_distances
from singplan.errors import InputError, PlanningError, SingplanError
from singplan.ik import IkSolutions, opw_batch, solve_all
from singplan.robot import Robot, bundled_robots, load_robot

logging.getLogger(__name__).addHandler(logging.NullHandler())

__version__ = "0.1.0"

__all__ = [
    "Configuration",
    "IkSolutions",
    "InputError",
    "PlanningError",
    "Robot",
    "SingplanError",
    "SingularityDistances",
    "__version__",
    "bundled_robots",
    "classify",
    "load_robot",
    "opw_batch",
    "singularity_distances",
    "solve_all",
]
