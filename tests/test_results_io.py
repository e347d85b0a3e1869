"""Lossless save / load of a planned trajectory, and its read-only arrays."""

from __future__ import annotations

import contextlib
import dataclasses
import re
import sys
from pathlib import Path

import numpy as np
import pytest

from singplan.outputs.report import report_html
from singplan.planning.orchestration.targets import load_task_robot
from singplan.results.plan import plan
from singplan.results.trajectory import Trajectory, load, save
from singplan.task.load import load_task

DEMO = Path(__file__).resolve().parent.parent / "singplan" / "demo_task.yaml"
# series the file holds in mm and deg: back to SI within the round-off of one conversion
CONVERTED = ("position_error_m", "orientation_error_rad", "distances")


@pytest.fixture(scope="module")
def planned(tmp_path_factory: pytest.TempPathFactory) -> tuple[Trajectory, Trajectory]:
    traj = plan(load_task(DEMO))
    return traj, load(save(traj, tmp_path_factory.mktemp("io")))


def test_load_gives_back_every_field_that_save_wrote(planned: tuple[Trajectory, Trajectory]) -> None:
    traj, back = planned
    assert traj.samples and traj.segments and traj.moves and traj.metrics.crossings
    for f in dataclasses.fields(Trajectory):
        before, after = getattr(traj, f.name), getattr(back, f.name)
        if f.name == "samples":
            assert after.keys() == before.keys()
            for name, series in before.items():
                if name in CONVERTED:
                    np.testing.assert_allclose(after[name], series, rtol=1e-15, atol=1e-300, err_msg=name)
                else:
                    np.testing.assert_array_equal(after[name], series, err_msg=name)
        elif isinstance(before, np.ndarray):
            np.testing.assert_array_equal(after, before, err_msg=f.name)
        else:
            assert after == before, f.name


def test_the_report_of_a_loaded_trajectory_is_the_report_of_the_planned_one(
        planned: tuple[Trajectory, Trajectory]) -> None:
    traj, back = planned
    robot = load_task_robot(load_task(DEMO))
    mpl = sys.modules.get("matplotlib")  # when the report draws with it: ids from the content, not random
    with mpl.rc_context({"svg.hashsalt": "singplan"}) if mpl is not None else contextlib.nullcontext():
        page, planned_page = report_html(back, robot), report_html(traj, robot)
    assert "<svg" in page and "stopping" in page.lower()
    assert _undated(page) == _undated(planned_page)


def _undated(page: str) -> str:
    """The page without the creation times matplotlib writes into each SVG (when it draws them)."""
    return re.sub(r"<dc:date>[^<]*</dc:date>", "", page)


def test_a_trajectory_s_arrays_are_read_only(planned: tuple[Trajectory, Trajectory]) -> None:
    for traj in planned:
        for name, values in [("t", traj.t), ("q", traj.q), ("qd", traj.qd), ("qdd", traj.qdd), *traj.samples.items()]:
            with pytest.raises(ValueError, match="read-only"):
                values[0] = 1.0
            assert not values.flags.writeable, name
