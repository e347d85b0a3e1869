"""All-branch IK throughput: singplan's vectorised OPW solver beside py-opw-kinematics.

    python bench/bench_ik.py [--robot kuka_kr6_r900_2] [--repeat 5] [--write docs/benchmarks.md]

For N = 1, 100 and 10 000 random poses of one arm, in one run on one machine:
- singplan ``opw_batch``: all eight branches for the N poses at once;
- singplan ``solve_all``: the single-pose API (all branches, limits, labels) in a loop;
- py-opw-kinematics ``inverse`` in a loop (all branches of one pose per call);
- py-opw-kinematics ``batch_inverse`` (one branch per pose, nearest the previous).
Times are the best of ``--repeat`` runs, in microseconds per pose.
"""

from __future__ import annotations

import argparse
import platform
import sys
import time
from collections.abc import Callable
from importlib.metadata import version
from pathlib import Path

import numpy as np
import pinocchio as pin
from py_opw_kinematics import KinematicModel
from py_opw_kinematics import Robot as OpwRobot
from scipy.spatial.transform import RigidTransform

from singplan.ik import opw_batch, solve_all
from singplan.robot import Robot, load_robot


def _oracle(robot: Robot) -> OpwRobot:
    p = robot.opw
    assert p is not None
    model = KinematicModel(a1=p.a1, a2=p.a2, b=p.b, c1=p.c1, c2=p.c2, c3=p.c3, c4=p.c4,
                           offsets=tuple(p.offsets_rad), flip_axes=tuple(s < 0 for s in p.sign_corrections))
    return OpwRobot(model, degrees=False)


def _best_us_per_pose(fn: Callable[[], object], n: int, repeat: int) -> float:
    best = float("inf")
    for _ in range(repeat):
        t0 = time.perf_counter()
        fn()
        best = min(best, time.perf_counter() - t0)
    return best / n * 1e6


def measure(robot_name: str, sizes: list[int], repeat: int) -> list[dict[str, float]]:
    robot = load_robot(robot_name)
    oracle = _oracle(robot)
    rng = np.random.default_rng(0)
    rows = []
    for n in sizes:
        q = rng.uniform(robot.lower_rad, robot.upper_rad, size=(n, 6))
        T = np.array([robot.fk(qk).homogeneous for qk in q])
        poses = RigidTransform.from_matrix(T)
        loop_n = min(n, 1000)  # the per-pose loops are timed on at most 1000 poses
        row = {
            "n": n,
            "singplan_opw_batch": _best_us_per_pose(lambda T=T: opw_batch(robot.opw, T), n, repeat),
            "singplan_solve_all": _best_us_per_pose(
                lambda T=T, k=loop_n: [solve_all(robot, _se3(Tk)) for Tk in T[:k]], loop_n, repeat),
            "pyopw_inverse": _best_us_per_pose(
                lambda poses=poses, k=loop_n: [oracle.inverse(poses[i]) for i in range(k)], loop_n, repeat),
            "pyopw_batch_inverse": _best_us_per_pose(lambda poses=poses: oracle.batch_inverse(poses), n, repeat),
        }
        rows.append(row)
    return rows


def _se3(T: np.ndarray) -> pin.SE3:
    return pin.SE3(T[:3, :3], T[:3, 3])


def machine() -> str:
    """CPU model, core count and OS, for the results file."""
    cpu = platform.processor() or platform.machine()
    cpuinfo = Path("/proc/cpuinfo")
    if cpuinfo.exists():
        names = [line.split(":", 1)[1].strip() for line in cpuinfo.read_text().splitlines()
                 if line.startswith("model name")]
        cpu = names[0] if names else cpu
    import os

    return f"{cpu}, {os.cpu_count()} cores, {platform.system()} {platform.release()}"


def table(robot_name: str, rows: list[dict[str, float]]) -> str:
    lines = [
        f"### IK throughput ({robot_name}, microseconds per pose, best of runs)",
        "",
        f"Machine: {machine()}; Python {platform.python_version()}, "
        f"numpy {version('numpy')}, pin {version('pin')}, py-opw-kinematics {version('py-opw-kinematics')}.",
        "",
        "| N | singplan `opw_batch` (8 branches) | singplan `solve_all` (8 branches, limits, labels) "
        "| py-opw `inverse` (8 branches) | py-opw `batch_inverse` (1 branch) |",
        "|---:|---:|---:|---:|---:|",
    ]
    for r in rows:
        lines.append(f"| {r['n']:,} | {r['singplan_opw_batch']:.2f} | {r['singplan_solve_all']:.1f} "
                     f"| {r['pyopw_inverse']:.2f} | {r['pyopw_batch_inverse']:.2f} |")
    lines.append("")
    lines.append("`solve_all` is timed on at most 1000 poses; it classifies every solution with Pinocchio "
                 "FK, which dominates its cost.")
    return "\n".join(lines)


def write_section(path: Path, text: str, mark: str = "bench_ik") -> None:
    """Replace one benchmark's section of the results file (between its markers), keeping the others."""
    begin, end = f"<!-- {mark}:begin -->", f"<!-- {mark}:end -->"
    old = path.read_text() if path.exists() else "# Benchmarks\n"
    block = f"{begin}\n{text}\n{end}"
    if begin in old:
        head, rest = old.split(begin, 1)
        new = head + block + rest.split(end, 1)[1]
    else:
        new = old.rstrip() + "\n\n" + block + "\n"
    path.write_text(new)


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--robot", default="kuka_kr6_r900_2")
    parser.add_argument("--repeat", type=int, default=5)
    parser.add_argument("--sizes", type=int, nargs="+", default=[1, 100, 10_000])
    parser.add_argument("--write", type=Path, default=None, help="update this markdown file")
    args = parser.parse_args(argv)
    text = table(args.robot, measure(args.robot, args.sizes, args.repeat))
    sys.stdout.write(text + "\n")
    if args.write:
        write_section(args.write, text)
    return 0


if __name__ == "__main__":
    sys.exit(main())
