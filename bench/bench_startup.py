"""What a user waits for before anything happens: start-up and a small plan, side by side in one run.

    python bench/bench_startup.py [--repeat 7] [--compare OTHER_CHECKOUT] [--write docs/benchmarks.md]

Each command runs in a fresh interpreter (a subprocess) ``--repeat`` times, interleaved round by
round so that a change of the machine's load falls on every command alike; the table gives the
median and the range of the wall times, and the median CPU time (user + system) of the process,
which a loaded machine disturbs less. The baselines are the imports singplan cannot avoid:
``import pinocchio`` (for ``import singplan`` and ``singplan --help``) and ``import pinocchio,
toppra, numba`` (for ``singplan plan`` of the bundled demo task).

Every command runs once before the first round, as after an install: the numba kernels are
compiled and cached, and the Python bytecode of every module is written (to a scratch
``PYTHONPYCACHEPREFIX``, leaving the checkout alone), as pip writes it at install time; a shell
that sets ``PYTHONDONTWRITEBYTECODE`` would otherwise have every run compile singplan's sources.
``--compare`` runs the singplan commands of another checkout (e.g. an older commit unpacked with
``git archive``) in the same rounds. The machine's load average is recorded: on a shared machine
the wall times are upper bounds.
"""

from __future__ import annotations

import argparse
import os
import platform
import resource
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
CHECKOUT = HERE.parent
MARK = "bench_startup"
PIN = '`python -c "import pinocchio"`'
PIN_TOPPRA_NUMBA = '`python -c "import pinocchio, toppra, numba"`'
PLAN = "`singplan plan demo --no-report --no-replay`"
# singplan's console script freezes the heap before the interpreter exits (singplan.cli.run); the
# same imports ended the same way show how much of the ratio is that exit
PIN_TOPPRA_NUMBA_FROZEN = '`python -c "import pinocchio, toppra, numba; import gc; gc.freeze()"`'


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
    checkout: Path = CHECKOUT  # whose singplan it runs (PYTHONPATH)


def _singplan_commands(checkout: Path, tag: str, targets: bool) -> list[Command]:
    sp = _singplan()
    demo = str(checkout / "singplan" / "demo_task.yaml")
    plan = f"{PLAN}{tag}"

    def bound(value: float) -> float | None:
        return value if targets else None

    return [
        Command(f'`python -c "import singplan"`{tag}', (sys.executable, "-c", "import singplan"), PIN, bound(1.5),
                checkout=checkout),
        Command(f"`singplan --help`{tag}", (*sp, "--help"), PIN, bound(1.0), checkout=checkout),
        Command(plan, (*sp, "plan", demo, "--quiet", "--no-report", "--no-replay"), PIN_TOPPRA_NUMBA, bound(1.35),
                True, checkout),
        Command(f"`singplan plan demo` (report.html and replay.html too){tag}", (*sp, "plan", demo, "--quiet"),
                plan, bound(1.3), True, checkout),
    ]


def commands(compare: Path | None = None) -> list[Command]:
    py = sys.executable
    out = [Command(PIN, (py, "-c", "import pinocchio")),
           Command(PIN_TOPPRA_NUMBA, (py, "-c", "import pinocchio, toppra, numba")),
           Command(PIN_TOPPRA_NUMBA_FROZEN, (py, "-c", "import pinocchio, toppra, numba; import gc; gc.freeze()"))]
    out += _singplan_commands(CHECKOUT, "", targets=True)
    if compare is not None:
        out += _singplan_commands(compare.resolve(), f" ({compare.name})", targets=False)
    return out


def _children_cpu_s() -> float:
    usage = resource.getrusage(resource.RUSAGE_CHILDREN)
    return usage.ru_utime + usage.ru_stime


def run_once(cmd: Command, scratch: Path, env: dict[str, str]) -> tuple[float, float]:
    """Wall and CPU time [s] of one run of the command."""
    argv = list(cmd.argv)
    if cmd.writes:
        out = scratch / "out"
        shutil.rmtree(out, ignore_errors=True)
        argv += ["-o", str(out)]
    cpu_before = _children_cpu_s()
    started = time.perf_counter()
    subprocess.run(argv, check=True, stdout=subprocess.DEVNULL, env={**env, "PYTHONPATH": str(cmd.checkout)},
                   cwd=cmd.checkout)
    return time.perf_counter() - started, _children_cpu_s() - cpu_before


@dataclass
class Measured:
    wall_s: dict[str, list[float]]
    cpu_s: dict[str, list[float]]
    load: tuple[float, float]  # 1-minute load average before and after the rounds


def measure(cmds: list[Command], repeat: int) -> Measured:
    """Every command, ``repeat`` interleaved rounds, after one run each to compile and cache."""
    with tempfile.TemporaryDirectory() as tmp:
        scratch = Path(tmp)
        env = {k: v for k, v in os.environ.items() if k != "PYTHONDONTWRITEBYTECODE"}
        env["PYTHONPYCACHEPREFIX"] = str(scratch / "pycache")
        for c in cmds:
            run_once(c, scratch, env)
        wall: dict[str, list[float]] = {c.label: [] for c in cmds}
        cpu: dict[str, list[float]] = {c.label: [] for c in cmds}
        load_before = os.getloadavg()[0]
        for _ in range(repeat):
            for c in cmds:
                w, u = run_once(c, scratch, env)
                wall[c.label].append(w)
                cpu[c.label].append(u)
        return Measured(wall, cpu, (load_before, os.getloadavg()[0]))


def table(cmds: list[Command], m: Measured, repeat: int) -> str:
    sys.path.insert(0, str(HERE))
    from bench_ik import machine  # one definition of the machine line for every benchmark

    wall = {label: statistics.median(ts) for label, ts in m.wall_s.items()}
    cpu = {label: statistics.median(ts) for label, ts in m.cpu_s.items()}
    lines = [f"### Start-up and a small plan (median of {repeat} runs, each in a fresh interpreter)", "",
             f"Measured {time.strftime('%Y-%m-%d %H:%M UTC', time.gmtime())}. Machine: {machine()}; Python "
             f"{platform.python_version()}, pin {version('pin')}, toppra {version('toppra')}, numba "
             f"{version('numba')}, meshcat {version('meshcat')}, matplotlib {version('matplotlib')}. "
             f"Load average (1 min) {m.load[0]:.1f} before, {m.load[1]:.1f} after.", "",
             "| command | wall median [s] | wall min - max [s] | CPU median [s] | ratio to | wall ratio | CPU ratio "
             "| issue 12 target |",
             "|---|---:|---:|---:|---|---:|---:|---:|"]
    for c in cmds:
        ts = m.wall_s[c.label]
        base = ratio = cpu_ratio = target = ""
        if c.baseline is not None:
            base = c.baseline
            ratio = f"{wall[c.label] / wall[c.baseline]:.2f}"
            cpu_ratio = f"{cpu[c.label] / cpu[c.baseline]:.2f}"
            target = f"<= {c.target:g}" if c.target is not None else ""
        lines.append(f"| {c.label} | {wall[c.label]:.3f} | {min(ts):.3f} - {max(ts):.3f} | {cpu[c.label]:.3f} | "
                     f"{base} | {ratio} | {cpu_ratio} | {target} |")
    lines += ["", f"{PLAN} against {PIN_TOPPRA_NUMBA_FROZEN} (the imports ended as singplan's console script "
                  f"ends): wall {wall[PLAN] / wall[PIN_TOPPRA_NUMBA_FROZEN]:.2f}, CPU "
                  f"{cpu[PLAN] / cpu[PIN_TOPPRA_NUMBA_FROZEN]:.2f}."]
    return "\n".join(lines)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--repeat", type=int, default=7)
    parser.add_argument("--compare", type=Path, default=None, help="another checkout whose singplan runs too")
    parser.add_argument("--write", type=Path, default=None, help="replace this benchmark's section of the file")
    args = parser.parse_args()
    cmds = commands(args.compare)
    text = table(cmds, measure(cmds, args.repeat), args.repeat)
    sys.stdout.write(text + "\n")
    if args.write:
        from bench_ik import write_section

        write_section(args.write, text, MARK)


if __name__ == "__main__":
    main()
