"""Each move handed to the record's sink as it is decided (issue 24's memory): the record is the same
as the one built from the moves kept whole to the end, bit for bit; the blocks the rows wait in."""

from __future__ import annotations

import gc
import weakref
from pathlib import Path

import numpy as np
import pytest
import yaml

from singplan.planning.orchestration import rows
from singplan.planning.orchestration.planner import PlannedMove, TimedMove, plan_moves
from singplan.planning.orchestration.rows import RowStore
from singplan.results.build import MoveReports
from singplan.results.plan import plan, trajectory_of
from singplan.results.trajectory import Trajectory
from singplan.task.load import load_task, parse_task

ROOT = Path(__file__).resolve().parents[1]
# no fly-by (each move handed over as it is planned): LIN, CIRC, PTP; wrist crossings with auto;
# fly-by corners (handed over once the corners are settled)
TASKS = ["kuka_program.yaml", "kuka_long_program.yaml", "flyby_pick_place.yaml"]


def _same(a: Trajectory, b: Trajectory) -> None:
    for name in ("t", "q", "qd", "qdd"):
        assert np.array_equal(getattr(a, name), getattr(b, name)), name
    assert a.samples.keys() == b.samples.keys()
    for name, values in a.samples.items():
        assert np.array_equal(values, b.samples[name], equal_nan=True), name
    assert a.segments == b.segments and a.events == b.events and a.moves == b.moves
    ja, jb = a.metrics.to_json(), b.metrics.to_json()
    ja.pop("planning_time_s"), jb.pop("planning_time_s")
    assert ja == jb


@pytest.mark.parametrize("name", TASKS)
def test_the_record_of_moves_handed_over_as_planned_is_the_record_of_moves_kept_whole(name: str) -> None:
    task = load_task(ROOT / "examples" / name)
    whole = plan_moves(task)
    assert whole.sink is None and any(pm.deviations is not None or pm.jmap.parts for pm in whole.moves)  # whole
    _same(plan(task), trajectory_of(whole))


def test_a_planned_task_handed_over_keeps_each_move_only_for_messages() -> None:
    task = load_task(ROOT / "examples" / "kuka_long_program.yaml")
    planned = plan_moves(task, None, None, MoveReports)
    assert isinstance(planned.sink, MoveReports)
    assert planned.sink.samples == len(planned.q)
    assert all(pm.deviations is None and not pm.zones and not pm.crossings for pm in planned.moves)
    k0 = 0
    for tm in planned.timed:  # every move's samples a view of the stitched ones
        assert np.shares_memory(tm.q, planned.q) and np.array_equal(tm.q, planned.q[k0:k0 + len(tm.q)])
        k0 += len(tm.q) - 1


def test_rows_kept_in_blocks_come_back_in_order_bit_for_bit(monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setattr(rows, "BLOCK_ROWS", 7)  # several blocks, and a move longer than a block
    rng = np.random.default_rng(3)
    parts = [rng.standard_normal((k, 3)) for k in (3, 4, 1, 12, 5)]
    store = RowStore((3,))
    views = [store.kept(p) for p in parts]
    assert all(np.array_equal(v, p) for v, p in zip(views, parts, strict=True))
    assert len(store.blocks) == 4  # 3 + 4 fill one; 1 starts the next; 12 gets one of its own; 5 the last
    block = weakref.ref(store.blocks[0].base.base if store.blocks[0].base is not None else store.blocks[0])
    del views
    stitched = store.stitched()
    assert np.array_equal(stitched, np.concatenate(parts)) and not store.blocks
    gc.collect()
    assert block() is None  # the stitched rows are a copy: the blocks are given back
    assert RowStore().stitched().shape == (0,)


def test_every_reported_time_is_a_sample_time_whatever_the_period() -> None:
    """A period whose decimal form is too long for exact times over the whole trajectory: its times
    are the plain products, and so are those of the moves whose own samples alone had exact ones."""
    mapping = yaml.safe_load((ROOT / "examples" / "kuka_long_program.yaml").read_text())
    mapping.setdefault("output", {})["period"] = 0.006000000000123
    task = parse_task(mapping)
    traj = plan(task)
    _same(traj, trajectory_of(plan_moves(task)))
    times = [*(t for s in traj.segments for t in (s.t0, s.t1)), *(e.t for e in traj.events),
             *(t for c in traj.metrics.crossings for t in (c.t0, c.t1))]
    assert times and all(t == traj.t[round(t / traj.period)] for t in times)


def test_a_record_built_twice_from_moves_handed_over_is_the_same() -> None:
    planned = plan_moves(load_task(ROOT / "examples" / "kuka_program.yaml"), None, None, MoveReports)
    _same(trajectory_of(planned), trajectory_of(planned))


class _Counting:
    def __init__(self, *_: object) -> None:
        self.moves = 0

    def take(self, pm: PlannedMove, tm: TimedMove, nxt: PlannedMove | None, blend: object) -> None:
        self.moves += 1


def test_moves_handed_to_another_sink_give_no_trajectory_here() -> None:
    planned = plan_moves(load_task(ROOT / "examples" / "kuka_program.yaml"), None, None, _Counting)
    assert isinstance(planned.sink, _Counting) and planned.sink.moves == 3
    with pytest.raises(TypeError, match="_Counting"):
        trajectory_of(planned)
