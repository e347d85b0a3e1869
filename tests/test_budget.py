"""Bounded work and memory: tasks over the caps are refused up front (exit 2), naming the move."""

from __future__ import annotations

import json
import math
import os
import resource
import subprocess
import sys
import time
from pathlib import Path
from typing import Any

import numpy as np
import pytest
import yaml

from singplan.errors import BudgetError
from singplan.planning.orchestration import planner
from singplan.planning.orchestration.budget import MAX_PATH_SAMPLES, TaskEstimate, check_task, estimate_moves, memory_mb
from singplan.planning.orchestration.targets import load_task_robot
from singplan.planning.path.cartesian import STEP_M, STEP_RAD
from singplan.planning.timing.ratios import sample_ratios
from singplan.results import build as trajectory_build
from singplan.results.plan import plan
from singplan.task.load import parse_task
from singplan.task.schema import MAX_OUTPUT_SAMPLES, TASK_MEMORY_MB, Task

START_DEG = [0, -80, 100, 0, 40, 0]
GUARD_BYTES = 3_000_000_000  # the subprocess's address space: a regression fails, it cannot eat the machine
GUARD_S = 120


def _task(moves: list[dict[str, Any]], period: float = 0.004) -> dict[str, Any]:
    return {"robot": "kuka_kr6_r900_2", "tool": {"xyz": [0, 0, 0.1]}, "start": {"joints_deg": START_DEG},
            "moves": moves, "output": {"period": period}}


FAR_VIA = _task([{"circ": {"via": {"xyz": [-100, 100, 100]}, "to": {"xyz": [100, -100, -100]}, "speed": 0.25}}])
LIN_TO = [0.45, 0.3, 0.45]
LIN_BACK = [0.45, -0.05, 0.45]


def _three_slow_lins(samples_each: float, period: float = 0.0005) -> dict[str, Any]:
    """Three LINs of ~0.35 m, each timed at about ``samples_each`` samples of ``period`` [s]
    (0.5 ms: millions of samples at speeds above the task's lowest, 0.1 mm/s)."""
    speed = 0.355 / (samples_each * period)
    return _task([{"lin": {"to": {"xyz": xyz}, "speed": speed}} for xyz in (LIN_TO, LIN_BACK, LIN_TO)], period)


def _estimate(doc: dict[str, Any], **kwargs: Any) -> TaskEstimate:
    task = parse_task(doc)
    robot = load_task_robot(task)
    return check_task(task, robot, np.radians(task.start_joints_deg), STEP_M, STEP_RAD, **kwargs)


def _limit_memory() -> None:
    resource.setrlimit(resource.RLIMIT_AS, (GUARD_BYTES, GUARD_BYTES))


def _guarded_cli(args: list[str]) -> tuple[int, str, float]:
    """``singplan ARGS`` in a subprocess under an address-space limit and a timeout."""
    code = "import sys; from singplan.cli import main; sys.exit(main(sys.argv[1:]))"
    t0 = time.perf_counter()
    done = subprocess.run([sys.executable, "-c", code, *args], capture_output=True, text=True, timeout=GUARD_S,
                          preexec_fn=_limit_memory, check=False)
    return done.returncode, done.stderr, time.perf_counter() - t0


def _measured_cli(args: list[str], tmp_path: Path) -> tuple[int, str, float]:
    """``singplan ARGS`` in a guarded subprocess: exit code, stderr and peak RSS [MB] (``os.wait4``)."""
    code = "import sys; from singplan.cli import main; sys.exit(main(sys.argv[1:]))"
    err_path = tmp_path / "stderr.txt"
    with err_path.open("w") as err:
        proc = subprocess.Popen([sys.executable, "-c", code, *args], preexec_fn=_limit_memory,
                                stdout=subprocess.DEVNULL, stderr=err)
    deadline = time.perf_counter() + GUARD_S
    while not (done := os.wait4(proc.pid, os.WNOHANG))[0]:
        if time.perf_counter() > deadline:
            proc.kill()
        time.sleep(0.1)
    proc.returncode = os.waitstatus_to_exitcode(done[1])
    return proc.returncode, err_path.read_text(), done[2].ru_maxrss / 1024


def _write(tmp_path: Path, doc: dict[str, Any]) -> Path:
    path = tmp_path / "task.yaml"
    path.write_text(yaml.safe_dump(json.loads(json.dumps(doc))))  # no shared lists: no YAML aliases
    return path


@pytest.mark.parametrize("command", ["plan", "check"])
@pytest.mark.slow  # singplan in a guarded subprocess
def test_far_via_circ_is_refused_quickly(tmp_path: Path, command: str) -> None:
    """The issue's CIRC (radius ~18 km: 57 M path samples) grew to 23.6 GB; now exit 2 in seconds."""
    args = [command, str(_write(tmp_path, FAR_VIA))] + (["-o", str(tmp_path / "out")] if command == "plan" else [])
    code, err, seconds = _guarded_cli(args)
    assert code == 2, err
    assert "moves[0].circ" in err and str(MAX_PATH_SAMPLES) in err and "Traceback" not in err
    assert seconds < 30.0  # imports included; the estimate itself takes milliseconds
    assert not (tmp_path / "out").exists()


def test_far_via_estimate_names_the_path_samples() -> None:
    with pytest.raises(BudgetError) as info:
        _estimate(FAR_VIA, timed=False)
    assert info.value.move == 0 and info.value.cap == MAX_PATH_SAMPLES and info.value.value > 5e7


def test_sample_cap_counts_all_moves_together() -> None:
    """Three moves of ~4.1 M samples: the 10 M cap is crossed at move 2 (the issue's MemoryError)."""
    doc = _three_slow_lins(4.1e6)
    with pytest.raises(BudgetError) as info:
        _estimate(doc, budget_mb=math.inf)  # the sample cap alone
    assert info.value.move == 2 and info.value.cap == MAX_OUTPUT_SAMPLES
    assert 12.0e6 < info.value.value < 12.4e6
    assert "moves[2]" in str(info.value) and "output.period" in str(info.value)


def test_a_slow_ptp_is_told_to_raise_its_velocity_scale() -> None:
    """A PTP has no speed: the advice names its velocity_scale (the share of the joint limits)."""
    there, back = ([120, -20, 40, 90, -60, 150], START_DEG)
    ptps = [{"ptp": {"to": {"joints_deg": q}, "velocity_scale": 0.001}} for q in (there, back) * 8]  # 16 x 0.67 M
    with pytest.raises(BudgetError) as info:
        _estimate(_task(ptps, period=0.0005), budget_mb=math.inf)
    assert "raise output.period or moves[15]'s velocity_scale" in str(info.value), str(info.value)


@pytest.mark.slow  # singplan in a guarded subprocess
def test_memory_budget_names_the_move_where_it_is_crossed(tmp_path: Path) -> None:
    doc = _three_slow_lins(4.1e6)
    with pytest.raises(BudgetError) as info:
        _estimate(doc)
    assert info.value.move == 0  # 4.1 M samples alone are over 1.5 GB by the measured model
    assert info.value.value > TASK_MEMORY_MB == info.value.cap
    code, err, seconds = _guarded_cli(["plan", str(_write(tmp_path, doc)), "-o", str(tmp_path / "out")])
    assert code == 2 and "moves[0]" in err and "1500 MB" in err and seconds < 30.0, err


def test_a_task_just_under_the_caps_is_not_refused() -> None:
    under_cap = _estimate(_three_slow_lins(3.3e6), budget_mb=math.inf)
    assert 9.8e6 < under_cap.output_samples <= MAX_OUTPUT_SAMPLES
    fits = memory_mb(2_000_000, 200, 200) < TASK_MEMORY_MB  # the model's room, for the next line
    under_budget = _estimate(_three_slow_lins(0.6e6))
    assert fits and under_budget.output_samples <= under_budget.output_allowance


def test_timed_moves_are_checked_against_what_is_left(monkeypatch: pytest.MonkeyPatch) -> None:
    """The estimate is a lower bound; the exact count of each timed move is checked before allocating."""
    task = parse_task(_task([{"lin": {"to": {"xyz": LIN_TO}, "speed": 0.5}},
                             {"lin": {"to": {"xyz": LIN_BACK}, "speed": 0.5}}]))
    counts = _samples_per_move(task)
    allowance = sum(counts)  # the whole task has sum + 1 samples: one too many
    monkeypatch.setattr(planner, "check_task", lambda *args, **kwargs: TaskEstimate((), allowance))
    with pytest.raises(BudgetError) as info:
        plan(task)
    assert info.value.move == 1 and "moves[1]" in str(info.value)
    assert (info.value.value, info.value.cap) == (counts[1], counts[1] - 1)


def _samples_per_move(task: Task) -> list[int]:
    traj = plan(task)
    ends = [max(s.t1 for s in traj.segments if s.move == i) for i in range(len(task.moves))]
    starts = [0.0, *ends[:-1]]
    return [round((b - a) / task.period_s) for a, b in zip(starts, ends, strict=True)]


@pytest.mark.parametrize("moves", [
    [{"lin": {"to": {"xyz": LIN_TO}, "speed": 0.3}}],
    [{"circ": {"via": {"xyz": [0.5, 0.1, 0.5]}, "to": {"xyz": LIN_TO}, "speed": 0.2}}],
    [{"ptp": {"to": {"joints_deg": [30, -70, 90, 10, 50, 20]}, "velocity_scale": 0.5}},
     {"ptp": {"to": {"joints_deg": START_DEG}}}],
    [{"lin": {"to": {"xyz": LIN_TO}, "speed": 0.5}}, {"ptp": {"to": {"joints_deg": START_DEG}}},
     {"lin": {"to": {"xyz": LIN_BACK}}}],
])
def test_estimates_are_lower_bounds_of_the_planned_samples(moves: list[dict[str, Any]]) -> None:
    task = parse_task(_task(moves))
    robot = load_task_robot(task)
    estimate = estimate_moves(task, robot, np.radians(task.start_joints_deg), STEP_M, STEP_RAD)
    planned = _samples_per_move(task)
    for m, real in zip(estimate, planned, strict=True):
        assert 0 <= m.output_samples <= real, (m, real)
    assert any(m.output_samples > 0 for m in estimate)  # not vacuous
    timed_lin = [(m, real) for m, real in zip(estimate, planned, strict=True) if m.kind != "ptp"]
    assert all(m.output_samples >= 0.5 * real for m, real in timed_lin if m.length_m > 0.05)  # not vacuous


def test_chunked_build_ratios_equal_the_whole_array_ones(monkeypatch: pytest.MonkeyPatch) -> None:
    """The build's chunked ratios (bounded temporaries) give the same numbers (its differences:
    test_dynamics.test_central_differences_equal_the_record_formula_bit_for_bit)."""
    monkeypatch.setattr(trajectory_build, "_CHUNK", 7)
    rng = np.random.default_rng(1)
    vmax, amax = np.full(6, 1.0), np.full(6, 3.0)
    for n in (1, 2, 3, 8, 9, 51):
        q = rng.normal(size=(n, 6))
        assert trajectory_build._chunked_ratios(q, 0.004, vmax, amax) == sample_ratios(q, 0.004, vmax, amax)


def _one_slow_lin(samples: float, period: float) -> dict[str, Any]:
    """The LIN of bench/bench_memory.py (0.355 m), timed at about ``samples`` samples of ``period`` [s]."""
    return _task([{"lin": {"to": {"xyz": LIN_TO}, "speed": 0.355 / (samples * period)}}], period)


def test_the_budget_edge_is_where_the_model_reaches_the_budget() -> None:
    """One LIN: 3.3 M samples fit the 1.5 GB (bench_memory measured 3.4 M under it); 3.8 M do not."""
    fits = _estimate(_one_slow_lin(3.3e6, 0.0005))
    assert fits.output_samples <= fits.output_allowance < 3.6e6
    with pytest.raises(BudgetError) as info:
        _estimate(_one_slow_lin(3.8e6, 0.0005))
    assert info.value.move == 0 and info.value.cap == TASK_MEMORY_MB < info.value.value
    assert "MB" in str(info.value) and "output.period" in str(info.value)


@pytest.mark.slow  # 0.2 M samples with every output, in a subprocess whose peak RSS is measured
def test_the_model_bounds_the_measured_peak_with_every_output(tmp_path: Path) -> None:
    """plan with its default outputs (files, report, replay) on 0.2 M samples: the budget's estimate
    is an upper bound of the measured peak RSS, and the replay page stays small."""
    doc = _one_slow_lin(0.2e6, 0.001)
    estimate = _estimate(doc)
    out = tmp_path / "out"
    code, stderr, peak_mb = _measured_cli(["plan", str(_write(tmp_path, doc)), "-o", str(out), "--quiet"], tmp_path)
    model_mb = memory_mb(estimate.output_samples, max(m.path_samples for m in estimate.moves), estimate.path_samples)
    print(f"0.2 M samples, every output: peak {peak_mb:.0f} MB, model {model_mb:.0f} MB, "
          f"replay.html {(out / 'replay.html').stat().st_size / 1e6:.2f} MB")
    assert code == 0, stderr
    assert {"trajectory.json", "trajectory.csv", "report.html", "replay.html"} <= {p.name for p in out.iterdir()}
    assert peak_mb <= model_mb
    assert (out / "replay.html").stat().st_size < 5e6
