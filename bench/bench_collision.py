"""What collision checking costs: the public cell scenarios planned with checking on and without,
side by side in one run.

    python bench/bench_collision.py [--scenarios ../shared/scenarios_cell] [--repeat 9] [--write docs/benchmarks.md]

Target (issue 25): planning the public cell scenarios with checking on takes at most 1.5x the time
without. Three variants of each task are planned in-process (``singplan.plan``: everything a caller
waits for, the last collision gate included; imports and the robot's first load excluded), the
variants alternating run by run so that a change of the machine's load falls on all alike:

- ``on``: the task as given (its cell, tool geometry and ``collision`` key);
- ``no cell``: the same task without those keys (a robot with collision geometry and an SRDF, the
  bundled arms, still checks itself: DESIGN.md's default);
- ``off``: without them and with ``collision: {self: false}``: nothing is checked.

The ratio that the target bounds is ``on`` / ``off``. Times are the process CPU time of each plan
(``time.process_time``: a loaded, shared machine disturbs it less than the wall time), the minimum
and the median of ``--repeat`` runs; a task that does not plan (exit 3, the pillar) is timed to its
refusal.
"""

from __future__ import annotations

import argparse
import copy
import statistics
import sys
import tempfile
import time
from pathlib import Path
from typing import Any

import yaml

from singplan.errors import SingplanError
from singplan.results.plan import plan

HERE = Path(__file__).resolve().parent
MARK = "bench_collision"
VARIANTS = ("on", "no cell", "off")


def variants(task_file: Path, folder: Path) -> dict[str, Path]:
    """The task as given, without its cell keys, and without any checking, as files (relative paths
    made absolute: the copies live elsewhere)."""
    doc = yaml.safe_load(task_file.read_text())
    base = task_file.resolve().parent
    if str(doc["robot"]).endswith(".urdf"):
        doc["robot"] = str((base / doc["robot"]).resolve())
    for shape in doc.get("cell") or ():
        if "mesh" in shape:
            shape["mesh"]["file"] = str((base / shape["mesh"]["file"]).resolve())
    if (doc.get("collision") or {}).get("srdf"):
        doc["collision"]["srdf"] = str((base / doc["collision"]["srdf"]).resolve())
    bare = copy.deepcopy(doc)
    bare.pop("cell", None)
    bare.pop("collision", None)
    if isinstance(bare.get("tool"), dict):
        bare["tool"].pop("geometry", None)
    off = {**copy.deepcopy(bare), "collision": {"self": False}}
    out = {}
    for name, content in zip(VARIANTS, (doc, bare, off), strict=True):
        path = folder / f"{task_file.stem}__{name.replace(' ', '_')}.yaml"
        path.write_text(yaml.safe_dump(content, sort_keys=False))
        out[name] = path
    return out


def _once(path: Path) -> tuple[float, str]:
    t0 = time.process_time()
    try:
        traj = plan(path)
        outcome = f"{traj.duration_s:.3f} s"
    except SingplanError as exc:
        outcome = f"exit {exc.exit_code}"
    return time.process_time() - t0, outcome


def measure(scenarios: Path, repeat: int) -> list[dict[str, Any]]:
    expect = yaml.safe_load((scenarios / "expect.yaml").read_text())
    names = [n for n in sorted(expect) if expect[n].get("exit") != 2]  # bad input is refused before planning
    rows: list[dict[str, Any]] = []
    with tempfile.TemporaryDirectory(prefix="singplan-bench-collision-") as tmp:
        files = {n: variants(scenarios / f"{n}.yaml", Path(tmp)) for n in names}
        for n in names:  # a first run of each: the robot's load and the meshes' reading are not what is timed
            for path in files[n].values():
                _once(path)
        times: dict[tuple[str, str], list[float]] = {}
        outcomes: dict[tuple[str, str], str] = {}
        for _ in range(repeat):
            for n in names:
                for v, path in files[n].items():
                    seconds, outcomes[(n, v)] = _once(path)
                    times.setdefault((n, v), []).append(seconds)
        for n in names:
            rows.append({"task": n, **{v: (min(times[(n, v)]), statistics.median(times[(n, v)])) for v in VARIANTS},
                         "outcomes": {v: outcomes[(n, v)] for v in VARIANTS}})
    return rows


def report(rows: list[dict[str, Any]], repeat: int) -> str:
    from importlib.metadata import version

    sys.path.insert(0, str(HERE))
    from bench_ik import machine

    lines = [f"Machine: {machine()}; Python {sys.version.split()[0]}, pin {version('pin')}, coal {version('coal')}, "
             f"toppra {version('toppra')}, numpy {version('numpy')}. `python bench/bench_collision.py --repeat "
             f"{repeat}`: process CPU time per `plan()` [ms], minimum / median of {repeat} runs, the variants "
             "alternating run by run.", "",
             "| task | on | no cell | off | on / off (min) | on / off (median) | on: outcome |",
             "|---|---|---|---|---|---|---|"]
    total = {v: 0.0 for v in VARIANTS}
    for r in rows:
        for v in VARIANTS:
            total[v] += r[v][0]
        cells = " | ".join(f"{r[v][0] * 1e3:.0f} / {r[v][1] * 1e3:.0f}" for v in VARIANTS)
        lines.append(f"| {r['task']} | {cells} | {r['on'][0] / r['off'][0]:.2f} | {r['on'][1] / r['off'][1]:.2f} "
                     f"| {r['outcomes']['on']} |")
    lines.append(f"| all together | {total['on'] * 1e3:.0f} | {total['no cell'] * 1e3:.0f} | {total['off'] * 1e3:.0f} "
                 f"| {total['on'] / total['off']:.2f} | | |")
    return "\n".join(lines) + "\n"


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--scenarios", type=Path, default=HERE.parents[1] / "shared" / "scenarios_cell")
    parser.add_argument("--repeat", type=int, default=9, help="runs per variant and task")
    parser.add_argument("--write", type=Path, default=None, help="results file to update (its bench_collision section)")
    args = parser.parse_args(argv)
    text = report(measure(args.scenarios, args.repeat), args.repeat)
    sys.path.insert(0, str(HERE))
    from bench_ik import emit

    emit(text, args.write, MARK)
    return 0


if __name__ == "__main__":
    sys.exit(main())
