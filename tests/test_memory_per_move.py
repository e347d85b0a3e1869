"""Memory of long programs (issue 24): what a plan needs beyond its trajectory record does not grow per move.

A program of N wrist-crossing LINs (auto: several candidates a move, one of them refused with an
error) is planned with :mod:`tracemalloc` tracing every allocation. The whole-trajectory stages
work a chunk of samples at a time; their chunks are made small here so that on these short
programs they are already at their cap, and what is left to grow with N is what a plan keeps per
move beyond the record, or a temporary the size of the whole trajectory. ``bench/bench_program.py``
measures the same on 1000 moves (docs/benchmarks.md).
"""

from __future__ import annotations

import gc
import tracemalloc
from typing import Any, NamedTuple

import numpy as np
import pinocchio as pin
import pytest

from singplan.kinematics import clearance, dynamics, stopping
from singplan.kinematics.robot import load_robot
from singplan.planning.orchestration import rows
from singplan.planning.orchestration.planner import PlannedTask, plan_moves
from singplan.results import build
from singplan.results import plan as plan_module
from singplan.results.build import MoveReports
from singplan.task.load import parse_task
from singplan.task.schema import Task

START_DEG = [34.466047735, -69.193961827, 100.109975431, 68.691762951, -14.064499937, -11.872434380]
ACROSS = {"xyz": [0.703837, -0.107362, 0.658022], "rpy_deg": [-121.329770, 35.631042, -129.525465]}
# What the plan may hold beyond its record per move, at its peak [bytes], the blocks rows wait in
# counted (here heap arrays: tracemalloc does not see memory maps). Measured on this program (313
# samples a move): about 5.9 kB (each move's samples' path parameters, 2.5 kB, and what the final
# gate's messages need of it, both kept until the gate has passed); with the moves kept whole until
# the record was built, about 14 kB without the blocks; at commit 6c7c391 about 250 kB (each move's
# samples copied again, whole-trajectory temporaries, the refused candidates' errors holding their
# frames until the cyclic collector ran).
PER_MOVE_BYTES = 9_000
# What the planned task keeps per move beyond its samples and the record's per-sample series [bytes]:
# about 11 kB (the record's parts of each move, ~5 kB: segments, events, crossing reports; the
# samples' path parameters; what the gate's messages need). With the moves kept whole until the
# record was built, about 25 kB, their deviation series (the record's series now) included.
KEPT_PER_MOVE_BYTES = 15_000


def _program(moves: int) -> Task:
    """``moves`` LINs back and forth across the KUKA's wrist zone (bench/bench_program.py's program)."""
    robot = load_robot("kuka_kr6_r900_2", tool=pin.SE3(np.eye(3), np.array([0.0, 0.0, 0.1])))
    T0 = robot.fk(np.radians(START_DEG))
    start = {"xyz": T0.translation.tolist(), "rpy_deg": np.degrees(pin.rpy.matrixToRpy(T0.rotation)).tolist()}
    return parse_task({
        "robot": "kuka_kr6_r900_2", "tool": {"xyz": [0, 0, 0.1]}, "start": {"joints_deg": START_DEG},
        "moves": [{"lin": {"to": ACROSS if k % 2 == 0 else start, "speed": 0.25}} for k in range(moves)],
        "singularity": {"method": "auto", "orientation_tolerance_deg": 1.0, "position_tolerance_mm": 0.01},
        "limits": {"acceleration": 10.0}, "output": {"period": 0.004}})


class Measured(NamedTuple):
    over_record: int  # the traced peak of plan() once the moves are planned, over the record it returns [bytes]
    kept: int  # what the planned task holds beyond its samples (PlannedTask.q) and the record's series [bytes]


def _measured(moves: int, monkeypatch: pytest.MonkeyPatch) -> Measured:
    """:func:`singplan.results.plan.plan` traced; its peak counted from the moves planned (planning's
    own peak, loading the task's robot, is the same for any program)."""
    kept: list[int] = []

    def planned_moves(*args: Any) -> PlannedTask:
        planned = plan_moves(*args)
        assert isinstance(planned.sink, MoveReports)
        series = [planned.sink.position_m, planned.sink.orientation_rad, planned.sink.tcp_ratio, planned.sink.distances]
        rows = sum(b[:n].nbytes for store in series for b, n in zip(store.blocks, store.filled, strict=True))
        kept.append(tracemalloc.get_traced_memory()[0] - base - planned.q.nbytes - rows)
        tracemalloc.reset_peak()  # from here: the record built from the planned moves
        return planned

    monkeypatch.setattr(plan_module, "plan_moves", planned_moves)
    # the blocks rows wait in as heap arrays, which tracemalloc sees (memory maps it does not)
    monkeypatch.setattr(rows, "_block", np.empty)
    task = _program(moves)
    gc.collect()
    tracemalloc.start()
    try:
        base = tracemalloc.get_traced_memory()[0]
        traj = plan_module.plan(task)
        peak = tracemalloc.get_traced_memory()[1]
        gc.collect()
        record = tracemalloc.get_traced_memory()[0]
    finally:
        tracemalloc.stop()
    assert len(traj.moves) == moves
    return Measured(peak - record, kept[0])


@pytest.fixture
def small_chunks(monkeypatch: pytest.MonkeyPatch) -> None:
    """The whole-trajectory stages' chunks at a few hundred samples (results unchanged: they work sample by sample)."""
    for module, name, value in [(build, "_CHUNK", 256), (dynamics, "_DIFFERENCES_CHUNK", 256),
                                (stopping, "_CHUNK_VALUES", 20_000), (stopping, "_CHUNK_ROWS", 256),
                                (clearance, "BLOCK", 256), (rows, "BLOCK_ROWS", 256)]:
        monkeypatch.setattr(module, name, value)


def test_what_a_plan_needs_beyond_its_record_grows_little_per_move(small_chunks: None,
                                                                   monkeypatch: pytest.MonkeyPatch) -> None:
    plan_module.plan(_program(2))  # caches filled once (robot, kernels)
    small, large = _measured(6, monkeypatch), _measured(24, monkeypatch)
    per_move = (large.over_record - small.over_record) / 18
    assert per_move < PER_MOVE_BYTES, (f"the peak over the record grows {per_move / 1e3:.1f} kB a move "
                                       f"({small.over_record / 1e6:.1f} MB at 6 moves, "
                                       f"{large.over_record / 1e6:.1f} MB at 24)")
    kept_per_move = (large.kept - small.kept) / 18
    assert kept_per_move < KEPT_PER_MOVE_BYTES, f"the planned moves keep {kept_per_move / 1e3:.1f} kB each"


def test_planning_leaves_no_cycles_holding_a_moves_candidates() -> None:
    """A refused candidate's error is kept for its message; its traceback would hold the frames that
    planned the move (every candidate's joint map and TOPP-RA spline) in a cycle that only the
    cyclic collector frees, late: on long programs tens of MB at a time."""
    task = _program(3)
    gc.collect()
    gc.disable()
    flags = gc.get_debug()
    try:
        planned = plan_moves(task)
        gc.set_debug(gc.DEBUG_SAVEALL)
        gc.collect()
        kept: list[Any] = [o for o in gc.garbage if type(o).__module__.startswith("singplan")]
    finally:
        gc.set_debug(flags)
        gc.garbage.clear()
        gc.enable()
    assert len(planned.moves) == 3
    assert not kept, sorted({type(o).__name__ for o in kept})
