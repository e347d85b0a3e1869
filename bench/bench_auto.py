"""What auto costs against one method: planning time of exact vs auto on the public LIN scenarios,
and a long program whose every LIN crosses the wrist (auto vs wrist-joint), side by side in one run.

    python bench/bench_auto.py [--scenarios ../shared/scenarios] [--repeat 5] [--lins 200] [--write docs/benchmarks.md]

Targets (issue 12): auto at most 1.5x exact's planning time (median over the public LIN
scenarios), 2.5x worst. Each scenario is planned in-process (imports and the robot's first
load excluded) ``--repeat`` times per method, the methods alternating run by run so that a change
of the machine's load falls on both alike; the table gives the medians. Two times per plan:
``plan()`` (everything a caller waits for: planning, the trajectory record and its checks) and
the planning stage alone (``PlannedTask.planning_s``: tracking, crossings, timing of every
candidate). A scenario exact cannot plan (exit 3 where a crossing is needed) has no exact
planning time; it is listed and left out of the ratios. The program is planned once per method.
"""

from __future__ import annotations

import argparse
import math
import os
import platform
import statistics
import sys
import time
from dataclasses import dataclass
from importlib.metadata import version
from pathlib import Path
from typing import Any

import numpy as np
import pinocchio as pin
import yaml

from singplan.errors import SingplanError
from singplan.planning.orchestration.planner import plan_moves
from singplan.planning.orchestration.targets import load_task_robot
from singplan.results.plan import trajectory_of
from singplan.task.load import load_task, parse_task
from singplan.task.schema import Task

HERE = Path(__file__).resolve().parent
MARK = "bench_auto"
PROGRAM_SOURCE = "abb_irb2400__wrist_near_lin"  # its LIN crosses the wrist; the program goes back and forth on it


@dataclass(frozen=True)
class Timing:
    """Median wall times of one method on one task [s], or why it does not plan."""

    plan_s: float  # plan(): planning, trajectory record and checks
    planning_s: float  # the planning stage alone
    duration_s: float | None  # the trajectory's duration; None when the method cannot plan the task
    chosen: str  # the methods the moves were planned with


def run_once(task: Task, method: str) -> Timing:
    """Plan ``task`` with ``method`` once: the wall times, or the exit code where it does not plan."""
    t0 = time.perf_counter()
    try:
        planned = plan_moves(task, method)
        traj = trajectory_of(planned)
    except SingplanError as exc:
        elapsed = time.perf_counter() - t0
        return Timing(elapsed, elapsed, None, f"exit {exc.exit_code}")
    elapsed = time.perf_counter() - t0
    chosen = ", ".join(sorted({f"{pm.method} {pm.variant}".strip() for pm in planned.moves}))
    return Timing(elapsed, planned.planning_s, traj.duration_s, chosen)


def _median(runs: list[Timing]) -> Timing:
    return Timing(statistics.median(t.plan_s for t in runs), statistics.median(t.planning_s for t in runs),
                  runs[-1].duration_s, runs[-1].chosen)


def lin_scenarios(scenarios: Path) -> list[tuple[str, Task]]:
    """The public scenarios that must plan and whose moves are all LINs."""
    expect = yaml.safe_load((scenarios / "expect.yaml").read_text())
    out = []
    for name in sorted(expect):
        if expect[name].get("exit") != 0:
            continue
        task = load_task(scenarios / f"{name}.yaml")
        if all(move.kind == "lin" for move in task.moves):
            out.append((name, task))
    return out


def measure_scenarios(scenarios: Path, runs: int) -> list[tuple[str, Timing, Timing]]:
    rows = []
    for name, task in lin_scenarios(scenarios):
        timings: dict[str, list[Timing]] = {"exact": [], "auto": []}
        for method in timings:
            run_once(task, method)  # warm-up: the robot's first load, numba's cache
        for _ in range(runs):  # the methods alternate, one run at a time
            for method, kept in timings.items():
                kept.append(run_once(task, method))
        rows.append((name, _median(timings["exact"]), _median(timings["auto"])))
    return rows


def wrist_program(scenarios: Path, lins: int) -> Task:
    """``lins`` LINs back and forth along the wrist-crossing LIN of PROGRAM_SOURCE: each crosses the wrist."""
    doc: dict[str, Any] = yaml.safe_load((scenarios / f"{PROGRAM_SOURCE}.yaml").read_text())
    robot = load_task_robot(parse_task(doc))
    T0 = robot.fk(np.radians(doc["start"]["joints_deg"]))
    start = {"xyz": T0.translation.tolist(), "rpy_deg": np.degrees(pin.rpy.matrixToRpy(T0.rotation)).tolist()}
    target = doc["moves"][0]["lin"]["to"]
    speed = doc["moves"][0]["lin"]["speed"]
    doc["moves"] = [{"lin": {"to": target if k % 2 == 0 else start, "speed": speed}} for k in range(lins)]
    return parse_task(doc)


def measure_program(scenarios: Path, lins: int) -> dict[str, Timing]:
    task = wrist_program(scenarios, lins)
    return {method: _program_once(task, method) for method in ("wrist-joint", "auto")}


def _program_once(task: Task, method: str) -> Timing:
    timing = run_once(task, method)
    if timing.duration_s is None:
        return timing
    return Timing(timing.plan_s, timing.planning_s, timing.duration_s, f"{len(task.moves)} LINs: {timing.chosen}")


def report(rows: list[tuple[str, Timing, Timing]], program: dict[str, Timing], lins: int, runs: int) -> str:
    ratios = [(a.plan_s / e.plan_s, a.planning_s / e.planning_s) for _, e, a in rows if e.duration_s is not None]
    med_plan, med_stage = (statistics.median(r[i] for r in ratios) for i in (0, 1))
    worst_plan, worst_stage = (max(r[i] for r in ratios) for i in (0, 1))
    load = os.getloadavg()[0] if hasattr(os, "getloadavg") else math.nan
    lines = [
        "### auto against exact on the public LIN scenarios, and a program of wrist crossings",
        "",
        f"Machine: {_machine()}; Python {platform.python_version()}, pin {version('pin')}, "
        f"toppra {version('toppra')}, numpy {version('numpy')}, numba {version('numba')}; "
        f"load average {load:.2f} at the end of the run.",
        "",
        f"Median of {runs} in-process runs per method, the methods alternating run by run. `plan()` is "
        "what a caller waits for (planning, trajectory record, checks); \"planning\" is the planning stage "
        "alone (`PlannedTask.planning_s`). Ratios are auto / exact.",
        "",
        "| scenario | exact plan() [s] | auto plan() [s] | ratio | exact planning [s] | auto planning [s] | ratio "
        "| exact duration [s] | auto duration [s] | auto chose |",
        "|---|---:|---:|---:|---:|---:|---:|---:|---:|---|",
    ]
    for name, e, a in rows:
        if e.duration_s is None:
            lines.append(f"| {name} | {e.chosen} | {a.plan_s:.3f} | - | {e.chosen} | {a.planning_s:.3f} | - | "
                         f"{e.chosen} | {_dur(a)} | {a.chosen} |")
            continue
        lines.append(f"| {name} | {e.plan_s:.3f} | {a.plan_s:.3f} | {a.plan_s / e.plan_s:.2f} | "
                     f"{e.planning_s:.3f} | {a.planning_s:.3f} | {a.planning_s / e.planning_s:.2f} | "
                     f"{_dur(e)} | {_dur(a)} | {a.chosen} |")
    lines += [
        "",
        f"auto / exact over the {len(ratios)} scenarios exact can plan: `plan()` median **{med_plan:.2f}x**, "
        f"worst **{worst_plan:.2f}x**; planning stage median **{med_stage:.2f}x**, worst **{worst_stage:.2f}x** "
        "(targets: 1.5x median, 2.5x worst).",
        "",
        f"Program: {lins} LINs back and forth along `{PROGRAM_SOURCE}`'s LIN (each crosses the wrist), "
        "planned once per method:",
        "",
        "| method | plan() [s] | planning [s] | duration [s] | moves |",
        "|---|---:|---:|---:|---|",
    ]
    for method, t in program.items():
        lines.append(f"| {method} | {t.plan_s:.1f} | {t.planning_s:.1f} | {_dur(t)} | {t.chosen} |")
    wj, auto = program["wrist-joint"], program["auto"]
    lines += ["", f"auto / wrist-joint on the program: {auto.plan_s / wj.plan_s:.2f}x (`plan()`)."]
    return "\n".join(lines)


def _dur(t: Timing) -> str:
    return f"{t.duration_s:.3f}" if t.duration_s is not None else t.chosen


def _machine() -> str:
    sys.path.insert(0, str(HERE))
    from bench_ik import machine  # one definition of the machine line for every benchmark

    return machine()


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--scenarios", type=Path, default=HERE.parents[1] / "shared" / "scenarios")
    parser.add_argument("--repeat", type=int, default=5, help="runs per method and scenario (median)")
    parser.add_argument("--lins", type=int, default=200, help="LINs in the wrist program")
    parser.add_argument("--write", type=Path, default=None, help="results file to update (its bench_auto section)")
    args = parser.parse_args(argv)
    rows = measure_scenarios(args.scenarios, args.repeat)
    program = measure_program(args.scenarios, args.lins)
    text = report(rows, program, args.lins, args.repeat)
    sys.path.insert(0, str(HERE))
    from bench_ik import emit

    emit(text, args.write, MARK)
    return 0


if __name__ == "__main__":
    sys.exit(main())
