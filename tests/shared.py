"""The shared acceptance material next to the project (../shared): the independent checker and the
public scenarios. A user's clone has none of it: tests that need it skip there with the reason,
except under CI=true, where it must be present (missing is an error, not a skip)."""

from __future__ import annotations

import importlib.util
import json
import os
import subprocess
import sys
from functools import cache
from pathlib import Path
from types import ModuleType

import pytest
import yaml

# ../shared next to the project; SINGPLAN_SHARED names it where the project sits elsewhere (a git worktree)
SHARED = Path(os.environ.get("SINGPLAN_SHARED") or Path(__file__).resolve().parents[2] / "shared")
CHECKER = SHARED / "verify" / "verify_trajectory.py"
SCENARIOS = SHARED / "scenarios"
PROGRAMS = SHARED / "scenarios_programs"


def require(path: Path) -> Path:
    """``path`` inside ../shared, or skip (a user's clone) / raise (CI=true) when it is absent."""
    if path.exists():
        return path
    if os.environ.get("CI") == "true":
        raise RuntimeError(f"CI=true but {path} is missing (../shared must sit next to the project)")
    pytest.skip(f"{path} is absent (../shared is not part of a user's clone)")


def run_checker(task: Path, out: Path, *options: str) -> subprocess.CompletedProcess[str]:
    """``verify_trajectory.py TASK OUT [options]``: exit code 0 when every check holds."""
    return subprocess.run([sys.executable, str(require(CHECKER)), str(task), str(out), *options],
                          capture_output=True, text=True, timeout=600, check=False)


def bench_module(stem: str) -> ModuleType:
    """A script of bench/ imported as a module (``sys.modules[stem]``: its dataclasses look it up)."""
    spec = importlib.util.spec_from_file_location(stem, Path(__file__).resolve().parents[1] / "bench" / f"{stem}.py")
    assert spec is not None and spec.loader is not None
    module = importlib.util.module_from_spec(spec)
    sys.modules[stem] = module
    spec.loader.exec_module(module)
    return module


@cache
def checker_module() -> ModuleType:
    """The independent checker imported in this process (a battery checks hundreds of plans: one
    interpreter and Pinocchio load, not one per plan)."""
    checker = require(CHECKER)
    sys.path.insert(0, str(checker.parent))  # it imports its neighbours (paths_check, collision_check)
    spec = importlib.util.spec_from_file_location("verify_trajectory", checker)
    assert spec is not None and spec.loader is not None
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


def check_in_process(task: Path, out: Path) -> list[str]:
    """The checker's failures for the plan in ``out`` of the task file ``task`` (empty: it passes)."""
    verify = checker_module()
    verify.paths_check.TASK_DIR = task.resolve().parent
    traj = json.loads((out / "trajectory.json").read_text())
    result = verify.Checker(yaml.safe_load(task.read_text()), traj, out).run()
    verify.collision_check.add_to(result, yaml.safe_load(task.read_text()), task, traj, out)
    return list(result["failures"])
