"""Cycle times of stop-to-stop programs with and without a jerk limit (and with the quintic PTP law).

    python bench/bench_jerk.py [--shared ../shared] [--jerk 1000 500 200] [--write docs/benchmarks.md]

The programs: the public program scenario (../shared/scenarios/abb_irb2400__program) and the public
fly-by programs (../shared/scenarios_programs/*flyby*) with every `blend_mm` and `weave` removed,
so every move starts and ends at rest. Each is planned by `singplan plan` (no pages) as written
(acceleration-limited), with `limits.jerk` at each value given, and with the quintic PTP law
(Python API ``Limits.ptp_time_law``, planned in-process; the checker does not know the law but
judges the samples), and every plan is judged by the independent checker.
"""

from __future__ import annotations

import argparse
import contextlib
import io
import json
import os
import platform
import subprocess
import sys
import tempfile
from dataclasses import replace
from importlib.metadata import version
from pathlib import Path
from typing import Any

import yaml

from singplan.cli import main as cli_main
from singplan.results.plan import plan
from singplan.results.trajectory import save
from singplan.task.load import parse_task

HERE = Path(__file__).resolve().parent
MARK = "bench_jerk"


def _machine() -> str:
    sys.path.insert(0, str(HERE))
    from bench_ik import machine  # one definition of the machine line for every benchmark

    return machine()


def programs(shared: Path) -> dict[str, dict[str, Any]]:
    """name -> task mapping, stop-to-stop (blend_mm and weave removed)."""
    found = {"abb_irb2400__program": yaml.safe_load((shared / "scenarios" / "abb_irb2400__program.yaml").read_text())}
    for path in sorted((shared / "scenarios_programs").glob("*flyby*.yaml")):
        task = yaml.safe_load(path.read_text())
        for move in task["moves"]:
            for body in move.values():
                body.pop("blend_mm", None)
                body.pop("weave", None)
        found[path.stem.replace("flyby_", "") + " (stop-to-stop)"] = task
    return found


def _judge(task: dict[str, Any], out: Path, checker: Path) -> tuple[float, float, bool]:
    """(duration [s], planning time [s], checker verdict) of the plan written in ``out``."""
    metrics = json.loads((out / "trajectory.json").read_text())["metrics"]
    (out / "task.yaml").write_text(yaml.safe_dump(task))
    verdict = subprocess.run([sys.executable, str(checker), str(out / "task.yaml"), str(out), "--quiet"],
                             capture_output=True, text=True, timeout=600)
    return float(metrics["duration_s"]), float(metrics["planning_time_s"]), verdict.returncode == 0


def run_one(task: dict[str, Any], out: Path, checker: Path, quintic: bool) -> tuple[float, float, bool] | str:
    out.mkdir(parents=True)
    if quintic:  # no YAML key: planned through the Python API
        parsed = parse_task(task)
        traj = plan(replace(parsed, limits=replace(parsed.limits, ptp_time_law="quintic")))
        save(traj, out)
        return _judge(task, out, checker)
    (out / "in.yaml").write_text(yaml.safe_dump(task))
    with contextlib.redirect_stdout(io.StringIO()):  # its one-line summary; the table says it all
        code = cli_main(["plan", str(out / "in.yaml"), "-o", str(out), "--quiet", "--no-report", "--no-replay"])
    return _judge(task, out, checker) if code == 0 else f"exit {code}"


def measure(shared: Path, jerks: list[float]) -> list[dict[str, Any]]:
    checker = shared / "verify" / "verify_trajectory.py"
    rows = []
    with tempfile.TemporaryDirectory() as tmp:
        for name, task in programs(shared).items():
            row: dict[str, Any] = {"name": name, "moves": len(task["moves"]), "load": os.getloadavg()[0]}
            variants = [("none", None, False), *((f"{j:g}", j, False) for j in jerks), ("quintic", None, True)]
            for key, jerk, quintic in variants:
                variant = json.loads(json.dumps(task))
                if jerk is not None:
                    variant.setdefault("limits", {})["jerk"] = jerk
                row[key] = run_one(variant, Path(tmp) / f"{len(rows)}-{key}", checker, quintic)
            rows.append(row)
    return rows


def _cell(result: tuple[float, float, bool] | str, base: float | None) -> str:
    if isinstance(result, str):
        return result
    duration, _, passed = result
    more = f" (+{100 * (duration / base - 1):.1f} %)" if base else ""
    return f"{duration:.3f}{more}{'' if passed else ' FAIL'}"


def table(rows: list[dict[str, Any]], jerks: list[float]) -> str:
    keys = [f"{j:g}" for j in jerks]
    lines = ["### Stop-to-stop programs with and without a jerk limit (duration [s], checker PASS unless marked)", "",
             f"Machine: {_machine()}; Python {platform.python_version()}, pin {version('pin')}, "
             f"toppra {version('toppra')}, numpy {version('numpy')}.", "",
             "| program | moves | acceleration-limited | " + " | ".join(f"jerk {k} rad/s^3" for k in keys)
             + " | quintic PTP law | planning [s] none / jerk " + keys[-1] + " | load |",
             "|---|---:|---:|" + "---:|" * len(keys) + "---:|---:|---:|"]
    for r in rows:
        base = r["none"][0] if not isinstance(r["none"], str) else None
        plan_s = " / ".join(f"{r[k][1]:.2f}" if not isinstance(r[k], str) else "-" for k in ("none", keys[-1]))
        lines.append(f"| {r['name']} | {r['moves']} | {_cell(r['none'], None)} | "
                     + " | ".join(_cell(r[k], base) for k in keys)
                     + f" | {_cell(r['quintic'], base)} | {plan_s} | {r['load']:.1f} |")
    return "\n".join(lines)


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--shared", type=Path, default=HERE.parents[1] / "shared")
    parser.add_argument("--jerk", type=float, nargs="+", default=[1000.0, 500.0, 200.0])
    parser.add_argument("--write", type=Path, default=None)
    args = parser.parse_args(argv)
    text = table(measure(args.shared, args.jerk), args.jerk)
    sys.path.insert(0, str(HERE))
    from bench_ik import emit

    emit(text, args.write, MARK)
    return 0


if __name__ == "__main__":
    sys.exit(main())
