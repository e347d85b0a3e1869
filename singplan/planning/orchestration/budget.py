"""Bounded work and memory: what a task will cost, estimated before anything large is allocated.

DESIGN.md caps a task at 10 000 000 output samples (all moves together) and at about 600 MB
per million output samples and 1.5 GB in all; more is bad input, refused up front. The
estimate is cheap (no IK, no sampling): per move, the number of path samples the planner's
initial grid will hold (from the LIN / CIRC length and rotation) and a LOWER bound of its
output samples (a LIN / CIRC takes at least length / speed; a PTP with joint targets at least
max_j |dq_j| / v_j). A lower bound never refuses a task that fits; the exact sample count of
each timed move is checked again against what is left of the task's allowance before its
samples are allocated (:func:`~singplan.planning.timing.records.check_move_samples`, called by the timing).

The memory model is measured, not derived (bench/bench_memory.py, docs/benchmarks.md):
peak RSS ~ base + output samples x per-output-sample + (largest move's path samples) x
per-path-sample while planning it + (all path samples) x per-path-sample kept.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from singplan.errors import BudgetError
from singplan.kinematics.robot import Robot
from singplan.planning.path.cartesian import move_target
from singplan.planning.path.pieces import move_piece
from singplan.task.schema import MAX_OUTPUT_SAMPLES, TASK_MEMORY_MB, Move, Task

# Peak RSS of a short task (interpreter, numpy, pinocchio, numba kernels, TOPP-RA): 388 MB; of a
# 0.1 M-sample one 449-450 MB whatever the outputs (the chunked evaluation's fixed ~60 MB of
# temporaries). bench/bench_memory.py, 2026-11-23, AMD EPYC, 2 cores (docs/benchmarks.md): 450 MB.
BASE_MB = 450.0
# Peak RSS growth per million output samples of `singplan plan` with its default outputs (trajectory
# files written streaming, report.html, replay.html), same benchmark: 688 MB at 1 M, 965 MB at 2 M and
# 1386 MB at 3.4 M samples, 284 MB a million above the 0.1 M figure (291 between 1 M and 3.4 M); the
# files alone took 1277 MB at 3.4 M, so the report and the bounded replay add 30-110 MB. 300 keeps
# every measured peak under the model (by 30-90 MB), so the budget's edge (3.5 M samples) is under 1.5 GB.
OUTPUT_MB_PER_MILLION = 300.0
# Peak RSS growth per path sample while one move is planned (tracking candidates, TOPP-RA's grid of
# the reference samples): 4.7 kB measured on a 0.355 m LIN sampled at 4 um (88 750 samples), rounded up.
PATH_KB_PER_SAMPLE_PLANNING = 5.0
# What each path sample keeps until the trajectory is built (the joint map's reference u and q,
# zones, crossings): a rough upper figure of 0.2 kB (u + q = 56 bytes, plus the parts' copies).
PATH_KB_PER_SAMPLE_KEPT = 0.2
# A bound of work rather than memory: path samples over all moves (about 20 us of IK and detection
# each, so ~100 s of geometry at the cap). 10 000 moves of 0.9 m at the 2 mm step stay under it.
MAX_PATH_SAMPLES = 5_000_000


@dataclass(frozen=True)
class MoveEstimate:
    """What one move will cost, from its geometry and limits alone."""

    index: int
    kind: str
    path_samples: int  # the planner's initial grid (LIN / CIRC), 0 for PTP
    output_samples: int  # a lower bound of the periods the move lasts
    length_m: float


@dataclass(frozen=True)
class TaskEstimate:
    """The moves' estimates and the task's allowance of output samples."""

    moves: tuple[MoveEstimate, ...]
    output_allowance: int  # output samples the task may produce in all (memory and cap)

    @property
    def output_samples(self) -> int:
        return 1 + sum(m.output_samples for m in self.moves)

    @property
    def path_samples(self) -> int:
        return sum(m.path_samples for m in self.moves)


def memory_mb(output_samples: int, path_samples_largest_move: int, path_samples: int) -> float:
    """The model's peak RSS [MB] of a task (see the module docstring)."""
    return (BASE_MB + output_samples * OUTPUT_MB_PER_MILLION / 1e6
            + path_samples_largest_move * PATH_KB_PER_SAMPLE_PLANNING / 1e3
            + path_samples * PATH_KB_PER_SAMPLE_KEPT / 1e3)


def estimate_moves(task: Task, robot: Robot, q_start: np.ndarray, step_m: float, step_rad: float) -> list[MoveEstimate]:
    """Per move: path samples at the planner's steps [m], [rad] and a lower bound of output samples."""
    T = robot.fk(q_start)
    q: np.ndarray | None = np.asarray(q_start, dtype=float)  # the joints, while they are known
    out = []
    for i, move in enumerate(task.moves):
        if move.kind == "ptp":
            samples = 0
            if move.to_joints_deg is not None:
                q_to = np.radians(np.asarray(move.to_joints_deg, dtype=float))
                if q is not None:
                    samples = _ptp_samples(task, robot, move, q, q_to)
                q, T = q_to, robot.fk(q_to)
            else:
                q, T = None, move_target(move, T)
            out.append(MoveEstimate(i, "ptp", 0, samples, 0.0))
            continue
        piece = move_piece(i, move, T)
        periods = piece.length_m / move.speed_m_s / task.period_s
        out.append(MoveEstimate(i, move.kind, piece.sample_count(step_m, step_rad) + 1, _whole(periods),
                                piece.length_m))
        q, T = None, piece.T_end
    return out


def check_task(task: Task, robot: Robot, q_start: np.ndarray, step_m: float, step_rad: float,
               timed: bool = True, budget_mb: float = TASK_MEMORY_MB,
               max_output_samples: int = MAX_OUTPUT_SAMPLES) -> TaskEstimate:
    """Refuse (BudgetError) a task whose estimate crosses a cap; else its output-sample allowance.

    ``timed=False`` (``singplan check``): output samples are not made, only paths are sampled.
    The error names the first move at which the running total crosses a cap.
    """
    moves = estimate_moves(task, robot, q_start, step_m, step_rad)
    out_total, path_total, path_largest = 1, 0, 0
    for m in moves:
        out_total += m.output_samples if timed else 0
        path_total += m.path_samples
        path_largest = max(path_largest, m.path_samples)
        _check_path(m, path_total)
        _check_output(task, m, out_total, max_output_samples)
        used = memory_mb(out_total, path_largest, path_total)
        if used > budget_mb:
            raise BudgetError(f"moves[{m.index}]", f"{_figures(task, m, out_total, path_total, timed)} would take "
                              f"about {used:.0f} MB, over the budget of {budget_mb:.0f} MB; {_advice(m, timed)}",
                              m.index, used, budget_mb)
    spare_mb = budget_mb - memory_mb(0, path_largest, path_total)
    allowance = int(min(max_output_samples, spare_mb * 1e6 / OUTPUT_MB_PER_MILLION))
    return TaskEstimate(tuple(moves), allowance)


def _check_path(m: MoveEstimate, path_total: int) -> None:
    if path_total <= MAX_PATH_SAMPLES:
        return
    raise BudgetError(f"moves[{m.index}].{m.kind}", f"the path up to move {m.index} ({m.length_m:.1f} m in this "
                      f"move) needs {path_total} path samples in all, over the cap of {MAX_PATH_SAMPLES}; "
                      f"{_advice(m, False)}", m.index, path_total, MAX_PATH_SAMPLES)


def _check_output(task: Task, m: MoveEstimate, out_total: int, cap: int) -> None:
    if out_total <= cap:
        return
    raise BudgetError(f"moves[{m.index}]", f"the task needs at least {out_total} output samples up to move "
                      f"{m.index} (this move: {m.output_samples} at {task.period_s:g} s), over the cap of {cap} "
                      f"for all moves together; {_advice(m, True)}", m.index, out_total, cap)


def _figures(task: Task, m: MoveEstimate, out_total: int, path_total: int, timed: bool) -> str:
    outputs = f"at least {out_total} output samples at {task.period_s:g} s and " if timed else ""
    return (f"up to move {m.index} ({m.kind}, {m.length_m:.1f} m, {m.path_samples} path samples) the task's "
            f"{outputs}{path_total} path samples")


def _advice(m: MoveEstimate, timed: bool) -> str:
    geometry = "bring the move's targets (and a CIRC's via) closer or split the move"
    if not timed or m.output_samples == 0:
        return geometry
    speed = "velocity_scale" if m.kind == "ptp" else "speed"  # a PTP is timed by its share of the joint limits
    return f"raise output.period or moves[{m.index}]'s {speed}, split the task, or {geometry}"


def _whole(periods: float) -> int:
    """Whole periods that a duration of at least ``periods`` periods takes, saturating at 1e15
    (a speed of 1e-300 m/s still gives a number); the 1e-6 margin covers TOP-RA's rounding."""
    return int(min(math.floor(periods * (1.0 - 1e-6)), 1e15)) if math.isfinite(periods) else 10**15


def _ptp_samples(task: Task, robot: Robot, move: Move, q_from: np.ndarray, q_to: np.ndarray) -> int:
    v_rad_s = robot.velocity_rad_s * task.joint_speed_scale(move)
    return _whole(float(np.max(np.abs(q_to - q_from) / v_rad_s)) / task.period_s)


