"""What a user waits for before anything happens: start-up and a small plan, side by side in one run.

    python bench/bench_startup.py [--repeat 5] [--write docs/benchmarks.md]

Each command runs in a fresh interpreter (a subprocess) ``--repeat`` times, interleaved round by
round so that a change of the machine's load falls on every command alike; the table gives the
median and the range of the wall times. The baselines are the imports singplan cannot avoid:
``import pinocchio`` (for ``import singplan`` and ``singplan --help``) and ``import pinocchio,
toppra, numba`` (for ``singplan plan`` of the bundled demo task). The numba kernels are compiled
and cached once before the first round, as after an install. The machine's load average is
recorded: on a shared machine the figures are upper bounds.
"""

from __future__ import annotations

import argparse
import os
import platform
import shutil
import statistics
import subprocess
import sys
import tempfile
import time
from dataclasses import dataclass
from importlib.metadata import version
from pathlib import Path

HERE = Path(__file__).resolve().parent
DEMO = HERE.parent / "singplan" / "demo_task.yaml"
MARK = "bench_startup"


def _singplan() -> list[str]:
    """The console script next to this interpreter, or ``python -m singplan`` when it is not installed."""
    script = Path(sys.executable).with_name("singplan")
    return [str(script)] if script.exists() else [sys.executable, "-m", "singplan"]


@dataclass(frozen=True)
class Command:
    label: str
    argv: tuple[str, ...]
    baseline: str | None = None  # label of the command this one is compared with
    target: float | None = None  # issue 12's bound on the ratio to the baseline
    writes: bool = False  # takes an output folder (a fresh one each run)


def commands() -> list[Command]:
    py, sp = sys.executable, _singplan()
    return [
        Command("`python -c \"import pinocchio\"`", (py, "-c", "import pinocchio")),
        Command("`python -c \"import singplan\"`", (py, "-c", "import singplan"),
                "`python -c \"import pinocchio\"`", 1.5),
        Command("`singplan --help`", (*sp, "--help"), "`python -c \"import pinocchio\"`", 1.0),
        Command("`python -c \"import pinocchio, toppra, numba\"`", (py, "-c", "import pinocchio, toppra, numba")),
        Command("`singplan plan demo --no-report --no-replay`",
                (*sp, "plan", str(DEMO), "--quiet", "--no-report", "--no-replay"),
                "`python -c \"import pinocchio, toppra, numba\"`", 1.35, True),
        Command("`singplan plan demo` (report.html and replay.html too)", (*sp, "plan", str(DEMO), "--quiet"),
                "`singplan plan demo --no-report --no-replay`", 1.3, True),
    ]


def run_once(cmd: Command, scratch: Path, env: dict[str, str]) -> float:
    argv = list(cmd.argv)
    if cmd.writes:
        out = scratch / "out"
        shutil.rmtree(out, ignore_errors=True)
        argv += ["-o", str(out)]
    started = time.perf_counter()
    subprocess.run(argv, check=True, stdout=subprocess.DEVNULL, env=env)
    return time.perf_counter() - started


def measure(repeat: int) -> tuple[dict[str, list[float]], tuple[float, float]]:
    """Wall times [s] of every command, ``repeat`` rounds; and the load average before / after."""
    env = {**os.environ, "PYTHONPATH": str(HERE.parent)}  # this checkout's singplan
    cmds = commands()
    times: dict[str, list[float]] = {c.label: [] for c in cmds}
    with tempfile.TemporaryDirectory() as tmp:
        scratch = Path(tmp)
        run_once(cmds[4], scratch, env)  # compile or load the numba kernels once, as after an install
        load_before = os.getloadavg()[0]
        for _ in range(repeat):
            for c in cmds:
                times[c.label].append(run_once(c, scratch, env))
        return times, (load_before, os.getloadavg()[0])


def table(times: dict[str, list[float]], load: tuple[float, float], repeat: int) -> str:
    sys.path.insert(0, str(HERE))
    from bench_ik import machine  # one definition of the machine line for every benchmark

    median = {label: statistics.median(ts) for label, ts in times.items()}
    lines = [f"### Start-up and a small plan (median of {repeat} runs, each in a fresh interpreter)", "",
             f"Measured {time.strftime('%Y-%m-%d %H:%M UTC', time.gmtime())}. Machine: {machine()}; Python "
             f"{platform.python_version()}, pin {version('pin')}, toppra {version('toppra')}, numba "
             f"{version('numba')}, meshcat {version('meshcat')}, matplotlib {version('matplotlib')}. "
             f"Load average (1 min) {load[0]:.1f} before, {load[1]:.1f} after.", "",
             "| command | median [s] | min - max [s] | ratio to | ratio | issue 12 target |",
             "|---|---:|---:|---|---:|---:|"]
    for c in commands():
        ts = times[c.label]
        if c.baseline is None:
            ratio = base = target = ""
        else:
            base = c.baseline
            ratio = f"{median[c.label] / median[c.baseline]:.2f}"
            target = f"<= {c.target:g}" if c.target is not None else ""
        lines.append(f"| {c.label} | {median[c.label]:.3f} | {min(ts):.3f} - {max(ts):.3f} | {base} | {ratio} | "
                     f"{target} |")
    return "\n".join(lines)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--repeat", type=int, default=5)
    parser.add_argument("--write", type=Path, default=None, help="replace this benchmark's section of the file")
    args = parser.parse_args()
    times, load = measure(args.repeat)
    text = table(times, load, args.repeat)
    sys.stdout.write(text + "\n")
    if args.write:
        from bench_ik import write_section

        write_section(args.write, text, MARK)


if __name__ == "__main__":
    main()
