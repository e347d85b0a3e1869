"""Tasks written from outside, planned with every method and judged by the independent checker.

    python bench/edge_battery.py [--count 40] [--seed 0] [--methods auto,exact,...] [--workers 1]
                                 [--timeout 120] [--tasks DIR | --save-tasks DIR] [--json FILE]

The tasks are ``tests/edge_tasks.edge_tasks(seed, count)``: LINs and CIRCs through wrist, shoulder
and elbow hits and near misses on bundled arms and the example-robot-data UR5 / UR10 (``--tasks
DIR`` plans the ``*.yaml`` files of a folder instead, e.g. ones saved with ``--save-tasks``, so two
versions of singplan can be compared on the same files). Each task is planned with every method
at its own tolerances, and ``exact``, ``average`` and ``ptp`` once more at issue 22's loose ones
(50 mm, 45 deg). Each run goes through ``singplan.cli.main`` in a worker process (``--workers``)
with a timeout; a plan that exits 0 is judged by ../shared/verify's checker.

Criteria (issue 22): no exit 1 and no timeout, every exit 0 passes the checker, and at the loose
tolerances ``average`` and ``ptp`` plan wherever ``exact`` does. Prints one line a run, a table by
method and the runs that break a criterion; the exit status is 1 when any does.
"""

from __future__ import annotations

import argparse
import json
import multiprocessing
import shutil
import sys
import tempfile
from collections import Counter, defaultdict
from dataclasses import asdict, dataclass
from pathlib import Path
from typing import Any

import yaml

REPO = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(REPO))
from bench.reliability import Case, _checker, judge, run_in_process  # noqa: E402 (the repo root first)
from tests.edge_tasks import LOOSE, METHODS  # noqa: E402

LOOSE_METHODS = ("exact", "average", "ptp")


@dataclass
class Run:
    task: str
    method: str
    loose: bool
    exit_code: int | None
    seconds: float
    verdict: str  # "ok" or what broke the contract (reliability.judge)
    message: str
    checker: str = ""


def _tasks(args: argparse.Namespace) -> dict[str, dict[str, Any]]:
    if args.tasks is not None:
        return {p.stem: yaml.safe_load(p.read_text()) for p in sorted(args.tasks.glob("*.yaml"))}
    from tests.edge_tasks import edge_tasks  # generating needs singplan's kinematics

    tasks = {case.name: case.task for case in edge_tasks(args.seed, args.count)}
    if args.save_tasks is not None:
        args.save_tasks.mkdir(parents=True, exist_ok=True)
        for name, task in tasks.items():
            (args.save_tasks / f"{name}.yaml").write_text(yaml.safe_dump(task, sort_keys=False))
    return tasks


def _variant(task: dict[str, Any], method: str, loose: bool) -> dict[str, Any]:
    sing = {**(task.get("singularity") or {}), "method": method}
    if loose:
        sing.update(LOOSE)
    return {**task, "singularity": sing}


_VERIFY: Any = None


def _run(job: tuple[str, dict[str, Any], str, bool, float]) -> Run:
    """One planning run in a worker (singplan imported once per worker) and its checker verdict."""
    global _VERIFY
    name, task, method, loose, timeout_s = job
    if _VERIFY is None:
        _VERIFY = _checker()
    case = Case(f"{name}--{method}{'--loose' if loose else ''}", "edge",
                yaml.safe_dump(_variant(task, method, loose), sort_keys=False), (0, 3), valid=True)
    work = Path(tempfile.mkdtemp(prefix="singplan-edges-")) / case.name
    try:
        code, seconds, _, out, err = run_in_process(case, work, timeout_s)
        verdict, checker = judge(case, code, seconds, out + err, work, timeout_s, _VERIFY)
    finally:
        shutil.rmtree(work.parent, ignore_errors=True)
    return Run(name, method, loose, code, round(seconds, 2), verdict, (out + err).strip()[-400:], checker[:600])


def broken(runs: list[Run]) -> list[str]:
    """The criteria each run (or pair of runs) breaks."""
    found = [f"{r.task} {r.method}{' (loose)' if r.loose else ''}: {r.verdict}: {r.message[-200:]}"
             for r in runs if r.verdict != "ok"]
    loose = {(r.task, r.method): r for r in runs if r.loose}
    for (task, method), r in sorted(loose.items()):
        exact = loose.get((task, "exact"))
        if method != "exact" and exact is not None and exact.exit_code == 0 and r.exit_code != 0:
            found.append(f"{task} {method} (loose): exit {r.exit_code} where exact plans: {r.message[-200:]}")
    return found


def table(runs: list[Run]) -> str:
    rows = ["| method | tolerances | runs | exit 0 | exit 3 | exit 2 | exit 1 | timeout | checker rejects |",
            "|---|---|---:|---:|---:|---:|---:|---:|---:|"]
    groups: dict[tuple[str, bool], list[Run]] = defaultdict(list)
    for r in runs:
        groups[(r.method, r.loose)].append(r)
    for (method, loose), group in sorted(groups.items(), key=lambda kv: (kv[0][1], METHODS.index(kv[0][0]))):
        codes = Counter(r.exit_code for r in group)
        rejects = sum(r.verdict.startswith("checker") for r in group)
        rows.append(f"| {method} | {'50 mm / 45 deg' if loose else 'task'} | {len(group)} | {codes[0]} | {codes[3]} | "
                    f"{codes[2]} | {codes[1]} | {codes[None]} | {rejects} |")
    return "\n".join(rows)


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--count", type=int, default=40, help="tasks to generate")
    ap.add_argument("--seed", type=int, default=0, help="seed of the generated tasks")
    ap.add_argument("--methods", default=",".join(METHODS), help="comma-separated methods")
    ap.add_argument("--workers", type=int, default=1, help="worker processes")
    ap.add_argument("--timeout", type=float, default=120.0, help="seconds before a run counts as a timeout")
    ap.add_argument("--tasks", type=Path, default=None, help="plan the *.yaml tasks of this folder instead")
    ap.add_argument("--save-tasks", type=Path, default=None, help="save the generated tasks here")
    ap.add_argument("--json", type=Path, default=None, help="write every run as JSON")
    args = ap.parse_args(argv)
    methods = [m for m in args.methods.split(",") if m]
    tasks = _tasks(args)
    jobs = [(name, task, m, False, args.timeout) for name, task in tasks.items() for m in methods]
    jobs += [(name, task, m, True, args.timeout) for name, task in tasks.items() for m in LOOSE_METHODS
             if m in methods]
    runs: list[Run] = []
    with multiprocessing.get_context("fork").Pool(args.workers, maxtasksperchild=40) as pool:
        for r in pool.imap(_run, jobs):
            runs.append(r)
            print(f"{r.task:60s} {r.method:12s}{'L' if r.loose else ' '} exit {r.exit_code!s:>4} {r.seconds:6.1f} s  "
                  f"{r.verdict}", flush=True)
    print()
    print(f"{len(tasks)} tasks, {len(runs)} runs")
    print(table(runs))
    problems = broken(runs)
    print(f"\n{len(problems)} broken criteria" + "".join(f"\n- {p}" for p in problems))
    if args.json is not None:
        args.json.write_text(json.dumps([asdict(r) for r in runs], indent=1))
    return 1 if problems else 0


if __name__ == "__main__":
    sys.exit(main())
