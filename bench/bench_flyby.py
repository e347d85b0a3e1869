"""Cycle times of fly-by programs: stop-to-stop, blended, and each with a jerk limit, side by side.

    python bench/bench_flyby.py [--shared ../shared] [--jerk 1000] [--write docs/benchmarks.md]

The programs: the public fly-by programs (../shared/scenarios_programs/*flyby*) and the bundled
examples/flyby_*.yaml. Each is planned by `singplan plan` (no pages) four ways: with every
`blend_mm` removed (every move starts and ends at rest), as written (blended), and both again
with `limits.jerk`; every plan is judged by the independent checker (`--shared`). The gain is
1 - blended / stop-to-stop.
"""

from __future__ import annotations

import argparse
import json
import os
import platform
import sys
import tempfile
from importlib.metadata import version
from pathlib import Path
from typing import Any

import yaml

HERE = Path(__file__).resolve().parent
sys.path.insert(0, str(HERE))
from bench_ik import emit, machine  # noqa: E402  (one definition for every benchmark)
from bench_jerk import run_one  # noqa: E402

MARK = "bench_flyby"


def programs(shared: Path) -> dict[str, dict[str, Any]]:
    """name -> task mapping of every fly-by program found."""
    paths = [*sorted((shared / "scenarios_programs").glob("*flyby*.yaml")),
             *sorted((HERE.parent / "examples").glob("flyby_*.yaml"))]
    return {p.stem: yaml.safe_load(p.read_text()) for p in paths}


def _variant(task: dict[str, Any], blended: bool, jerk: float | None) -> dict[str, Any]:
    out = json.loads(json.dumps(task))
    if not blended:
        for move in out["moves"]:
            for body in move.values():
                body.pop("blend_mm", None)
    if jerk is not None:
        out.setdefault("limits", {})["jerk"] = jerk
    return out


def measure(shared: Path, jerk: float) -> list[dict[str, Any]]:
    checker = shared / "verify" / "verify_trajectory.py"
    rows = []
    with tempfile.TemporaryDirectory() as tmp:
        for name, task in programs(shared).items():
            row: dict[str, Any] = {"name": name, "moves": len(task["moves"]), "load": os.getloadavg()[0]}
            for key, blended, j in (("stop", False, None), ("blend", True, None), ("stop_j", False, jerk),
                                    ("blend_j", True, jerk)):
                row[key] = run_one(_variant(task, blended, j), Path(tmp) / f"{len(rows)}-{key}", checker, False)
            rows.append(row)
    return rows


def _cell(result: tuple[float, float, bool] | str, base: tuple[float, float, bool] | str | None = None) -> str:
    if isinstance(result, str):
        return result
    duration, _, passed = result
    gain = f" ({100 * (1 - duration / base[0]):+.0f} %)" if base is not None and not isinstance(base, str) else ""
    return f"{duration:.3f}{gain}{'' if passed else ' FAIL'}"


def table(rows: list[dict[str, Any]], jerk: float) -> str:
    lines = ["### Fly-by programs: cycle time [s] (gain against stopping at every point; checker PASS unless marked)",
             "", f"Machine: {machine()}; Python {platform.python_version()}, pin {version('pin')}, "
             f"toppra {version('toppra')}, numpy {version('numpy')}.", "",
             f"| program | moves | stop-to-stop | blended | stop-to-stop, jerk {jerk:g} | blended, jerk {jerk:g} "
             "| planning [s] stop / blended | load |", "|---|---:|---:|---:|---:|---:|---:|---:|"]
    for r in rows:
        plan_s = " / ".join(f"{r[k][1]:.2f}" if not isinstance(r[k], str) else "-" for k in ("stop", "blend"))
        lines.append(f"| {r['name']} | {r['moves']} | {_cell(r['stop'])} | {_cell(r['blend'], r['stop'])} | "
                     f"{_cell(r['stop_j'])} | {_cell(r['blend_j'], r['stop_j'])} | {plan_s} | {r['load']:.1f} |")
    return "\n".join(lines)


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--shared", type=Path, default=HERE.parents[1] / "shared")
    parser.add_argument("--jerk", type=float, default=1000.0)
    parser.add_argument("--write", type=Path, default=None)
    args = parser.parse_args(argv)
    text = table(measure(args.shared, args.jerk), args.jerk)
    emit(text, args.write, MARK)
    return 0


if __name__ == "__main__":
    sys.exit(main())
