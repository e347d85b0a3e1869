"""singplan: plan industrial robot motions through kinematic singularities.

Quaternions, where they appear, are (x, y, z, w). Units are SI (m, rad, s) inside the code;
degrees only at the edges, in names that say so (``rpy_deg``, ``joints_deg``).

The public names below are loaded on first use, through the module-level :func:`__getattr__`:
``import singplan`` itself imports no Pinocchio, numba, TOPP-RA, meshcat or matplotlib, so a
script or ``singplan --help`` pays only for what it calls. ``from singplan import plan`` works as
usual (it triggers the import of :mod:`singplan.results.plan`).
"""

from __future__ import annotations

import importlib
import logging
from typing import TYPE_CHECKING, Any

if TYPE_CHECKING:
    from singplan.errors import InputError, PlanningError, SingplanError
    from singplan.kinematics.configuration import (
        Configuration,
        SingularityDistances,
        classify,
        singularity_distances,
    )
    from singplan.kinematics.ik.solve import IkSolutions, opw_batch, solve_all
    from singplan.kinematics.robot import Robot, bundled_robots, load_robot
    from singplan.outputs.viewer import replay
    from singplan.planning.orchestration.detect import detect
    from singplan.results.plan import plan
    from singplan.results.trajectory import Segment, Trajectory, save
    from singplan.task.load import load_task, parse_task
    from singplan.task.schema import Task

logging.getLogger(__name__).addHandler(logging.NullHandler())

__version__ = "0.1.0"

_HOMES = {  # public name -> the module that defines it
    "InputError": "singplan.errors",
    "PlanningError": "singplan.errors",
    "SingplanError": "singplan.errors",
    "Configuration": "singplan.kinematics.configuration",
    "SingularityDistances": "singplan.kinematics.configuration",
    "classify": "singplan.kinematics.configuration",
    "singularity_distances": "singplan.kinematics.configuration",
    "IkSolutions": "singplan.kinematics.ik.solve",
    "opw_batch": "singplan.kinematics.ik.solve",
    "solve_all": "singplan.kinematics.ik.solve",
    "Robot": "singplan.kinematics.robot",
    "bundled_robots": "singplan.kinematics.robot",
    "load_robot": "singplan.kinematics.robot",
    "Task": "singplan.task.schema",
    "load_task": "singplan.task.load",
    "parse_task": "singplan.task.load",
    "detect": "singplan.planning.orchestration.detect",
    "plan": "singplan.results.plan",
    "Segment": "singplan.results.trajectory",
    "Trajectory": "singplan.results.trajectory",
    "save": "singplan.results.trajectory",
    "replay": "singplan.outputs.viewer",
}

__all__ = [  # every name of _HOMES, and the version
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


def __getattr__(name: str) -> Any:
    """A public name, imported from its module the first time it is asked for."""
    home = _HOMES.get(name)
    if home is None:
        raise AttributeError(f"module 'singplan' has no attribute {name!r}")
    value = getattr(importlib.import_module(home), name)
    globals()[name] = value  # later look-ups skip this function
    return value


def __dir__() -> list[str]:
    return sorted({*globals(), *_HOMES})
