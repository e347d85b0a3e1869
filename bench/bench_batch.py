"""Wall time of `singplan batch` on the public scenarios that plan: 1 and 2 local workers, N, Dask.

    python bench/bench_batch.py [--scenarios ../shared/scenarios] [--repeat 2] [--no-pages]
                                [--write docs/benchmarks.md]

Every scenario that expect.yaml says must plan (exit 0) is planned by :func:`singplan.batch.plan_many`
with its default outputs (trajectory files, report.html, replay.html; only the trajectory files
with ``--no-pages``) into a fresh folder:
first in this process one task after the other (``plan_task`` in a loop, the planner already
warm: the floor a batch cannot beat per core), then on 1, 2 and os.cpu_count() local worker
processes (their start and warm-up included, as a user sees it), then on a Dask LocalCluster of
2 worker processes with one thread each (the cluster's start excluded, its workers' warm-up
included). Each figure is the best of ``--repeat`` runs. The machine's load average is
recorded beside the figures: on a shared machine they are upper bounds.
"""

from __future__ import annotations

import argparse
import os
import platform
import sys
import tempfile
import time
from collections.abc import Callable
from dataclasses import dataclass
from functools import partial
from importlib.metadata import version
from pathlib import Path

import yaml

from singplan.batch import make_jobs, plan_many, plan_task

HERE = Path(__file__).resolve().parent
MARK = "bench_batch"


def _machine() -> str:
    sys.path.insert(0, str(HERE))
    from bench_ik import machine  # one definition of the machine line for every benchmark

    return machine()


def public_tasks(scenarios: Path) -> list[Path]:
    expect = yaml.safe_load((scenarios / "expect.yaml").read_text())
    return [scenarios / f"{name}.yaml" for name in sorted(expect) if expect[name].get("exit") == 0]


def in_one_process(tasks: list[Path], out: Path, pages: bool = True) -> list[int]:
    """Each task planned in turn in this process."""
    return [plan_task(job).exit_code for job in make_jobs(tasks, out, report=pages, replay=pages)]


def best_of(repeat: int, run: Callable[[Path], list[int]]) -> tuple[float, list[int]]:
    """The shortest wall time of ``repeat`` runs [s], each into a fresh folder, and the exit codes."""
    times = []
    codes: list[int] = []
    for _ in range(repeat):
        with tempfile.TemporaryDirectory(prefix="bench-batch-") as tmp:
            t0 = time.perf_counter()
            codes = run(Path(tmp) / "out")
            times.append(time.perf_counter() - t0)
    return min(times), codes


@dataclass(frozen=True)
class Row:
    mode: str
    wall_s: float
    planned: int
    tasks: int
    load_before: float  # the machine's 1-minute load average
    load_after: float


def measure(tasks: list[Path], repeat: int, pages: bool) -> list[Row]:
    from distributed import LocalCluster

    with tempfile.TemporaryDirectory(prefix="bench-batch-warm-") as tmp:
        in_one_process(tasks[:1], Path(tmp), pages)  # imports done and kernels loaded before the first figure
    rows = [_row("in this process, one after the other (warm)", repeat, partial(in_one_process, tasks, pages=pages))]
    for n in sorted({1, 2, os.cpu_count() or 1}):
        rows.append(_row(f"`--workers {n}`", repeat, partial(_batch, tasks, pages, workers=n)))
    with LocalCluster(n_workers=2, processes=True, threads_per_worker=1, dashboard_address=None) as cluster:
        rows.append(_row("Dask LocalCluster, 2 workers x 1 thread (`--scheduler`)", repeat,
                         partial(_batch, tasks, pages, scheduler=cluster.scheduler_address)))
    return rows


def _batch(tasks: list[Path], pages: bool, out: Path, workers: int | None = None,
           scheduler: str | None = None) -> list[int]:
    result = plan_many(tasks, out, workers=workers, scheduler=scheduler, report=pages, replay=pages)
    return [r.exit_code for r in result.records]


def _row(label: str, repeat: int, run: Callable[[Path], list[int]]) -> Row:
    load_before = os.getloadavg()[0]
    wall_s, codes = best_of(repeat, run)
    row = Row(label, wall_s, codes.count(0), len(codes), load_before, os.getloadavg()[0])
    sys.stderr.write(f"{row}\n")
    return row


def table(rows: list[Row], repeat: int, pages: bool) -> str:
    one = next(r.wall_s for r in rows if r.mode == "`--workers 1`")
    outputs = "trajectory files, report.html, replay.html" if pages else "trajectory files only, `--no-pages`"
    lines = [f"### Batch planning of the public scenarios that plan ({outputs}; best of {repeat})", "",
             f"Measured {time.strftime('%Y-%m-%d %H:%M UTC', time.gmtime())}. Machine: {_machine()}; Python "
             f"{platform.python_version()}, pin {version('pin')}, toppra {version('toppra')}, "
             f"dask {version('dask')}, distributed {version('distributed')}.", "",
             "| how | planned | wall [s] | speed-up over `--workers 1` | load average (1 min) before / after |",
             "|---|---:|---:|---:|---:|"]
    for r in rows:
        lines.append(f"| {r.mode} | {r.planned}/{r.tasks} | {r.wall_s:.1f} | {one / r.wall_s:.2f} | "
                     f"{r.load_before:.1f} / {r.load_after:.1f} |")
    return "\n".join(lines)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--scenarios", type=Path, default=HERE.parents[1] / "shared" / "scenarios")
    parser.add_argument("--repeat", type=int, default=2)
    parser.add_argument("--no-pages", action="store_true", help="write the trajectory files only (no HTML pages)")
    parser.add_argument("--write", type=Path, default=None)
    args = parser.parse_args()
    tasks = public_tasks(args.scenarios)
    text = table(measure(tasks, args.repeat, not args.no_pages), args.repeat, not args.no_pages)
    sys.stdout.write(text + "\n")
    if args.write:
        sys.path.insert(0, str(HERE))
        from bench_ik import write_section

        write_section(args.write, text, f"{MARK}-{'trajectories' if args.no_pages else 'pages'}")


if __name__ == "__main__":
    main()
