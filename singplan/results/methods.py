"""What the outputs say of the crossing methods, taken from their one home
(:mod:`singplan.planning.crossing.registry`): the outputs never import the planning stages
themselves (an import-linter contract in pyproject.toml). Importing this loads the crossing
methods (Pinocchio, numba): only for what is written after a plan.
"""

from __future__ import annotations

from singplan.planning.crossing.registry import PAUSING

__all__ = ["PAUSING"]
