"""Long programs of wrist-crossing LINs (issue 24): milliseconds a move, peak memory, durations.

    python bench/bench_program.py [--moves 40 1000] [--methods auto exact] [--baseline DIR]
                                  [--write docs/benchmarks.md]
    python bench/bench_program.py --profile 1000 [--methods auto]

The program: N LINs back and forth on the KUKA KR 6 R900-2 (tool 0.1 m, 0.25 m/s, acceleration
limit 10 rad/s^2, period 4 ms) between a pose just off the wrist singularity and one across it,
so every move crosses the wrist zone. Each (N, method) is planned by ``singplan.plan`` in a fresh
subprocess after a two-move warm-up (imports, compiled kernels from the disk cache); the figures
are that process's planning time and its peak RSS (``os.wait4``) above its RSS after the warm-up.

``--baseline DIR``: a tree of an earlier singplan (e.g. ``git archive <commit> | tar -x -C DIR``)
planned the same way, alternating with this tree (``--rounds`` times each, the fastest kept), so
the ratios are measured side by side on whatever load the machine has; the durations and every
move's sample count are compared.

``--profile N``: cProfile of one plan of N moves in this process, the cumulative time of each
planning stage (stages nest: the table says which contains which).
"""

from __future__ import annotations

import argparse
import cProfile
import json
import os
import platform
import pstats
import resource
import subprocess
import sys
import tempfile
import time
from importlib.metadata import version
from pathlib import Path
from typing import Any

import numpy as np

HERE = Path(__file__).resolve().parent
ROOT = HERE.parent
MARK = "bench_program"
START_DEG = [34.466047735, -69.193961827, 100.109975431, 68.691762951, -14.064499937, -11.872434380]
ACROSS = {"xyz": [0.703837, -0.107362, 0.658022], "rpy_deg": [-121.329770, 35.631042, -129.525465]}
TIMEOUT_S = 3600


def program(moves: int, method: str) -> dict[str, Any]:
    """The task mapping: ``moves`` LINs alternating between the pose across the wrist and the start pose."""
    import pinocchio as pin

    from singplan.kinematics.robot import load_robot

    robot = load_robot("kuka_kr6_r900_2", tool=pin.SE3(np.eye(3), np.array([0.0, 0.0, 0.1])))
    T0 = robot.fk(np.radians(START_DEG))
    start = {"xyz": T0.translation.tolist(), "rpy_deg": np.degrees(pin.rpy.matrixToRpy(T0.rotation)).tolist()}
    return {"robot": "kuka_kr6_r900_2", "tool": {"xyz": [0, 0, 0.1]}, "start": {"joints_deg": START_DEG},
            "moves": [{"lin": {"to": ACROSS if k % 2 == 0 else start, "speed": 0.25}} for k in range(moves)],
            "singularity": {"method": method, "orientation_tolerance_deg": 1.0, "position_tolerance_mm": 0.01},
            "limits": {"acceleration": 10.0}, "output": {"period": 0.004}}


def child(moves: int, method: str) -> None:
    """Plan the program once (after a warm-up) and print its figures as JSON."""
    from singplan.results.plan import plan
    from singplan.task.load import parse_task

    plan(parse_task(program(2, method)))
    base_mb = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024
    task = parse_task(program(moves, method))
    t0 = time.perf_counter()
    traj = plan(task)
    seconds = time.perf_counter() - t0
    counts = [round((m.t1 - m.t0) / traj.period) for m in traj.moves]
    print(json.dumps({"seconds": seconds, "base_mb": base_mb, "duration_s": traj.duration_s,
                      "samples": len(traj.t), "move_samples": counts,
                      "output_mb": (traj.q.nbytes + traj.qd.nbytes + traj.qdd.nbytes + traj.t.nbytes) / 2**20,
                      "arrays_mb": (traj.q.nbytes + traj.qd.nbytes + traj.qdd.nbytes + traj.t.nbytes
                                    + sum(np.asarray(v).nbytes for v in traj.samples.values())) / 2**20}))


def run(tree: Path, moves: int, method: str) -> dict[str, Any]:
    """One child in a fresh process on ``tree``: its figures and its peak RSS [MB]."""
    env = {**os.environ, "PYTHONPATH": str(tree)}
    argv = [sys.executable, str(HERE / "bench_program.py"), "--child", str(moves), method]
    with tempfile.TemporaryFile("w+") as out, tempfile.TemporaryFile("w+") as err:
        proc = subprocess.Popen(argv, env=env, cwd=tree, stdout=out, stderr=err, text=True)
        _, status, usage = os.wait4(proc.pid, 0)
        proc.returncode = os.waitstatus_to_exitcode(status)
        out.seek(0)
        err.seek(0)
        if proc.returncode != 0:
            raise RuntimeError(f"{tree} {moves} {method}: exit {proc.returncode}\n{err.read()[-2000:]}")
        figures: dict[str, Any] = json.loads(out.read().strip().splitlines()[-1])
    figures["peak_mb"] = usage.ru_maxrss / 1024
    return figures


def measure(trees: dict[str, Path], sizes: list[int], methods: list[str], rounds: int) -> list[dict[str, Any]]:
    """Each (size, method) on each tree ``rounds`` times, the trees alternately; the fastest run of each."""
    rows = []
    for moves in sizes:
        for method in methods:
            row: dict[str, Any] = {"moves": moves, "method": method}
            for _ in range(rounds):
                for label, tree in trees.items():
                    f = run(tree, moves, method)
                    print(f"{label:8s} {moves:5d} {method:6s} {f['seconds'] / moves * 1e3:7.1f} ms/move "
                          f"peak {f['peak_mb']:6.0f} MB (+{f['peak_mb'] - f['base_mb']:.0f})  "
                          f"{f['duration_s']:.3f} s, {f['samples']} samples", flush=True)
                    if label not in row or f["seconds"] < row[label]["seconds"]:
                        row[label] = f
            rows.append(row)
    return rows


def table(rows: list[dict[str, Any]], labels: list[str]) -> str:
    pair = len(labels) == 2
    head = ["moves", "method", *(f"{lb} [ms/move]" for lb in labels), *(["ratio"] if pair else []),
            *(f"{lb} peak over warm-up [MB]" for lb in labels), "trajectory arrays [MB]",
            "all per-sample arrays [MB]", *(f"{lb} peak over them [MB]" for lb in labels), "duration [s]",
            *(["same durations"] if pair else [])]
    lines = ["| " + " | ".join(head) + " |", "|" + "---:|" * len(head)]
    for r in rows:
        f = [r[lb] for lb in labels]
        cells = [str(r["moves"]), r["method"], *(f"{x['seconds'] / r['moves'] * 1e3:.1f}" for x in f)]
        if pair:
            cells.append(f"{f[0]['seconds'] / f[1]['seconds']:.1f}x")
        cells += [f"{x['peak_mb'] - x['base_mb']:.0f}" for x in f]
        cells += [f"{f[-1]['output_mb']:.1f}", f"{f[-1]['arrays_mb']:.1f}"]
        cells += [f"{x['peak_mb'] - x['base_mb'] - f[-1]['arrays_mb']:.0f}" for x in f]
        cells.append(f"{f[-1]['duration_s']:.3f}")
        if pair:
            same = f[0]["move_samples"] == f[1]["move_samples"] and f[0]["samples"] == f[1]["samples"]
            cells.append("yes" if same else "**no**")
        lines.append("| " + " | ".join(cells) + " |")
    return "\n".join(lines)


def report(rows: list[dict[str, Any]], labels: list[str], baseline: str | None, rounds: int) -> str:
    load = os.getloadavg()
    return "\n".join([
        "### Long programs of wrist-crossing LINs (KUKA KR 6 R900-2)", "",
        f"Machine: {_machine()}; load average {load[0]:.1f} / {load[1]:.1f} / {load[2]:.1f} (1 / 5 / 15 min) at "
        f"the end of the run: a shared machine, so compare the ratio, measured in the same run. Python "
        f"{platform.python_version()}, numpy {version('numpy')}, numba {version('numba')}, pin {version('pin')}, "
        f"toppra {version('toppra')}.", "",
        "N LINs back and forth across the wrist zone (0.25 m/s, 10 rad/s^2, 4 ms), each planned in a fresh "
        f"process after a two-move warm-up, {rounds} times, the fastest kept; peak RSS above the RSS after the "
        "warm-up, and above that the record's own per-sample arrays (q, qd, qdd, t and every per-sample series: "
        "what any plan of these moves returns). "
        + (f"`{labels[0]}` is {baseline}, planned alternately with `{labels[1]}` (this tree); 'same durations': "
           "every move's sample count and the total equal." if baseline else ""), "",
        table(rows, labels)])


def _machine() -> str:
    cpu = platform.machine()
    cpuinfo = Path("/proc/cpuinfo")
    if cpuinfo.exists():
        names = [ln.split(":", 1)[1].strip() for ln in cpuinfo.read_text().splitlines() if ln.startswith("model name")]
        cpu = names[0] if names else cpu
    return f"{cpu}, {os.cpu_count()} cores, {platform.system()} {platform.release()}"


# (label, pstats function key suffix): the planning stages, outermost first
STAGES = [
    ("plan_moves: every move planned and timed", "planning/orchestration/planner.py", "plan_moves"),
    ("  auto: candidates prepared (joint maps, timing paths, refusals)", "planning/orchestration/select.py",
     "_prepared"),
    ("    plan_move: tracking and crossing of one candidate", "planning/orchestration/move_plan.py", "plan_cartesian"),
    ("    timing_path: reference samples and spline", "planning/timing/toppra.py", "timing_path"),
    ("    refusal: the candidate's checks", "planning/orchestration/checks.py", "refusal"),
    ("  auto: candidates timed best bound first", "planning/orchestration/select.py", "_timed_best_first"),
    ("    time_move: TOPP-RA passes, sampling, checks", "planning/timing/move.py", "time_move"),
    ("      TOPP-RA (compiled reachability analysis)", "planning/timing/reachability.py", "solve"),
    ("  JointMap.evaluate, every caller (reference samples, checks, output samples)", "planning/path/jointmap.py",
     "evaluate"),
    ("build_trajectory: samples, segments, metrics", "results/build.py", "build_trajectory"),
    ("checks of the record, sample by sample", "results/plan.py", "_check_metrics"),
]


def profile(moves: int, method: str) -> str:
    from singplan.results.plan import plan
    from singplan.task.load import parse_task

    plan(parse_task(program(2, method)))
    task = parse_task(program(moves, method))
    profiler = cProfile.Profile()
    t0 = time.perf_counter()
    profiler.runcall(plan, task)
    total = time.perf_counter() - t0
    stats = pstats.Stats(profiler).stats  # type: ignore[attr-defined]
    lines = [f"cProfile of one plan of {moves} moves ({method}): {total:.1f} s under the profiler, "
             f"{total / moves * 1e3:.1f} ms a move", "",
             "| stage | calls | cumulative [s] | share |", "|---|---:|---:|---:|"]
    for label, path, name in STAGES:
        hits = [(v[1], v[3]) for (file, _, func), v in stats.items() if file.endswith(path) and func == name]
        calls, cum = (sum(h[0] for h in hits), sum(h[1] for h in hits)) if hits else (0, 0.0)
        lines.append(f"| {label} | {calls} | {cum:.2f} | {cum / total:.0%} |")
    top = sorted(stats.items(), key=lambda kv: kv[1][2], reverse=True)[:15]
    lines += ["", "Own time (tottime), the 15 largest:", "", "| function | calls | own [s] |", "|---|---:|---:|"]
    for (file, line, func), v in top:
        lines.append(f"| `{Path(file).name}:{line} {func}` | {v[1]} | {v[2]:.2f} |")
    return "\n".join(lines)


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--moves", type=int, nargs="+", default=[40, 1000])
    parser.add_argument("--methods", nargs="+", default=["auto", "exact"])
    parser.add_argument("--baseline", type=Path, help="a tree of an earlier singplan, planned alternately")
    parser.add_argument("--rounds", type=int, default=3, help="runs of each tree, size and method (the fastest kept)")
    parser.add_argument("--write", type=Path, help="write the table into this results file (its own section)")
    parser.add_argument("--profile", type=int, metavar="N", help="cProfile one plan of N moves per stage")
    parser.add_argument("--child", nargs=2, metavar=("MOVES", "METHOD"), help=argparse.SUPPRESS)
    args = parser.parse_args(argv)
    if args.child:
        child(int(args.child[0]), args.child[1])
        return 0
    if args.profile:
        for method in args.methods:
            print(profile(args.profile, method) + "\n")
        return 0
    trees = {"before": args.baseline.resolve()} if args.baseline else {}
    trees["this"] = ROOT
    rows = measure(trees, args.moves, args.methods, args.rounds)
    text = report(rows, list(trees), f"`{args.baseline}`" if args.baseline else None, args.rounds)
    from bench_ik import emit  # here, not above: it loads py-opw-kinematics

    emit(text, args.write, MARK)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
