"""What a controller program costs and holds: points, stops, the shortest segment, the deviation
reached and the time to choose the points and write the program, for the examples and the public
program scenarios, each in its robot's vendor's format at the default tolerance.

    python bench/bench_programs.py [--tolerance-mm 0.1] [--shared ../shared]

Planning is not timed (bench/bench_plan.py does that); the time is :func:`write_program`'s, best of
three, in this process (the robot and the numba kernels loaded once before).
"""

from __future__ import annotations

import argparse
import os
import platform
import tempfile
import time
from pathlib import Path

import singplan
from singplan.kinematics.vendor_config import convention_for
from singplan.outputs.programs import ProgramOptions, program_path, write_program
from singplan.outputs.timeline import robot_of

HERE = Path(__file__).resolve().parent
FORMAT_OF_VENDOR = {"kuka": "krl", "abb": "rapid", "fanuc": "fanuc-ls"}
EXAMPLES = ("kuka_program", "abb_near_miss_auto", "fanuc_near_miss_exact", "flyby_pick_place", "weave_seam")
SCENARIOS = ("kuka_kr6_r900_2__nullspace_wrist_exact_hit", "abb_irb2400__nullspace_shoulder_pass",
             "abb_irb2400__flyby_pick_place", "fanuc_lrmate200id__flyby_seam_lin_circ_lin",
             "kuka_kr6_r900_2__flyby_corner_near_wrist", "kuka_kr6_r900_2__weave_lin_sine",
             "abb_irb2400__weave_circ_triangle")


def tasks(shared: Path) -> list[Path]:
    out = [HERE.parent / "examples" / f"{name}.yaml" for name in EXAMPLES]
    return out + [p for p in (shared / "scenarios_programs" / f"{n}.yaml" for n in SCENARIOS) if p.is_file()]


def row(task: Path, tolerance_mm: float, folder: Path) -> str:
    traj = singplan.plan(task)
    convention = convention_for(robot_of(traj))
    fmt = FORMAT_OF_VENDOR[convention.vendor] if convention else None
    if fmt is None:
        return f"| {task.stem} | {len(traj.t)} | no convention | | | | | |"
    best = float("inf")
    for _ in range(3):
        start = time.perf_counter()
        export = write_program(traj, fmt, program_path(folder, fmt), ProgramOptions(tolerance_mm=tolerance_mm))
        best = min(best, time.perf_counter() - start)
    return (f"| {task.stem} | {fmt} | {len(traj.t)} | {export.points} | {export.exact_stops} | "
            f"{export.shortest_segment_s * 1e3:.0f} | {export.max_position_error_mm:.4f} | {best:.2f} |")


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--tolerance-mm", type=float, default=0.1)
    parser.add_argument("--shared", type=Path, default=HERE.parent.parent / "shared")
    args = parser.parse_args()
    print(f"{platform.processor() or platform.machine()}, {os.cpu_count()} CPUs, Python {platform.python_version()}, "
          f"load average {os.getloadavg()[0]:.1f}; tolerance {args.tolerance_mm:g} mm / 0.005 deg\n")
    print("| task | format | samples | points | exact stops | shortest segment [ms] | max deviation [mm] | "
          "write_program [s] |")
    print("|---|---|---|---|---|---|---|---|")
    with tempfile.TemporaryDirectory() as folder:
        for task in tasks(args.shared):
            print(row(task, args.tolerance_mm, Path(folder)), flush=True)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
