"""All-branch IK throughput: singplan's vectorised OPW solver beside py-opw-kinematics.

    python bench/bench_ik.py [--robot kuka_kr6_r900_2] [--repeat 5] [--write docs/benchmarks.md]

For N = 1, 100 and 10 000 random poses of one arm, in one run on one machine:
- singplan ``opw_batch``: all eight branches for the N poses at once;
- singplan ``solve_all``: the single-pose API (all branches, limits, labels) in a loop;
- py-opw-kinematics ``inverse`` in a loop (all branches of one pose per call);
- py-opw-kinematics ``batch_inverse`` (one branch per pose, nearest the previous).
Times are the best of ``--repeat`` runs, in microseconds per pose.

    python bench/bench_ik.py --numeric [--poses 30] [--write docs/kinematics.md]

The numeric all-branch solver (singplan.kinematics.ik.numeric) on arms without and with a closed form:
milliseconds per call and the branches it finds against a reference (the closed form inside
the limits, or for the offset-wrist arm the brute force of tests/test_ik_numeric.py).

    python bench/bench_ik.py --solve-all [--baseline DIR [--baseline-label TEXT]] [--poses 1000]
                             [--arms ARM ...] [--write docs/benchmarks.md]

``solve_all`` per pose (every branch and whole-turn variant inside the limits, labelled) on OPW
and UR arms (default: the KUKA KR 6 R900-2, the ABB IRB 2400 and the UR5), without and with a
seed, each tree in a fresh process (``--baseline``: a tree of an earlier singplan, e.g. a
``git archive`` of a commit, measured alternately with this one in the same run; the table
names it by ``--baseline-label``), beside py-opw-kinematics ``inverse`` (eight branches, no
limits, no labels). The load average is read before and after the run.
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

from singplan.kinematics.ik.numeric import all_branches
from singplan.kinematics.ik.solve import closed_form_branches, opw_batch, solve_all
from singplan.kinematics.robot import Robot, load_robot, robots_dir

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))  # the reference lives with its tests
from tests.test_ik_numeric import brute_force_branches, found_in, has_variant_inside


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
    lines.append("`solve_all` is timed on at most 1000 poses (it also expands whole turns inside the limits and "
                 "labels every row: see the next table).")
    return "\n".join(lines)


def emit(text: str, path: Path | None, mark: str) -> None:
    """Print a benchmark's table and, when asked, write it into its section of the results file."""
    sys.stdout.write(text + "\n")
    if path is not None:
        write_section(path, text, mark)


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


def offset_wrist_robot(folder: Path) -> Robot:
    """The FANUC M-10iA with axis 6 moved 50 mm off axis 5 (as in tests/test_ik_numeric.py)."""
    text = (robots_dir() / "fanuc_m10ia.urdf").read_text()
    old = '<origin xyz="0.1 0.0 0.0" rpy="0.0 -0.0 0.0"/>\n    <axis xyz="-1.0 0.0 0.0"/>'
    assert text.count(old) == 1
    path = folder / "fanuc_m10ia_offset_wrist.urdf"
    path.write_text(text.replace(old, old.replace("0.1 0.0 0.0", "0.1 0.0 0.05")))
    return load_robot(path)


def measure_numeric(robot: Robot, n_poses: int, seed: int = 11) -> dict[str, float]:
    """ms per all_branches call (median, max) and branches found / reference over random FK poses."""
    rng = np.random.default_rng(seed)
    times_ms, found, reference_total, extra = [], 0, 0, 0
    for _ in range(n_poses):
        T = robot.fk(rng.uniform(robot.lower_rad, robot.upper_rad))
        closed = closed_form_branches(robot, T.homogeneous[None])[0]
        reference = ([c for c in closed if np.all(np.isfinite(c)) and has_variant_inside(robot, c)] if closed.shape[0]
                     else brute_force_branches(robot, T, rng))
        t0 = time.perf_counter()
        rows, _ = all_branches(robot, T)
        times_ms.append((time.perf_counter() - t0) * 1e3)
        reference_total += len(reference)
        found += sum(found_in(b, rows) for b in reference)
        extra += sum(not found_in(r, reference) for r in rows)
    return {"poses": n_poses, "found": found, "reference": reference_total, "extra": extra,
            "median_ms": float(np.median(times_ms)), "max_ms": float(np.max(times_ms))}


def numeric_table(rows: dict[str, dict[str, float]]) -> str:
    lines = [
        "### Numeric all-branch IK (`singplan.kinematics.ik.numeric.all_branches`)",
        "",
        f"Machine: {machine()}; Python {platform.python_version()}, pin {version('pin')}. "
        "Random poses = FK of uniform random joints inside the limits (seed 11).",
        "",
        "| arm | reference | poses | branches found / reference | not in reference | ms per call (median) | ms (max) |",
        "|---|---|---:|---:|---:|---:|---:|",
    ]
    for name, r in rows.items():
        ref = "brute force (1000 random starts)" if "offset" in name else "closed form inside limits"
        lines.append(f"| {name} | {ref} | {r['poses']} | {r['found']} / {r['reference']} | {r['extra']} "
                     f"| {r['median_ms']:.1f} | {r['max_ms']:.1f} |")
    return "\n".join(lines)


def main_numeric(n_poses: int, write: Path | None) -> int:
    import tempfile

    with tempfile.TemporaryDirectory() as folder:
        arms = {"fanuc_m10ia with axis 6 offset 50 mm": offset_wrist_robot(Path(folder)),
                "fanuc_m10ia": load_robot("fanuc_m10ia"), "kuka_kr6_r900_2": load_robot("kuka_kr6_r900_2"),
                "ur5": load_robot("ur5")}
        text = numeric_table({name: measure_numeric(robot, n_poses) for name, robot in arms.items()})
    sys.stdout.write(text + "\n")
    if write:
        write_section(write, text, mark="bench_ik_numeric")
    return 0


SOLVE_ALL_ARMS = ("kuka_kr6_r900_2", "abb_irb2400", "ur5")


def solve_all_figures(poses: int, repeat: int, arms: list[str]) -> dict[str, dict[str, float]]:
    """solve_all's microseconds per pose (best of ``repeat`` loops) without and with a seed, and the
    mean number of rows, per arm; seeded random poses inside the limits (capped at +-2 pi)."""
    out = {}
    for name in arms:
        robot = load_robot(name)
        rng = np.random.default_rng(24)
        q = rng.uniform(np.maximum(robot.lower_rad, -2 * np.pi), np.minimum(robot.upper_rad, 2 * np.pi),
                        size=(poses, robot.n_joints))
        targets = [robot.fk(qk) for qk in q]
        seeds = q + rng.normal(0.0, 0.3, q.shape)
        solve_all(robot, targets[0])  # kernels loaded
        out[name] = {
            "free_us": _best_us_per_pose(lambda r=robot, ts=targets: [solve_all(r, T) for T in ts], poses, repeat),
            "seeded_us": _best_us_per_pose(lambda r=robot, ts=targets, ss=seeds: [
                solve_all(r, T, seed=s) for T, s in zip(ts, ss, strict=True)], poses, repeat),
            "rows": float(np.mean([len(solve_all(robot, T)) for T in targets])),
        }
    return out


def _solve_all_in(tree: Path, poses: int, repeat: int, arms: list[str]) -> dict[str, dict[str, float]]:
    """:func:`solve_all_figures` of the singplan in ``tree``, in a fresh process."""
    import json
    import os
    import subprocess

    argv = [sys.executable, __file__, "--solve-all-child", "--poses", str(poses), "--repeat", str(repeat),
            "--arms", *arms]
    done = subprocess.run(argv, env={**os.environ, "PYTHONPATH": str(tree)}, capture_output=True, text=True,
                          check=True)
    figures: dict[str, dict[str, float]] = json.loads(done.stdout.strip().splitlines()[-1])
    return figures


def solve_all_table(trees: dict[str, Path], poses: int, repeat: int, baseline: str | None,
                    arms: list[str]) -> str:
    import os

    load_before = os.getloadavg()[0]
    results: dict[str, list[dict[str, dict[str, float]]]] = {label: [] for label in trees}
    for _ in range(2):  # two rounds, alternating the trees; the best of each
        for label, tree in trees.items():
            results[label].append(_solve_all_in(tree, poses, repeat, arms))
    load_after = os.getloadavg()[0]
    best = {label: {arm: {k: min(r[arm][k] for r in runs) for k in runs[0][arm]} for arm in arms}
            for label, runs in results.items()}
    labels = list(trees)
    lines = [
        "### `solve_all` per pose (all branches and whole turns inside the limits, labelled)",
        "",
        f"Machine: {machine()}, load average {load_before:.1f} before the run and {load_after:.1f} after; "
        f"Python {platform.python_version()}, numpy {version('numpy')}, "
        f"numba {version('numba')}, pin {version('pin')}, py-opw-kinematics {version('py-opw-kinematics')}. "
        f"{poses} seeded random poses an arm; microseconds per pose, the best of {repeat} loops in each of two "
        "fresh processes per tree" + (f", `before` = {baseline}, measured alternately in the same run" if baseline
                                      else "") + "; a shared machine: compare the ratios.",
        "",
        "| arm | rows a pose | " + " | ".join(f"{lb} (no seed)" for lb in labels) + " | "
        + " | ".join(f"{lb} (seeded)" for lb in labels) + " | py-opw `inverse` (8 branches) |",
        "|---|---:|" + "---:|" * (2 * len(labels) + 1),
    ]
    for arm in arms:
        robot = load_robot(arm)
        reference = "-"
        if robot.opw is not None:
            oracle = _oracle(robot)
            poses_T = RigidTransform.from_matrix(np.array([robot.fk(q).homogeneous for q in np.random.default_rng(
                24).uniform(robot.lower_rad, robot.upper_rad, size=(poses, 6))]))
            us = _best_us_per_pose(lambda o=oracle, ps=poses_T: [o.inverse(ps[i]) for i in range(poses)], poses, 3)
            reference = f"{us:.1f}"
        free = [f"{best[lb][arm]['free_us']:.1f}" for lb in labels]
        seeded = [f"{best[lb][arm]['seeded_us']:.1f}" for lb in labels]
        lines.append(f"| {arm} | {best[labels[-1]][arm]['rows']:.0f} | " + " | ".join(free) + " | "
                     + " | ".join(seeded) + f" | {reference} |")
    return "\n".join(lines)


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--robot", default="kuka_kr6_r900_2")
    parser.add_argument("--repeat", type=int, default=5)
    parser.add_argument("--sizes", type=int, nargs="+", default=[1, 100, 10_000])
    parser.add_argument("--write", type=Path, default=None, help="update this markdown file")
    parser.add_argument("--numeric", action="store_true", help="the numeric all-branch solver instead")
    parser.add_argument("--poses", type=int, default=None,
                        help="random poses per arm (--numeric: 30, --solve-all: 1000)")
    parser.add_argument("--solve-all", action="store_true", help="solve_all per pose, beside --baseline")
    parser.add_argument("--baseline", type=Path, default=None, help="a tree of an earlier singplan (--solve-all)")
    parser.add_argument("--baseline-label", default=None, help="how the table names --baseline (default its path)")
    parser.add_argument("--arms", nargs="+", default=list(SOLVE_ALL_ARMS), help="the arms of --solve-all")
    parser.add_argument("--solve-all-child", action="store_true", help=argparse.SUPPRESS)
    args = parser.parse_args(argv)
    if args.numeric:
        return main_numeric(args.poses or 30, args.write)
    if args.solve_all_child:
        import json

        sys.stdout.write(json.dumps(solve_all_figures(args.poses or 1000, args.repeat, args.arms)) + "\n")
        return 0
    if args.solve_all:
        trees = {"before": args.baseline.resolve()} if args.baseline else {}
        trees["this"] = Path(__file__).resolve().parents[1]
        label = args.baseline_label or (str(args.baseline) if args.baseline else None)
        text = solve_all_table(trees, args.poses or 1000, args.repeat, label, args.arms)
        sys.stdout.write(text + "\n")
        if args.write:
            write_section(args.write, text, mark="bench_ik_solve_all")
        return 0
    text = table(args.robot, measure(args.robot, args.sizes, args.repeat))
    sys.stdout.write(text + "\n")
    if args.write:
        write_section(args.write, text)
    return 0


if __name__ == "__main__":
    sys.exit(main())
