"""The shared acceptance material next to the project (../shared): the independent checker and the
public scenarios. A user's clone has none of it: tests that need it skip there with the reason,
except under CI=true, where it must be present (missing is an error, not a skip)."""

from __future__ import annotations

import os
import subprocess
import sys
from pathlib import Path

import pytest

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
