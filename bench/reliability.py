"""Reliability figures: random valid tasks and hostile inputs, each planned in its own process.

    python bench/reliability.py --valid 200 [--seed 0] [--hostile-dir DIR ...] [--generated-hostile]
                                [--timeout 120] [--slow 60] [--mem-limit-mb 4000] [--in-process]
                                [--failures DIR] [--json FILE]

Every case runs as ``python -m singplan plan TASK -o OUT --quiet --no-report --no-replay`` with a
timeout; its wall time and peak resident memory come from ``os.wait4`` (that child's own rusage).
Valid tasks are ``tests/task_strategies.seeded_task(seed)`` for seeds ``--seed`` ..; a plan that
exits 0 is judged by the independent checker in ../shared/verify. Hostile inputs are the
``*.yaml`` files of each ``--hostile-dir`` (category: the folder's name; expected exit 2 or 3)
and, with ``--generated-hostile``, a small built-in battery with the exit code each must give.

Verdicts: ``ok`` (the contract held), else a failure category such as ``exit1-OverflowError``,
``exit2-on-valid``, ``checker-<first failed check>``, ``exit3-no-point``, ``timeout``,
``slow`` (over --slow seconds), ``traceback``, ``left-output`` (a failed run left files in -o),
``wrong-exit``. With ``--failures DIR`` each failing case is saved as DIR/<category>/<case>/
(task.yaml, stdout.txt, stderr.txt, meta.json). Prints a table by category: cases, exit codes,
verdicts, worst time, peak memory.
"""

from __future__ import annotations

import argparse
import importlib.util
import io
import json
import os
import re
import resource
import shutil
import signal
import subprocess
import sys
import tempfile
import time
import traceback
from collections import Counter, defaultdict
from dataclasses import asdict, dataclass, field
from pathlib import Path
from types import ModuleType
from typing import Any

import yaml

REPO = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(REPO))
from tests.task_strategies import seeded_task  # noqa: E402 (the repo root is put on the path first)

# ../shared next to the project; SINGPLAN_SHARED names it where the project sits elsewhere (a git worktree)
VERIFY = Path(os.environ.get("SINGPLAN_SHARED") or REPO.parent / "shared") / "verify" / "verify_trajectory.py"
MOVE_NAMED = re.compile(r"\bmove \d+")
POINT_NAMED = re.compile(r"s = -?\d[\d.]* mm|xyz|sample \d+|t = \d[\d.]* ?s")
EXCEPTION_LINE = re.compile(r"^(\w+(?:\.\w+)*(?:Error|Exception|Interrupt|Exit))\b", re.MULTILINE)
NUMBER = re.compile(r"-?\d+(?:\.\d+)?(?:e[-+]?\d+)?")


@dataclass
class Case:
    name: str
    category: str
    text: str  # the task file's content
    expected: tuple[int, ...]  # acceptable exit codes
    valid: bool = False  # a random valid task: exit 0 must pass the checker, exit 3 must name move and point


@dataclass
class Outcome:
    case: str
    category: str
    exit_code: int | None
    verdict: str
    seconds: float
    peak_rss_mb: float
    message: str
    checker: str = ""
    extra: dict[str, Any] = field(default_factory=dict)


# -- cases -------------------------------------------------------------------------------------


def valid_cases(count: int, seed: int) -> list[Case]:
    return [Case(f"valid-{s:05d}", "valid", yaml.safe_dump(seeded_task(s), sort_keys=False), (0, 3), valid=True)
            for s in range(seed, seed + count)]


def folder_cases(folder: Path) -> list[Case]:
    return [Case(f"{folder.name}-{p.stem}", folder.name, p.read_text(errors="replace"), (2, 3))
            for p in sorted(folder.glob("*.yaml"))]


# the start's TCP is at xyz [0.50863961, 0, 0.81636039], rpy_deg [180, 45, 180]
_BASE = "robot: kuka_kr6_r900_2\nstart: {joints_deg: [0, -90, 90, 0, 45, 0]}\n"
_LIN = "moves:\n  - lin: {to: {xyz: [0.4, 0.1, 0.5]}, speed: 0.2}\n"


def generated_hostile() -> list[Case]:
    """A small battery, one or two per kind of issue 10; each with the exit code it must give."""
    deep = "robot: ur5\nstart: " + "[" * 3000 + "]" * 3000 + "\nmoves: []\n"
    cases = {
        "duplicate-key": (_BASE + "moves:\n  - lin: {to: {xyz: [0.4, 0.1, 0.5]}, speed: 0.25, speed: 9.5}\n", 2),
        "huge-integer": (_BASE + "moves:\n  - lin: {to: {xyz: [0.4, 0.1, 0.5]}, speed: " + "9" * 400 + "}\n", 2),
        "nested-3000": (deep, 2),
        "speed-1e-300": (_BASE + "moves:\n  - lin: {to: {xyz: [0.4, 0.1, 0.5]}, speed: 1.0e-300}\n", 2),
        "velocity-scale-1e-300": (_BASE + _LIN + "limits: {velocity_scale: 1.0e-300}\n", 2),
        "nan-coordinate": (_BASE + "moves:\n  - lin: {to: {xyz: [.nan, 0.1, 0.5]}}\n", 2),
        "unknown-key": (_BASE + _LIN + "speeed: 1\n", 2),
        "yaml-alias": (_BASE + "p: &a {xyz: [0.4, 0.1, 0.5]}\nmoves:\n  - lin: {to: *a}\n", 2),
        "not-yaml": ("robot: [unclosed\n", 2),
        "empty": ("", 2),
        "far-circ-via": (_BASE + "moves:\n  - circ: {via: {xyz: [-100, 100, 100]}, to: {xyz: [100, -100, -100]}}\n",
                         2),
        "collinear-circ": (_BASE + "moves:\n  - circ: {via: {xyz: [0.52863961, 0.0, 0.79636039]}, "
                                   "to: {xyz: [0.54863961, 0.0, 0.77636039]}}\n", 2),
        "joints-out-of-limits": ("robot: kuka_kr6_r900_2\nstart: {joints_deg: [0, -90, 90, 0, 170, 0]}\n" + _LIN, 2),
        # the stretched arm: the TCP of all-zero joints is at xyz [0.81725, 0.19145, -0.00549]
        "ur5-all-zero-start": ("robot: ur5\nstart: {joints_deg: [0, 0, 0, 0, 0, 0]}\n"
                               "moves:\n  - lin: {to: {xyz: [0.76725, 0.19145, -0.00549]}, speed: 0.1}\n", 0),
        "unreachable-lin": (_BASE + "moves:\n  - lin: {to: {xyz: [5.0, 0.0, 0.5]}}\n", 3),
        "tiny-lin-10um": (_BASE + "moves:\n  - lin: {to: {xyz: [0.50864961, 0.0, 0.81636039]}}\n", 0),
    }
    return [Case(f"gen-{name}", "generated-hostile", text, (code,)) for name, (text, code) in cases.items()]


# -- running -----------------------------------------------------------------------------------


def _limit_memory(limit_mb: int) -> None:
    """Runs in the child before exec: a runaway plan fails with MemoryError instead of swapping the machine."""
    if limit_mb > 0:
        resource.setrlimit(resource.RLIMIT_AS, (limit_mb << 20, limit_mb << 20))


def run_case(case: Case, work: Path, timeout_s: float, mem_limit_mb: int) -> tuple[int | None, float, float, str, str]:
    """Exit code (None on timeout), seconds, peak RSS [MB], stdout, stderr of one planning run."""
    work.mkdir(parents=True)
    task = work / "task.yaml"
    task.write_text(case.text)
    stdout, stderr = work / "stdout.txt", work / "stderr.txt"
    cmd = [sys.executable, "-m", "singplan", "plan", str(task), "-o", str(work / "out"), "--quiet", "--no-report",
           "--no-replay"]
    start = time.monotonic()
    with stdout.open("w") as out, stderr.open("w") as err:
        proc = subprocess.Popen(cmd, stdout=out, stderr=err, stdin=subprocess.DEVNULL, cwd=work,
                                preexec_fn=lambda: _limit_memory(mem_limit_mb))
        code: int | None = None
        while True:
            pid, status, usage = os.wait4(proc.pid, os.WNOHANG)
            if pid:
                code = os.waitstatus_to_exitcode(status)
                break
            if time.monotonic() - start > timeout_s:
                proc.kill()
                _, _, usage = os.wait4(proc.pid, 0)
                break
            time.sleep(0.02)
    proc.returncode = code if code is not None else -9  # already reaped by wait4
    seconds = time.monotonic() - start
    return code, seconds, usage.ru_maxrss / 1024.0, stdout.read_text(), stderr.read_text()


class _CaseTimeoutError(Exception):
    pass


def _alarm(signum: int, frame: object) -> None:
    raise _CaseTimeoutError


def run_in_process(case: Case, work: Path, timeout_s: float) -> tuple[int | None, float, float, str, str]:
    """The same as :func:`run_case` through ``singplan.cli.main`` in this process (no start-up cost per case).

    Peak memory is then this process's high-water mark so far, not the case's own.
    """
    from singplan.cli import main as cli_main

    work.mkdir(parents=True)
    task = work / "task.yaml"
    task.write_text(case.text)
    out, err = io.StringIO(), io.StringIO()
    argv = ["plan", str(task), "-o", str(work / "out"), "--quiet", "--no-report", "--no-replay"]
    previous = signal.signal(signal.SIGALRM, _alarm)
    signal.setitimer(signal.ITIMER_REAL, timeout_s)
    start = time.monotonic()
    code: int | None
    try:
        code = cli_main(argv, out=out, err=err)
    except _CaseTimeoutError:
        code = None
    except BaseException:  # what would reach the user as a traceback (exit 1)
        err.write(traceback.format_exc())
        code = 1
    finally:
        signal.setitimer(signal.ITIMER_REAL, 0.0)
        signal.signal(signal.SIGALRM, previous)
    seconds = time.monotonic() - start
    (work / "stdout.txt").write_text(out.getvalue())
    (work / "stderr.txt").write_text(err.getvalue())
    return code, seconds, resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024.0, out.getvalue(), err.getvalue()


def _checker() -> ModuleType | None:
    if not VERIFY.is_file():
        return None
    spec = importlib.util.spec_from_file_location("verify_trajectory", VERIFY)
    assert spec is not None and spec.loader is not None
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


def _checker_verdict(verify: ModuleType | None, case: Case, out_dir: Path) -> str:
    """'' when the checker passes, else its first failure with the numbers blanked (a category key)."""
    if verify is None:
        return "checker-missing"
    try:
        traj = json.loads((out_dir / "trajectory.json").read_text())
        result = verify.Checker(yaml.safe_load(case.text), traj, out_dir).run()
    except (OSError, ValueError, KeyError, TypeError, IndexError) as exc:
        return f"cannot check: {type(exc).__name__}"
    return "" if result["ok"] else "; ".join(result["failures"])


def judge(case: Case, code: int | None, seconds: float, said: str, work: Path, slow_s: float,
          verify: ModuleType | None) -> tuple[str, str]:
    """(verdict, checker text): 'ok' or a failure category."""
    if code is None:
        return "timeout", ""
    if "Traceback" in said:
        found = EXCEPTION_LINE.findall(said)
        return f"exit{code}-{found[-1] if found else 'traceback'}", ""
    if code == 1:
        found = EXCEPTION_LINE.findall(said)
        return f"exit1-{found[-1] if found else 'no-traceback'}", ""
    if code not in case.expected and code >= 0:
        return ("exit2-on-valid" if case.valid and code == 2 else f"wrong-exit-{code}"), ""
    if code < 0:
        return f"killed-signal{-code}", ""
    if code != 0 and (work / "out").exists():
        return "left-output", ""
    if not (work / "task.yaml").exists():
        return "task-file-lost", ""
    if case.valid and code == 3 and not (MOVE_NAMED.search(said) and POINT_NAMED.search(said)):
        return "exit3-no-point", ""
    if case.valid and code == 0:
        checker = _checker_verdict(verify, case, work / "out")
        if checker:
            key = NUMBER.sub("#", checker.split("; ")[0])[:70]
            return f"checker: {key}", checker
    if seconds > slow_s:
        return "slow", ""
    return "ok", ""


def _save_failure(root: Path, outcome: Outcome, work: Path) -> None:
    folder = root / re.sub(r"[^\w.-]+", "_", outcome.verdict)[:80] / outcome.case
    folder.mkdir(parents=True, exist_ok=True)
    for name in ("task.yaml", "stdout.txt", "stderr.txt"):
        if (work / name).exists():
            shutil.copy(work / name, folder / name)
    (folder / "meta.json").write_text(json.dumps(asdict(outcome), indent=2))


# -- report ------------------------------------------------------------------------------------


def table(outcomes: list[Outcome]) -> str:
    rows = ["| category | cases | exit codes | verdicts | worst time [s] | peak memory [MB] |",
            "|---|---:|---|---|---:|---:|"]
    by_category: dict[str, list[Outcome]] = defaultdict(list)
    for o in outcomes:
        by_category[o.category].append(o)
    for category, group in sorted(by_category.items()):
        codes = Counter("timeout" if o.exit_code is None else str(o.exit_code) for o in group)
        verdicts = Counter(o.verdict for o in group)
        rows.append(f"| {category} | {len(group)} | {_counts(codes)} | {_counts(verdicts)} | "
                    f"{max(o.seconds for o in group):.1f} | {max(o.peak_rss_mb for o in group):.0f} |")
    return "\n".join(rows)


def _counts(counter: Counter[str]) -> str:
    return ", ".join(f"{key}: {n}" for key, n in sorted(counter.items(), key=lambda kv: (-kv[1], kv[0])))


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--valid", type=int, default=0, help="number of random valid tasks")
    ap.add_argument("--seed", type=int, default=0, help="first seed of the random valid tasks")
    ap.add_argument("--hostile-dir", type=Path, action="append", default=[], help="folder of hostile *.yaml tasks")
    ap.add_argument("--generated-hostile", action="store_true", help="also run the small built-in hostile battery")
    ap.add_argument("--timeout", type=float, default=120.0, help="seconds before a run is killed")
    ap.add_argument("--slow", type=float, default=60.0, help="seconds over which a run counts as slow")
    ap.add_argument("--mem-limit-mb", type=int, default=4000, help="address-space cap of each run (0: none)")
    ap.add_argument("--in-process", action="store_true",
                    help="plan through singplan.cli.main in this process: fast, but memory is the process's peak")
    ap.add_argument("--failures", type=Path, default=None, help="save each failing case under DIR/<verdict>/")
    ap.add_argument("--json", type=Path, default=None, help="write every outcome as JSON")
    args = ap.parse_args(argv)

    cases = valid_cases(args.valid, args.seed)
    for folder in args.hostile_dir:
        cases += folder_cases(folder)
    if args.generated_hostile:
        cases += generated_hostile()
    if args.in_process:
        _limit_memory(args.mem_limit_mb)
    verify = _checker()
    if verify is None:
        print(f"warning: no independent checker at {VERIFY}: planned trajectories are not checked", file=sys.stderr)
    outcomes: list[Outcome] = []
    with tempfile.TemporaryDirectory(prefix="singplan-reliability-") as tmp:
        for case in cases:
            work = Path(tmp) / case.name
            if args.in_process:
                code, seconds, rss_mb, out, err = run_in_process(case, work, args.timeout)
            else:
                code, seconds, rss_mb, out, err = run_case(case, work, args.timeout, args.mem_limit_mb)
            said = out + err
            verdict, checker = judge(case, code, seconds, said, work, args.slow, verify)
            outcome = Outcome(case.name, case.category, code, verdict, round(seconds, 3), round(rss_mb, 1),
                              said.strip()[-600:], checker[:2000])
            outcomes.append(outcome)
            print(f"{case.name:40s} exit {code!s:>4} {seconds:7.1f} s {rss_mb:7.0f} MB  {verdict}", flush=True)
            if verdict != "ok" and args.failures is not None:
                _save_failure(args.failures, outcome, work)
            shutil.rmtree(work, ignore_errors=True)
    print()
    print(table(outcomes))
    if args.json is not None:
        args.json.write_text(json.dumps([asdict(o) for o in outcomes], indent=1))
    return 0 if all(o.verdict == "ok" for o in outcomes) else 1


if __name__ == "__main__":
    sys.exit(main())
