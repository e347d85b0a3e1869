# /// script
# requires-python = ">=3.10"
# dependencies = ["singplan"]
# ///
"""Plan a task and write the program its robot's controller runs: KUKA KRL, ABB RAPID or FANUC TP,
chosen from the robot's controller convention (robots.yaml).

    python examples/controller_program.py [TASK.yaml] [OUT] [TOLERANCE_MM]

writes OUT/trajectory.{csv,json} and OUT/singplan.src (or .mod, .ls), and prints what the
program holds. docs/controller-programs.md tells how to load and run it on the controller.
"""

from __future__ import annotations

import sys
from pathlib import Path

import singplan
from singplan.kinematics.vendor_config import convention_for
from singplan.outputs.programs import ProgramOptions, program_path, write_program
from singplan.outputs.timeline import robot_of

FORMAT_OF_VENDOR = {"kuka": "krl", "abb": "rapid", "fanuc": "fanuc-ls"}


def main() -> int:
    task = Path(sys.argv[1]) if len(sys.argv) > 1 else Path(__file__).with_name("kuka_program.yaml")
    out = Path(sys.argv[2]) if len(sys.argv) > 2 else Path("singplan-program")
    tolerance_mm = float(sys.argv[3]) if len(sys.argv) > 3 else 0.1
    traj = singplan.plan(task)
    singplan.save(traj, out)
    convention = convention_for(robot_of(traj))
    if convention is None or convention.vendor not in FORMAT_OF_VENDOR:
        print(f"{traj.robot}: no KUKA, ABB or FANUC controller convention; no program written")
        return 2
    fmt = FORMAT_OF_VENDOR[convention.vendor]
    export = write_program(traj, fmt, program_path(out, fmt), ProgramOptions(tolerance_mm=tolerance_mm,
                                                                           source=str(task)))
    print(export.message())
    return 0


if __name__ == "__main__":
    sys.exit(main())
