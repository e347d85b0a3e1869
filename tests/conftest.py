"""Shared fixtures: robots are loaded once per session (Pinocchio parsing is the slow part), the
demo planned once, and one live replay server serves the tests of `singplan replay --serve`."""

from __future__ import annotations

import os
import signal
import subprocess
import sys
from collections.abc import Iterator
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
import pytest

from singplan.kinematics.robot import Robot, bundled_robots, load_robot

OPW_NAMES = [name for name, entry in bundled_robots().items() if entry.family == "opw"]


@pytest.fixture(scope="session")
def robots() -> dict[str, Robot]:
    return {name: load_robot(name) for name in [*OPW_NAMES, "ur5"]}


@pytest.fixture
def rng() -> np.random.Generator:
    return np.random.default_rng(20261122)


def erd_urdf(name: str) -> str:
    """The URDF path ``example_robot_data.load(name).urdf`` gives, without building the model: load()
    also parses every mesh (2.6 s for so101, 1 s for z1). tests/test_robot.py checks the two agree."""
    import example_robot_data.robots_loader as loaders

    loader = loaders.ROBOTS[name]
    return os.path.join(loaders.getModelPath(loader.path), loader.path, loader.urdf_subpath, loader.urdf_filename)


def random_q(robot: Robot, rng: np.random.Generator, n: int) -> np.ndarray:
    """n joint vectors inside the limits (finite ranges, capped at +-2*pi), shape (n, dof)."""
    lo = np.maximum(robot.lower_rad, -2 * np.pi)
    hi = np.minimum(robot.upper_rad, 2 * np.pi)
    return rng.uniform(lo, hi, size=(n, robot.n_joints))


# the public scenarios sit next to the project in development and CI (as in tests/test_scenarios.py)
_SHARED_SCENARIOS = Path(__file__).resolve().parents[2] / "shared" / "scenarios"
SCENARIOS = _SHARED_SCENARIOS if _SHARED_SCENARIOS.is_dir() else None


@pytest.fixture(scope="session")
def planned_kuka(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """An output folder of a small plan (a KUKA LIN through a wrist near miss), planned once per session."""
    from singplan.results.plan import plan
    from singplan.results.trajectory import save
    from singplan.task.load import load_task

    task = Path(__file__).resolve().parent.parent / "singplan" / "demo_task.yaml"
    return save(plan(load_task(task)), tmp_path_factory.mktemp("planned_kuka"))


def listening_ports() -> dict[int, set[str]]:
    """Listening TCP ports of this machine -> their local addresses (hex, from /proc/net/tcp*)."""
    ports: dict[int, set[str]] = {}
    for table in ("/proc/net/tcp", "/proc/net/tcp6"):
        if not os.path.exists(table):
            continue
        for line in Path(table).read_text().splitlines()[1:]:
            fields = line.split()
            address, port = fields[1].split(":")
            if fields[3] == "0A":  # LISTEN
                ports.setdefault(int(port, 16), set()).add(address)
    return ports


@dataclass
class ReplayServer:
    """A running ``singplan replay DIR --serve``: its first line and the ports listening before and after it."""

    proc: subprocess.Popen[str]
    line: str
    ports_before: dict[int, set[str]]
    ports_serving: dict[int, set[str]]
    rest: list[str] = field(default_factory=list)  # its stdout after the first line, once stopped

    def errors(self) -> str:
        """Its stderr, for a message when it did not start (it has exited then)."""
        assert self.proc.stderr is not None
        return self.proc.stderr.read() if self.proc.poll() is not None else ""

    def stop(self) -> str:
        """SIGTERM, as a user's Ctrl-C or kill would; its stdout after the first line (once stopped, again)."""
        if not self.rest:
            if self.proc.poll() is None:
                self.proc.send_signal(signal.SIGTERM)
            self.rest.append(self.proc.communicate(timeout=30)[0])
        return self.rest[0]


@pytest.fixture(scope="session")
def replay_server(planned_kuka: Path) -> Iterator[ReplayServer]:
    """One live server (a singplan process and meshcat's own server process: seconds to start) for the
    tests of tests/test_outputs.py and tests/test_plan.py; the one that stops it checks how it stops."""
    before = listening_ports()
    proc = subprocess.Popen([sys.executable, "-m", "singplan", "replay", str(planned_kuka), "--serve"],
                            stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    assert proc.stdout is not None
    server = ReplayServer(proc, proc.stdout.readline(), before, listening_ports())
    try:
        yield server
    finally:
        server.stop()
