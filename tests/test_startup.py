"""Start-up work (issue 12): what `import singplan`, `singplan --help` and `singplan plan` load, and
the work they do once instead of twice. The timings themselves are bench/bench_startup.py's."""

from __future__ import annotations

import gc
import io
import json
import math
import subprocess
import sys
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import numpy as np
import pytest
import yaml

from singplan import cli
from singplan.kinematics import families, robot, vendor_config
from singplan.kinematics.closedform import opw
from singplan.planning.orchestration import targets

DEMO = Path(cli.__file__).with_name("demo_task.yaml")
HEAVY = ("pinocchio", "numba", "toppra", "scipy", "meshcat", "matplotlib")
PAGES = ("meshcat", "trimesh")  # the replay's (matplotlib, the report's, comes with TOPP-RA anyway)


@pytest.fixture
def fresh_registry() -> Iterator[None]:
    """robots.yaml read again by the test, and again by whatever runs after it."""
    caches = (robot.registry_specs, robot.bundled_robots, vendor_config._registry_conventions)
    for c in caches:
        c.cache_clear()
    yield
    for c in caches:
        c.cache_clear()


def test_robots_yaml_is_parsed_once_for_the_registry_and_the_controller_conventions(
        fresh_registry: None, monkeypatch: pytest.MonkeyPatch) -> None:
    parsed: list[str] = []
    real_load = yaml.load

    def counting_load(stream: Any, Loader: Any) -> Any:  # PyYAML's keyword
        parsed.append(Loader.__name__)
        return real_load(stream, Loader=Loader)

    monkeypatch.setattr(robot.yaml, "load", counting_load)
    monkeypatch.setattr(robot.yaml, "safe_load", lambda *a, **k: pytest.fail("robots.yaml read a second way"))
    entries = robot.bundled_robots()
    conventions = vendor_config._registry_conventions()
    assert len(parsed) == 1, parsed
    assert "kuka_kr6_r900_2" in entries and len(conventions) >= 10


def test_the_registry_reads_as_the_pure_python_safe_loader_reads_it(fresh_registry: None) -> None:
    text = (robot.robots_dir() / "robots.yaml").read_text()
    assert robot.registry_specs() == yaml.safe_load(text)["robots"]


def test_the_numpy_wrap_of_the_family_offsets_is_the_compiled_one() -> None:
    rng = np.random.default_rng(12)
    edges = [math.pi, -math.pi, 0.0, 3 * math.pi, -3 * math.pi, 2 * math.pi, -math.pi + 1e-16, math.pi - 1e-16]
    angles = [*rng.uniform(-20.0, 20.0, 2000), *edges]
    assert [families._wrap(a) for a in angles] == [float(opw.wrap(a)) for a in angles]


def test_plan_with_a_page_loads_the_robot_once(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    loads: list[str] = []
    real_load = targets.load_robot

    def counting(name: str, **kwargs: Any) -> robot.Robot:
        loads.append(name)
        return real_load(name, **kwargs)

    monkeypatch.setattr(targets, "load_robot", counting)
    out = io.StringIO()
    code = cli.main(["plan", str(DEMO), "-o", str(tmp_path / "o"), "--quiet", "--no-replay"], out=out,
                    err=io.StringIO())
    assert code == 0, out.getvalue()
    assert (tmp_path / "o" / "report.html").stat().st_size > 0
    assert loads == ["kuka_kr6_r900_2"]


def test_main_leaves_garbage_collection_as_it_found_it(tmp_path: Path) -> None:
    assert gc.get_freeze_count() == 0
    code = cli.main(["plan", str(DEMO), "-o", str(tmp_path / "o"), "--quiet", "--no-report", "--no-replay"],
                    out=io.StringIO(), err=io.StringIO())
    assert code == 0
    assert gc.get_freeze_count() == 0  # a long-lived caller of main() keeps collecting everything


def test_the_console_entry_point_freezes_the_heap_before_the_interpreter_exits(
        monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setattr(cli, "main", lambda: 0)
    monkeypatch.setattr(cli.signal, "signal", lambda *a: None)  # run() must not take this process's SIGTERM
    try:
        with pytest.raises(SystemExit) as stop:
            cli.run()
        assert stop.value.code == 0
        assert gc.get_freeze_count() > 0
    finally:
        gc.unfreeze()


def test_import_help_and_a_plan_without_pages_load_only_what_they_need(tmp_path: Path) -> None:
    """In a fresh interpreter: `import singplan` and `--help` load none of the heavy packages, a plan
    without pages none of the replay's."""
    script = f"""
import contextlib, io, json, sys
def loaded(names): return sorted(n for n in names if n in sys.modules)
import singplan
after_import = loaded({HEAVY!r})
from singplan.cli import main
with contextlib.redirect_stdout(io.StringIO()):
    help_code = main(["--help"])
after_help = loaded({HEAVY!r})
plan_code = main(["plan", {str(DEMO)!r}, "-o", {str(tmp_path / "o")!r}, "--quiet", "--no-report", "--no-replay"],
                 out=io.StringIO())
print(json.dumps([after_import, help_code, after_help, plan_code, loaded({PAGES!r})]))
"""
    run = subprocess.run([sys.executable, "-c", script], capture_output=True, text=True, timeout=300)
    assert run.returncode == 0, run.stderr[-2000:]
    after_import, help_code, after_help, plan_code, pages = json.loads(run.stdout.splitlines()[-1])
    assert (after_import, help_code, after_help) == ([], 0, [])
    assert (plan_code, pages) == (0, [])
