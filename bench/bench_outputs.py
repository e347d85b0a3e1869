"""What the pages cost: report.html and replay.html of a 60-move program beside its planning time,
and `singplan plan` of the demo with and without the pages, side by side in one run.

    python bench/bench_outputs.py [--repeat 3] [--demo-repeat 5] [--write docs/benchmarks.md]

The 60-move program (:func:`sixty_move_task`) is 20 rounds of examples/kuka_program.yaml's LIN
through a wrist singularity, its CIRC (every fifth one woven) and a PTP back to the start, on the
bundled KUKA KR 6 R900-2, method exact: 20 crossings, 100 segments, about 35 000 samples.
In one process: planning (in-process ``singplan.plan``, kernels loaded by a first plan), the
import of the page modules, then each page built alone and both as ``singplan plan`` builds
them (:func:`singplan.outputs.pages.build_pages`), best of ``--repeat``; and the pages' sizes.
The demo commands run in fresh interpreters, interleaved round by round (bench_startup's), the
median of ``--demo-repeat``. Issue 12's targets: both pages in under twice the planning time,
replay.html under 5 MB, the demo with its pages at most 1.3x the demo without.
"""

from __future__ import annotations

import argparse
import copy
import os
import platform
import statistics
import sys
import tempfile
import time
from collections.abc import Callable
from datetime import datetime, timezone
from importlib.metadata import version
from pathlib import Path
from typing import Any

import yaml

from singplan.kinematics.robot import Robot
from singplan.results.plan import plan
from singplan.results.trajectory import Trajectory
from singplan.task.load import parse_task

HERE = Path(__file__).resolve().parent
EXAMPLES = HERE.parent / "examples"
MARK = "bench_outputs"
_WEAVE = {"pattern": "sine", "amplitude_mm": 2.0, "wavelength_mm": 20.0}


def sixty_move_task(rounds: int = 20) -> dict[str, Any]:
    """``rounds`` x (LIN through the wrist singularity, CIRC, PTP back to the start): 3 x rounds moves."""
    task = yaml.safe_load((EXAMPLES / "kuka_program.yaml").read_text())
    lin, circ, _ = task["moves"]
    back = {"ptp": {"to": {"joints_deg": task["start"]["joints_deg"]}, "velocity_scale": 0.6}}
    moves = []
    for i in range(rounds):
        arc = copy.deepcopy(circ)
        if i % 5 == 4:
            arc["circ"]["weave"] = dict(_WEAVE)
        moves += [copy.deepcopy(lin), arc, copy.deepcopy(back)]
    task["moves"] = moves
    task["singularity"]["method"] = "exact"
    return task


def _best(fn: Callable[[], Any], repeat: int) -> tuple[float, Any]:
    best, value = float("inf"), None
    for _ in range(repeat):
        started = time.perf_counter()
        value = fn()
        best = min(best, time.perf_counter() - started)
    return best, value


def measure_program(repeat: int) -> dict[str, float]:
    """Seconds and bytes of the 60-move program: planning, page imports, each page, both pages."""
    plan(HERE.parent / "singplan" / "demo_task.yaml")  # kernels loaded, as in a second plan of a session
    task = parse_task(sixty_move_task())
    planning_s, traj = _best(lambda: plan(task), max(1, repeat - 1))
    started = time.perf_counter()
    from singplan.outputs import report, viewer  # the page modules' own imports

    import_s = time.perf_counter() - started
    assert report is not None
    robot = viewer.robot_of(traj)
    report_s, _ = _best(lambda: _pages(traj, robot, True, False), repeat)
    replay_s, _ = _best(lambda: _pages(traj, robot, False, True), repeat)
    both_s, pages = _best(lambda: _pages(traj, robot, True, True), repeat)
    return {"samples": len(traj.t), "segments": len(traj.segments),
            "crossings": sum(s.kind == "crossing" for s in traj.segments), "planning_s": planning_s,
            "import_s": import_s, "report_s": report_s, "replay_s": replay_s, "both_s": both_s,
            "report_mb": len(pages["report.html"].encode()) / 1e6,
            "replay_mb": len(pages["replay.html"].encode()) / 1e6}


def _pages(traj: Trajectory, robot: Robot, report: bool, replay: bool) -> dict[str, str]:
    from singplan.outputs.pages import build_pages

    pages, skipped = build_pages(traj, robot, report, replay)
    if skipped:
        raise RuntimeError(f"pages not built: {skipped}")
    return pages


def measure_demo(repeat: int) -> dict[str, list[float]]:
    """Wall times [s] of `singplan plan demo` without and with its pages, fresh interpreters."""
    sys.path.insert(0, str(HERE))
    from bench_startup import commands, run_once  # one definition of the demo commands

    demo = [c for c in commands() if c.label.startswith("`singplan plan demo")]
    env = {**os.environ, "PYTHONPATH": str(HERE.parent)}
    times: dict[str, list[float]] = {c.label: [] for c in demo}
    with tempfile.TemporaryDirectory() as scratch:
        run_once(demo[0], Path(scratch), env)  # kernels compiled and cached
        for _ in range(repeat):
            for c in demo:
                times[c.label].append(run_once(c, Path(scratch), env)[0])  # wall time
    return times


def table(program: dict[str, float], demo: dict[str, list[float]], load: tuple[float, float]) -> str:
    p = program
    labels = list(demo)
    without, with_pages = (statistics.median(demo[label]) for label in labels)
    return "\n".join([
        "### Report and replay of a 60-move program; the demo with and without its pages",
        "",
        f"Measured {datetime.now(timezone.utc):%Y-%m-%d %H:%M} UTC. Machine: {_machine()}; Python "
        f"{platform.python_version()}, pin {version('pin')}, numpy {version('numpy')}, meshcat {version('meshcat')}. "
        f"Load average (1 min) {load[0]:.1f} before, {load[1]:.1f} after.",
        "",
        f"60-move program ({p['samples']:,} samples, {p['segments']} segments, {p['crossings']} crossings), "
        "in one process, best of runs:",
        "",
        "| planning [s] | page modules' import [s] | report.html [s] | replay.html [s] | both pages [s] "
        "| both / planning (target < 2) | report.html [MB] | replay.html [MB] (target < 5) |",
        "|---:|---:|---:|---:|---:|---:|---:|---:|",
        f"| {p['planning_s']:.2f} | {p['import_s']:.2f} | {p['report_s']:.2f} | {p['replay_s']:.2f} "
        f"| {p['both_s']:.2f} | {p['both_s'] / p['planning_s']:.2f} | {p['report_mb']:.2f} | {p['replay_mb']:.2f} |",
        "",
        f"`singplan plan` of the demo task, fresh interpreters, median of {len(demo[labels[0]])} interleaved runs:",
        "",
        "| command | median [s] | min - max [s] |",
        "|---|---:|---:|",
        *(f"| {label} | {statistics.median(v):.3f} | {min(v):.3f} - {max(v):.3f} |" for label, v in demo.items()),
        "",
        f"With the pages / without: {with_pages / without:.2f} (target <= 1.3).",
    ])


def _machine() -> str:
    sys.path.insert(0, str(HERE))
    from bench_ik import machine  # one definition of the machine line for every benchmark

    return machine()


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--repeat", type=int, default=3)
    parser.add_argument("--demo-repeat", type=int, default=5)
    parser.add_argument("--write", type=Path, default=None)
    args = parser.parse_args(argv)
    load_before = os.getloadavg()[0]
    program = measure_program(args.repeat)
    demo = measure_demo(args.demo_repeat)
    text = table(program, demo, (load_before, os.getloadavg()[0]))
    sys.path.insert(0, str(HERE))
    from bench_ik import emit

    emit(text, args.write, MARK)
    return 0


if __name__ == "__main__":
    sys.exit(main())
