"""Peak memory and time of planning long trajectories (DESIGN.md "Bounded resources").

    python bench/bench_memory.py [--sizes 0.1 0.5 1.0] [--write docs/benchmarks.md]

Each task is one slow LIN on the KUKA KR 6 R900-2 whose speed is chosen for about N million
output samples at 1 ms (at 4 ms, the lowest speed a task may ask, 0.1 mm/s, would give 0.89 M
at most). Every run is a fresh subprocess (its peak RSS from ``os.wait4``), under
an address-space limit and a timeout, in three modes (``--modes`` adds ``plan --no-replay``):

* ``plan()``: the planner in-process, no file written;
* ``plan --no-report --no-replay``: the CLI writing trajectory.csv and trajectory.json;
* ``plan`` (report and replay): the CLI's default.

The base line is the same LIN, fast (~180 samples), i.e. the process's imports and kernels.
The figures feed the memory model of singplan/planning/orchestration/budget.py; the table shows that model's
estimate of each task next to the measured peak (the budget refuses what it puts over 1.5 GB).
"""

from __future__ import annotations

import argparse
import math
import os
import platform
import resource
import subprocess
import sys
import tempfile
import time
from dataclasses import dataclass
from importlib.metadata import version
from pathlib import Path

import numpy as np
import yaml

HERE = Path(__file__).resolve().parent
MARK = "bench_memory"
PERIOD_S = 0.001
START_DEG = [0, -80, 100, 0, 40, 0]
LIN_TO = [0.45, 0.3, 0.45]
LIN_LENGTH_M = 0.3550082921423942  # from the start's TCP (tool 0.1 m) to LIN_TO
ADDRESS_SPACE_BYTES = 4_000_000_000  # a guard on a shared machine (address space, not RSS), above the budget
TIMEOUT_S = 900
MODES = {"plan()": None, "plan --no-report --no-replay": ["--no-report", "--no-replay"],
         "plan --no-replay": ["--no-replay"], "plan": []}
BASE_SPEED_M_S = 0.5  # the base line: the same LIN, fast (~180 samples)


def task_yaml(million_samples: float) -> dict[str, object]:
    """A task of about ``million_samples`` million output samples (0: the base line)."""
    speed = LIN_LENGTH_M / (million_samples * 1e6 * PERIOD_S) if million_samples else BASE_SPEED_M_S
    return {"robot": "kuka_kr6_r900_2", "tool": {"xyz": [0, 0, 0.1]}, "start": {"joints_deg": START_DEG},
            "moves": [{"lin": {"to": {"xyz": LIN_TO}, "speed": speed}}], "output": {"period": PERIOD_S}}


@dataclass(frozen=True)
class Run:
    million: float
    mode: str
    exit_code: int
    peak_mb: float
    seconds: float
    samples: int
    model_mb: float


def _limit() -> None:
    resource.setrlimit(resource.RLIMIT_AS, (ADDRESS_SPACE_BYTES, ADDRESS_SPACE_BYTES))


def run(task: Path, mode: str, out: Path) -> tuple[int, float, float]:
    """Exit code, peak RSS [MB] and wall time [s] of one subprocess."""
    flags = MODES[mode]
    if flags is None:
        code = f"from singplan.results.plan import plan; plan({str(task)!r})"
        argv = [sys.executable, "-c", code]
    else:
        argv = [sys.executable, "-m", "singplan", "plan", str(task), "-o", str(out), "--quiet", *flags]
    t0 = time.perf_counter()
    proc = subprocess.Popen(argv, preexec_fn=_limit, stdout=subprocess.DEVNULL, stderr=subprocess.PIPE)
    deadline = t0 + TIMEOUT_S
    while True:
        pid, status, usage = os.wait4(proc.pid, os.WNOHANG)
        if pid:
            break
        if time.perf_counter() > deadline:
            proc.kill()
            pid, status, usage = os.wait4(proc.pid, 0)
            break
        time.sleep(0.2)
    proc.returncode = os.waitstatus_to_exitcode(status)
    return proc.returncode, usage.ru_maxrss / 1024, time.perf_counter() - t0


def model_mb(task: Path) -> float:
    """The budget's estimate [MB] of a task's peak (singplan/planning/orchestration/budget.py, as the planner
    calls it)."""
    from singplan.planning.orchestration.budget import check_task, memory_mb
    from singplan.planning.orchestration.targets import load_task_robot
    from singplan.planning.path.cartesian import STEP_M, STEP_RAD
    from singplan.task.load import load_task

    spec = load_task(task)
    robot = load_task_robot(spec)
    q = np.radians(np.asarray(spec.start_joints_deg, dtype=float))
    estimate = check_task(spec, robot, q, STEP_M, STEP_RAD, budget_mb=math.inf)
    return memory_mb(estimate.output_samples, max(m.path_samples for m in estimate.moves), estimate.path_samples)


def measure(sizes: list[float], modes: list[str]) -> list[Run]:
    runs = []
    with tempfile.TemporaryDirectory() as tmp:
        for million in [0.0, *sizes]:
            task = Path(tmp) / f"task_{million}.yaml"
            task.write_text(yaml.safe_dump(task_yaml(million)))
            samples = round(million * 1e6) + 1
            model = model_mb(task)
            for mode in modes if million else ["plan()"]:
                code, peak, seconds = run(task, mode, Path(tmp) / "out")
                runs.append(Run(million, mode, code, peak, seconds, samples, model))
                print(f"{million:4.2f} M  {mode:30s} exit {code}  {peak:7.0f} MB (model {model:5.0f})  "
                      f"{seconds:6.1f} s", flush=True)
    return runs


def table(runs: list[Run]) -> str:
    base = next(r.peak_mb for r in runs if r.million == 0)
    lines = [f"Peak RSS of a fresh process (`os.wait4`) planning one slow LIN of about N million output samples "
             f"at {PERIOD_S * 1e3:g} ms (KUKA KR 6 R900-2), and wall time; MB per million output samples is "
             f"(peak - base) / N with the base of a short task ({base:.0f} MB: the imports and kernels). "
             "Budget of DESIGN.md: 600 MB per million samples, 1.5 GB in all. The model column is "
             "singplan/planning/orchestration/budget.py's estimate of the task's peak, what the budget refuses "
             "above 1.5 GB.", "",
             "| output samples [M] | mode | exit | peak RSS [MB] | MB per million | model [MB] | time [s] |",
             "|---:|---|---:|---:|---:|---:|---:|"]
    for r in runs:
        per = f"{(r.peak_mb - base) / r.million:.0f}" if r.million else ""
        lines.append(f"| {r.million:g} | `{r.mode}` | {r.exit_code} | {r.peak_mb:.0f} | {per} | {r.model_mb:.0f} "
                     f"| {r.seconds:.1f} |")
    return "\n".join(lines)


def _machine() -> str:
    sys.path.insert(0, str(HERE))
    from bench_ik import machine  # one definition of the machine line for every benchmark

    versions = ", ".join(f"{name} {version(name)}" for name in ("numpy", "pin", "toppra", "numba"))
    return f"Machine: {machine()}; Python {platform.python_version()}, {versions}."


def write_section(path: Path, text: str) -> None:
    doc = path.read_text() if path.exists() else "# Benchmarks\n"
    start, end = f"<!-- {MARK}:begin -->", f"<!-- {MARK}:end -->"
    block = f"{start}\n## Memory of long trajectories (`bench/bench_memory.py`)\n\n{text}\n{end}"
    if start in doc:
        doc = doc[:doc.index(start)] + block + doc[doc.index(end) + len(end):]
    else:
        doc = doc.rstrip("\n") + "\n\n" + block + "\n"
    path.write_text(doc)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--sizes", type=float, nargs="+", default=[0.1, 0.5, 1.0], help="million output samples")
    parser.add_argument("--modes", nargs="+", default=["plan()", "plan --no-report --no-replay", "plan"],
                        choices=list(MODES))
    parser.add_argument("--write", type=Path, default=None, help="rewrite this script's section of the file")
    args = parser.parse_args()
    runs = measure(args.sizes, args.modes)
    text = f"{_machine()}\n\n{table(runs)}"
    print(text)
    if args.write:
        write_section(args.write, text)


if __name__ == "__main__":
    main()
