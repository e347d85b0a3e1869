"""singplan: plan industrial robot motions through kinematic singularities.

Quaternions, where they appear, are (x, y, z, w). Units are SI (m, rad, s) inside the code;
degrees only at the edges, in names that say so (``rpy_deg``, ``joints_deg``).
"""

from __future__ import annotations

import logging

from singplan.errors import InputError, PlanningError, SingplanError
from singplan.kinematics.configuration import Configuration, SingularityDistances, classify, singularity_distances
from singplan.kinematics.ik.solve import IkSolutions, opw_batch, solve_all
from singplan.kinematics.robot import Robot, bundled_robots, load_robot
from singplan.outputs.viewer import replay
from singplan.planning.planner import detect
from singplan.results.plan import plan
from singplan.results.trajectory import Segment, Trajectory, save
from singplan.task.schema import Task, load_task, parse_task

logging.getLogger(__name__).addHandler(logging.NullHandler())

__version__ = "0.1.0"

__all__ = [
    "Configuration",
    "IkSolutions",
    "InputError",
    "PlanningError",
    "Robot",
    "Segment",
    "SingplanError",
    "SingularityDistances",
    "Task",
    "Trajectory",
    "__version__",
    "bundled_robots",
    "classify",
    "detect",
    "load_robot",
    "load_task",
    "opw_batch",
    "parse_task",
    "plan",
    "replay",
    "save",
    "singularity_distances",
    "solve_all",
]
