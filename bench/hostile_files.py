"""Hostile files, one process each: the controller sidecar, trajectory.json, URDFs, meshes (issue 22).

    python bench/hostile_files.py [--only WORD] [--big-mesh] [--timeout 60] [--mem-limit-mb 4000] [--json FILE]
                                  [--against CHECKOUT]

The cases are the tables of tests/test_hostile_files.py (sidecars through ``singplan plan``,
trajectory.json through ``singplan replay --html`` and ``singplan export --format ros2``, URDFs
through ``singplan plan``), the Collada textures of tests/test_meshes.py (through ``plan``), and
with ``--big-mesh`` a valid 200 MB binary STL visual (through ``plan`` with the replay page).
Each runs as ``python -m singplan ...`` under an address-space cap with a timeout; its wall time
and peak resident memory are the child's own (``os.wait4``). Prints one line per case (exit code,
seconds, peak MB, the first line of stderr) and a summary by category: cases, exit codes, worst
time, worst peak. ``--against CHECKOUT`` runs another checkout's singplan on the same cases (the
figures before this work: ``--against`` a checkout of the commit before it). The figures are in
docs/reliability.md.
"""

from __future__ import annotations

import argparse
import json
import os
import resource
import shutil
import signal
import subprocess
import sys
import tempfile
import time
from collections import Counter
from collections.abc import Callable
from dataclasses import asdict, dataclass
from pathlib import Path

import numpy as np

REPO = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(REPO))
from tests import test_hostile_files as files_cases  # noqa: E402 (the repo root is put on the path first)
from tests import test_meshes as mesh_cases  # noqa: E402

Setup = Callable[[Path], list[str]]  # builds the case's files in a folder, returns the singplan arguments


@dataclass
class Outcome:
    category: str
    name: str
    exit_code: int | None  # None: killed by the timeout
    seconds: float
    peak_mb: float
    said: str


def _sidecar(make: Callable[[Path], None]) -> Setup:
    def setup(folder: Path) -> list[str]:
        task = files_cases._robot_task(folder)
        make(folder / "robot.controller.yaml")
        return ["plan", str(task), "-o", str(folder / "out"), "--quiet", "--no-report", "--no-replay"]
    return setup


def _trajectory(edit: Callable[[dict], None] | None, raw: Callable[[Path], None] | None, command: str) -> Setup:
    def setup(folder: Path) -> list[str]:
        file = folder / "trajectory.json"
        if raw is not None:
            raw(file)
        else:
            doc = json.loads((_planned() / "trajectory.json").read_text())
            assert edit is not None
            edit(doc)
            file.write_text(json.dumps(doc))
        if command == "replay":
            return ["replay", str(file), "--html", str(folder / "r.html")]
        return ["export", str(file), "--format", "ros2", "-o", str(folder / "x.yaml")]
    return setup


def _urdf(text: str) -> Setup:
    def setup(folder: Path) -> list[str]:
        return ["plan", str(files_cases._robot_task(folder, text)), "-o", str(folder / "out"), "--quiet"]
    return setup


def _textures(folder: Path) -> list[str]:
    secret = folder / "secret.png"
    secret.write_bytes(mesh_cases.SECRET)
    mesh_cases._texture_dae(folder / "arm" / "meshes", secret)
    urdf = mesh_cases.robot_folder(folder, mesh_cases.with_visuals(mesh_cases.KUKA, "package://arm/meshes/part.dae"))
    task = folder / "task.yaml"
    task.write_text(json.dumps({"robot": str(urdf), "tip": "tool0", "start": {"joints_deg": mesh_cases.START_DEG},
                                "moves": [{"lin": {"to": mesh_cases.TARGET, "speed": 0.25}}]}))
    return ["plan", str(task), "-o", str(folder / "out"), "--quiet", "--no-report"]


def _big_mesh(folder: Path) -> list[str]:
    big = folder / "arm" / "meshes" / "big.stl"
    big.parent.mkdir(parents=True)
    triangles = 4_000_000  # 200 MB
    record = np.zeros(triangles // 4, dtype=[("n", "<f4", 3), ("v", "<f4", (3, 3)), ("a", "<u2")])
    rng = np.random.default_rng(0)
    with big.open("wb") as f:
        f.write(b"big".ljust(80) + triangles.to_bytes(4, "little"))
        for _ in range(4):
            record["v"] = rng.uniform(-0.05, 0.05, record["v"].shape)
            f.write(record.tobytes())
    urdf = mesh_cases.robot_folder(folder, mesh_cases.with_visuals(mesh_cases.KUKA, "../meshes/big.stl"))
    task = folder / "task.yaml"
    task.write_text(json.dumps({"robot": str(urdf), "tip": "tool0", "start": {"joints_deg": mesh_cases.START_DEG},
                                "moves": [{"lin": {"to": mesh_cases.TARGET, "speed": 0.25}}]}))
    return ["plan", str(task), "-o", str(folder / "out"), "--quiet", "--no-report"]


_PLANNED: list[Path] = []


def _planned() -> Path:
    """The demo task planned once (the trajectory.json the cases edit)."""
    if not _PLANNED:
        folder = Path(tempfile.mkdtemp(prefix="singplan-hostile-base-"))
        subprocess.run([sys.executable, "-m", "singplan", "plan", str(REPO / "singplan" / "demo_task.yaml"), "-o",
                        str(folder), "--quiet", "--no-report", "--no-replay"], check=True, env=_env(),
                       capture_output=True, cwd=folder)
        _PLANNED.append(folder)
    return _PLANNED[0]


def cases(big_mesh: bool) -> list[tuple[str, str, Setup]]:
    out: list[tuple[str, str, Setup]] = []
    out += [("sidecar", name, _sidecar(make)) for name, (make, _) in files_cases.SIDECARS.items()]
    for command in ("replay", "export"):
        out += [(f"trajectory.json ({command})", name, _trajectory(edit, None, command))
                for name, (edit, _) in files_cases.TRAJECTORIES.items()]
        out += [(f"trajectory.json ({command})", name, _trajectory(None, make, command))
                for name, (make, _) in files_cases.RAW.items()]
    out += [("URDF", name, _urdf(text)) for name, (text, _) in files_cases.URDFS.items()]
    out.append(("meshes", "Collada textures outside the robot", _textures))
    if big_mesh:
        out.append(("meshes", "a valid 200 MB binary STL", _big_mesh))
    return out


_SINGPLAN = [REPO]  # the checkout whose singplan the cases run


def _env() -> dict[str, str]:
    return {**os.environ, "PYTHONPATH": str(_SINGPLAN[0])}


def run(argv: list[str], folder: Path, timeout_s: float, mem_limit_mb: int) -> tuple[int | None, float, float, str]:
    """Run ``singplan ARGV`` in ``folder`` (not here: ``python -m`` puts the working folder first on the
    path, which would shadow ``--against``)."""
    def limit() -> None:
        if mem_limit_mb:
            cap = mem_limit_mb * 1024 * 1024
            resource.setrlimit(resource.RLIMIT_AS, (cap, cap))

    started = time.perf_counter()
    proc = subprocess.Popen([sys.executable, "-m", "singplan", *argv], stdout=subprocess.DEVNULL,
                            stderr=subprocess.PIPE, text=True, errors="replace", preexec_fn=limit, env=_env(),
                            cwd=folder)
    timer = _Timer(proc.pid, timeout_s)
    assert proc.stderr is not None
    said = proc.stderr.read()
    _, status, usage = os.wait4(proc.pid, 0)
    proc.returncode = os.waitstatus_to_exitcode(status)
    proc.stderr.close()
    code = None if timer.fired() else proc.returncode
    return code, time.perf_counter() - started, usage.ru_maxrss / 1024, said.strip().splitlines()[0] if said else ""


class _Timer:
    """Kill a process after a timeout (SIGALRM in this single-threaded script)."""

    def __init__(self, pid: int, timeout_s: float) -> None:
        self.pid, self._fired = pid, False
        signal.signal(signal.SIGALRM, self._kill)
        signal.setitimer(signal.ITIMER_REAL, timeout_s)

    def _kill(self, signum: int, frame: object) -> None:
        self._fired = True
        os.kill(self.pid, signal.SIGKILL)

    def fired(self) -> bool:
        signal.setitimer(signal.ITIMER_REAL, 0)
        return self._fired


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--only", default="", help="run only cases whose category or name holds this")
    ap.add_argument("--big-mesh", action="store_true", help="also plan with a valid 200 MB STL visual")
    ap.add_argument("--timeout", type=float, default=60.0, help="seconds before a run is killed")
    ap.add_argument("--mem-limit-mb", type=int, default=4000, help="address-space cap of each run (0: none)")
    ap.add_argument("--json", type=Path, default=None, help="write every outcome as JSON")
    ap.add_argument("--against", type=Path, default=None, help="run this checkout's singplan instead")
    args = ap.parse_args(argv)
    if args.against is not None:
        _SINGPLAN[0] = args.against.resolve()
    outcomes = []
    for category, name, setup in cases(args.big_mesh):
        if args.only not in f"{category} {name}":
            continue
        folder = Path(tempfile.mkdtemp(prefix="singplan-hostile-"))
        try:
            code, seconds, peak, said = run(setup(folder), folder, args.timeout, args.mem_limit_mb)
        finally:
            shutil.rmtree(folder, ignore_errors=True)
        outcomes.append(Outcome(category, name, code, seconds, peak, said))
        print(f"{category:26s} {name:42s} exit {code!s:>4s} {seconds:6.2f} s {peak:6.0f} MB  {said[:110]}",
              flush=True)
    print("\n| category | cases | exit codes | worst time [s] | worst peak [MB] |\n|---|---:|---|---:|---:|")
    for category in dict.fromkeys(o.category for o in outcomes):
        mine = [o for o in outcomes if o.category == category]
        codes = Counter("timeout" if o.exit_code is None else str(o.exit_code) for o in mine)
        print(f"| {category} | {len(mine)} | {', '.join(f'{c}: {n}' for c, n in sorted(codes.items()))} | "
              f"{max(o.seconds for o in mine):.1f} | {max(o.peak_mb for o in mine):.0f} |")
    if args.json is not None:
        args.json.write_text(json.dumps([asdict(o) for o in outcomes], indent=1))
    for folder in _PLANNED:
        shutil.rmtree(folder, ignore_errors=True)
    return 0


if __name__ == "__main__":
    sys.exit(main())
