"""A fingerprint of what singplan plans, to prove a refactoring changed nothing (issue 24).

    python bench/behaviour_fingerprint.py record OUT.jsonl [--tasks DIR_OR_FILE ...] [--methods ...] [--only SUBSTR]
    python bench/behaviour_fingerprint.py compare BEFORE.jsonl AFTER.jsonl

``record`` plans every task (default: every ``*.yaml`` listed in an ``expect.yaml`` of the public
scenario folders next to the project, ``../shared/scenarios*``, and ``examples/*.yaml``) through
``singplan.cli.main`` in this process, once with the task's own method and once with each
``--method`` (auto, exact, wrist-joint, axis, null-space, dls, average, ptp), and writes one JSON
line per run: exit code, the last line of what the command printed, the trajectory's duration
and sample count, a SHA-256 of its joint values ``q`` and one of trajectory.json's bytes (with
the wall-clock ``planning_time_s`` blanked, the one figure that differs between two runs). It also
runs ``singplan check`` and ``singplan check --json`` on each task. For the tasks of ``--pages``
(default: the examples and the cell and program scenarios) the task's own plan is run once more
with the summary (``--full``), the ``--json`` document and both pages, then replayed
(``singplan replay --html``) and exported in every format; each text is hashed with its wall-clock
figures blanked and meshcat's object ids made constant. ``singplan robots`` and ``singplan info``
of every bundled robot are recorded too. ``compare`` prints every line that differs and exits 1 if
any does.

Run it on the commit before a change and after it: a refactoring that moves code without
changing behaviour leaves every line identical, bit for bit.
"""

from __future__ import annotations

import argparse
import hashlib
import io
import json
import re
import shutil
import sys
import tempfile
import time
from collections.abc import Iterator
from pathlib import Path
from typing import Any

ROOT = Path(__file__).resolve().parents[1]
SHARED = ROOT.parent / "shared"
METHODS = ("auto", "exact", "wrist-joint", "axis", "null-space", "dls", "average", "ptp")
_WALL_CLOCK = re.compile(rb'"planning_time_s": [-+0-9.eE]+')
_WALL_CLOCK_TEXTS = (re.compile(r'"planning_time_s": [-+0-9.eE]+'), re.compile(r"planning [0-9.]+ s"),
                     re.compile(r"<td>planning_time_s</td><td>[^<]*</td>"), re.compile(r'"wall_s": [-+0-9.eE]+'))
EXPORTS = ("ros2", "ros2-json", "urscript", "csv-deg", "krl", "rapid", "fanuc-ls")


def default_tasks() -> list[Path]:
    """The public scenarios (those their expect.yaml lists) and the example tasks."""
    import yaml

    tasks: list[Path] = []
    for folder in sorted(SHARED.glob("scenarios*")):
        expect = folder / "expect.yaml"
        if expect.is_file():
            tasks += [folder / f"{name}.yaml" for name in sorted(yaml.safe_load(expect.read_text()))]
    return tasks + sorted((ROOT / "examples").glob("*.yaml"))


def _cli(argv: list[str]) -> tuple[int, str]:
    from singplan.cli import main

    out, err = io.StringIO(), io.StringIO()
    code = main(argv, out=out, err=err)
    lines = (out.getvalue() + err.getvalue()).strip().splitlines()
    return code, lines[-1] if lines else ""


def _digest(data: bytes) -> str:
    return hashlib.sha256(data).hexdigest()


def plan_row(task: Path, method: str | None, folder: Path) -> dict[str, Any]:
    """One plan of the task (its own method when ``method`` is None) and its figures."""
    argv = ["plan", str(task), "-o", str(folder), "--quiet", "--no-report", "--no-replay"]
    argv += ["--method", method] if method is not None else []
    t0 = time.perf_counter()
    code, last = _cli(argv)
    row: dict[str, Any] = {"task": str(task), "command": "plan", "method": method or "(task's)", "exit": code,
                           "last_line": last}
    trajectory = folder / "trajectory.json"
    if code == 0 and trajectory.is_file():
        import numpy as np

        raw = trajectory.read_bytes()
        doc = json.loads(raw)
        row |= {"duration_s": doc["metrics"]["duration_s"], "samples": len(doc["t"]),
                "q_sha256": _digest(np.asarray(doc["q"], dtype=np.float64).tobytes()),
                "json_sha256": _digest(_WALL_CLOCK.sub(b'"planning_time_s": 0', raw))}
    row["wall_s"] = round(time.perf_counter() - t0, 2)  # not compared
    return row


def _blanked(text: str) -> str:
    for pattern in _WALL_CLOCK_TEXTS:
        text = pattern.sub("<wall clock>", text)
    return text


def _cli_text(argv: list[str]) -> tuple[int, str]:
    from singplan.cli import main

    out, err = io.StringIO(), io.StringIO()
    code = main(argv, out=out, err=err)
    return code, out.getvalue() + "\n--\n" + err.getvalue()


def page_rows(task: Path, folder: Path) -> Iterator[dict[str, Any]]:
    """The task's own plan with its summary, --json document, pages, replay and exports, each hashed."""
    import uuid

    uuid.uuid1 = uuid.uuid4 = lambda *args, **kwargs: uuid.UUID(int=0)  # meshcat names its objects by uuid1
    shutil.rmtree(folder, ignore_errors=True)
    for flags in (["--full"], ["--json", "--no-report", "--no-replay"]):
        code, text = _cli_text(["plan", str(task), "-o", str(folder), *flags])
        yield {"task": str(task), "command": " ".join(["plan", *flags]), "exit": code,
               "output_sha256": _digest(_blanked(text).encode())}
        if code != 0:
            return
        if flags[0] == "--full":
            for page in ("report.html", "replay.html"):
                path = folder / page
                yield {"task": str(task), "command": f"page {page}",
                       "sha256": _digest(_blanked(path.read_text()).encode()) if path.is_file() else None}
    code, text = _cli_text(["replay", str(folder), "--html", str(folder / "again.html")])
    yield {"task": str(task), "command": "replay --html", "exit": code, "output_sha256": _digest(text.encode()),
           "sha256": _digest((folder / "again.html").read_bytes()) if code == 0 else None}
    for fmt in EXPORTS:
        target = folder / f"export-{fmt}"
        code, text = _cli_text(["export", str(folder), "--format", fmt, "-o", str(target)])
        written = target.read_bytes() if target.is_file() else b""
        yield {"task": str(task), "command": f"export {fmt}", "exit": code,
               "output_sha256": _digest(text.encode()), "sha256": _digest(written)}
    shutil.rmtree(folder, ignore_errors=True)


def robot_rows() -> Iterator[dict[str, Any]]:
    from singplan.kinematics.robot import bundled_robots

    for argv in (["robots"], ["robots", "--json"]):
        code, text = _cli_text(argv)
        yield {"task": "-", "command": " ".join(argv), "exit": code, "output_sha256": _digest(text.encode())}
    for name in bundled_robots():
        for flags in ([], ["--json"]):
            code, text = _cli_text(["info", name, *flags])
            yield {"task": name, "command": " ".join(["info", *flags]), "exit": code,
                   "output_sha256": _digest(text.encode())}


def default_pages() -> list[Path]:
    return sorted((ROOT / "examples").glob("*.yaml")) + sorted(SHARED.glob("scenarios_[cp]*/*.yaml"))


def check_rows(task: Path) -> Iterator[dict[str, Any]]:
    from singplan.cli import main

    for flags in ([], ["--json"]):
        out, err = io.StringIO(), io.StringIO()
        code = main(["check", str(task), *flags], out=out, err=err)
        yield {"task": str(task), "command": " ".join(["check", *flags]), "exit": code,
               "output_sha256": _digest((out.getvalue() + "\n--\n" + err.getvalue()).encode()),
               "last_line": (out.getvalue() + err.getvalue()).strip().splitlines()[-1:]}


def record(out_path: Path, tasks: list[Path], methods: list[str], only: str, pages: list[Path]) -> None:
    # one fixed folder, so the printed lines (which name it) compare equal between two records
    tmp = Path(tempfile.gettempdir()) / "singplan-fingerprint"
    with out_path.open("w") as out:
        if not only:
            for row in robot_rows():
                out.write(json.dumps(row) + "\n")
        for task in tasks:
            if only not in str(task):
                continue
            for k, method in enumerate([None, *methods]):
                folder = tmp / f"{task.stem}-{k}"
                shutil.rmtree(folder, ignore_errors=True)
                row = plan_row(task, method, folder)
                shutil.rmtree(folder, ignore_errors=True)
                out.write(json.dumps(row) + "\n")
                out.flush()
                print(f"{row['exit']} {row['wall_s']:6.1f} s {task.name} {row['method']}", file=sys.stderr)
            for row in check_rows(task):
                out.write(json.dumps(row) + "\n")
                out.flush()
            if task in pages:
                for row in page_rows(task, tmp / f"{task.stem}-pages"):
                    out.write(json.dumps(row) + "\n")
                    out.flush()


def _key(row: dict[str, Any]) -> tuple[str, str, str]:
    return row["task"], row["command"], row.get("method", "")


def compare(before: Path, after: Path) -> int:
    old = {_key(r): r for r in map(json.loads, before.read_text().splitlines())}
    new = {_key(r): r for r in map(json.loads, after.read_text().splitlines())}
    differ = 0
    for key in sorted(old.keys() | new.keys()):
        a, b = old.get(key), new.get(key)
        if a is None or b is None:
            print(f"only in {'after' if a is None else 'before'}: {key}")
            differ += 1
            continue
        fields = sorted(f for f in a.keys() | b.keys() if f != "wall_s" and a.get(f) != b.get(f))
        if fields:
            differ += 1
            print(f"{key}: " + "; ".join(f"{f}: {a.get(f)!r} -> {b.get(f)!r}" for f in fields))
    print(f"{len(old)} runs before, {len(new)} after, {differ} differ")
    return 1 if differ else 0


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    sub = ap.add_subparsers(dest="command", required=True)
    rec = sub.add_parser("record")
    rec.add_argument("out", type=Path)
    rec.add_argument("--tasks", type=Path, nargs="*", default=None)
    rec.add_argument("--methods", nargs="*", default=list(METHODS))
    rec.add_argument("--only", default="")
    rec.add_argument("--pages", type=Path, nargs="*", default=None)
    cmp_ = sub.add_parser("compare")
    cmp_.add_argument("before", type=Path)
    cmp_.add_argument("after", type=Path)
    args = ap.parse_args(argv)
    if args.command == "compare":
        return compare(args.before, args.after)
    pages = args.pages if args.pages is not None else default_pages()
    record(args.out, args.tasks or default_tasks(), args.methods, args.only, pages)
    return 0


if __name__ == "__main__":
    sys.exit(main())
