"""singplan: plan industrial robot motions through kinematic singularities.

Quaternions, where they appear, are (x, y, z, w). Units are SI (m, rad, s) inside the code;
degrees only at the edges, in names that say so (``rpy_deg``, ``joints_deg``).

The public names below are loaded on first use, through the module-level :func:`__getattr__`:
``import singplan`` itself imports no Pinocchio, numba, TOPP-RA, meshcat or matplotlib, so a
script or ``singplan --help`` pays only for what it calls. ``from singplan import plan`` works as
usual (it triggers the import of the entry module, :mod:`singplan.entry`).

Each name comes from its home in :data:`_HOMES`: the entry module (:mod:`singplan.entry`:
``plan``, ``plan_into``, ``detect``) and the modules that define the records, the errors and the
kinematics. ``tests/test_public_api.py`` resolves every name of ``__all__`` and checks that the
TYPE_CHECKING imports below (what type checkers see) name the same homes.
"""

from __future__ import annotations

import importlib
import logging
from typing import TYPE_CHECKING, Any

from singplan._version import __version__ as __version__

if TYPE_CHECKING:
    from singplan.entry import detect, load_task, parse_task, plan, plan_into
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
    from singplan.results.trajectory import Segment, Trajectory, save
    from singplan.task.schema import Task

logging.getLogger(__name__).addHandler(logging.NullHandler())


_HOMES = {  # module -> the public names it gives: the entry module, then the homes of records, errors, kinematics
    "singplan.entry": ("plan", "plan_into", "detect", "load_task", "parse_task"),
    "singplan.outputs.viewer": ("replay",),
    "singplan.results.trajectory": ("Segment", "Trajectory", "save"),
    "singplan.task.schema": ("Task",),
    "singplan.kinematics.robot": ("Robot", "bundled_robots", "load_robot"),
    "singplan.kinematics.ik.solve": ("IkSolutions", "opw_batch", "solve_all"),
    "singplan.kinematics.configuration": ("Configuration", "SingularityDistances", "classify",
                                          "singularity_distances"),
    "singplan.errors": ("InputError", "PlanningError", "SingplanError"),
}
_HOME_OF = {name: home for home, names in _HOMES.items() for name in names}

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
    "plan_into",
    "replay",
    "save",
    "singularity_distances",
    "solve_all",
]


def __getattr__(name: str) -> Any:
    """A public name, imported from its module the first time it is asked for."""
    home = _HOME_OF.get(name)
    if home is None:
        raise AttributeError(f"module 'singplan' has no attribute {name!r}")
    value = getattr(importlib.import_module(home), name)
    globals()[name] = value  # later look-ups skip this function
    return value


def __dir__() -> list[str]:
    return sorted({*globals(), *__all__})
