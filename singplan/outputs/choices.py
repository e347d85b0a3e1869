"""Names and defaults the command line offers, in a module that imports nothing heavy.

``singplan --help`` reads them before any output module (meshcat, matplotlib) is loaded.
"""

from __future__ import annotations

from typing import Literal

ExportFormat = Literal["ros2", "ros2-json", "urscript", "csv-deg", "krl", "rapid", "fanuc-ls"]
FORMATS: tuple[ExportFormat, ...] = ("ros2", "ros2-json", "urscript", "csv-deg", "krl", "rapid", "fanuc-ls")
PROGRAM_FORMATS: tuple[ExportFormat, ...] = ("krl", "rapid", "fanuc-ls")  # controller programs (outputs.programs)
PROGRAM_EXTENSIONS = {"krl": ".src", "rapid": ".mod", "fanuc-ls": ".ls"}
DEFAULT_PROGRAM_NAME = "singplan"
DEFAULT_FILE_NAMES: dict[str, str] = {"ros2": "trajectory.ros2.yaml", "ros2-json": "trajectory.ros2.json",
                                      "urscript": "trajectory.script", "csv-deg": "trajectory_deg.csv",
                                      **{f: DEFAULT_PROGRAM_NAME + ext for f, ext in PROGRAM_EXTENSIONS.items()}}
DEFAULT_TOLERANCE_MM = 0.1  # controller programs: TCP position between program points and the plan
DEFAULT_TOLERANCE_DEG = 0.005  # ... and TCP orientation (the checker holds 0.01 deg outside crossings)
UR_STEP_S = {"e-series": 0.002, "cb3": 0.008}  # servo loop of the controller generations
# the built-in crossing method names for the options' help, without importing the registry (numpy,
# Pinocchio): a copy for --help only; names are checked against singplan.planning.crossing.registry
# (tests/test_messages.py: the same)
CROSSING_METHODS = ("auto", "wrist-joint", "axis", "null-space", "exact", "dls", "average", "ptp", "stop")
DEFAULT_HOST = "127.0.0.1"  # the live server is for this machine unless asked otherwise
