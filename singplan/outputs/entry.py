"""The one entry to planning: :func:`plan` (a task to a :class:`Trajectory`), :func:`plan_into` (a
task planned into an output folder: the pipeline ``singplan plan`` and each batch task run) and
:func:`detect` (what ``singplan check`` reports). The command line, the batch runner and the
public names of ``singplan`` all come through here; nothing above the planning stages reaches
into :mod:`singplan.planning` itself (an import-linter contract in pyproject.toml).

In :func:`plan_into` the folder is checked and held before planning (nobody waits for a plan that cannot be written,
and no second run writes there meanwhile: :func:`~singplan.results.files.hold_output_folder`), the
task is planned once, the pages are built on the robot the plan loaded, and every file is
written by the rules of :mod:`singplan.results.files` (DESIGN.md, "Outputs"). The names of
singplan's files live with their writers (:mod:`singplan.results.trajectory`,
:mod:`singplan.outputs.pages`); :data:`OUTPUT_FILES` is all of them.
"""

from __future__ import annotations

import os
from collections.abc import Callable, Mapping
from dataclasses import dataclass
from pathlib import Path

from singplan.outputs.pages import PAGE_FILES, build_pages, page_names
from singplan.results.detect import MoveZones as MoveZones  # what detect() returns
from singplan.results.detect import detect as detect  # the public name singplan.detect
from singplan.results.files import hold_output_folder
from singplan.results.plan import Progress, planned_trajectory
from singplan.results.plan import plan as plan  # the public name singplan.plan: a task to a Trajectory
from singplan.results.trajectory import ROBOT_FILES, TRAJECTORY_FILES, Trajectory, robot_files, save
from singplan.task.schema import Task

# every file singplan may write into a task's output folder
OUTPUT_FILES = (*TRAJECTORY_FILES, *ROBOT_FILES, *PAGE_FILES)


def output_names(report: bool, replay: bool) -> tuple[str, ...]:
    """The files a plan may write: the trajectory's, the robot's copy (a URDF with continuous joints),
    then the pages asked for."""
    return (*TRAJECTORY_FILES, *ROBOT_FILES, *page_names(report, replay))


@dataclass(frozen=True)
class PlannedFolder:
    """A task planned and written: the trajectory, the folder (absolute), the files written in it
    (in order) and the pages that could not be built ({file name: reason})."""

    traj: Trajectory
    folder: Path
    files: tuple[str, ...]
    skipped: Mapping[str, str]


def plan_into(task: Task, out_dir: str | os.PathLike[str], *, method: str | None = None, report: bool = True,
              replay: bool = True, progress: Progress | None = None,
              before_planning: Callable[[], None] | None = None) -> PlannedFolder:
    """Plan ``task`` and write its files into ``out_dir``; a page that cannot be built is only skipped.

    ``before_planning`` runs once the folder was found usable, just before planning starts.

    Raises:
        OutputPathError: ``out_dir`` cannot receive the files, or another run is writing there
            (checked before planning, and the folder held until the files are written; exit code 2).
        InputError, PlanningError: as :func:`plan`; the folder is left as it was.
    """
    with hold_output_folder(out_dir, output_names(report, replay)) as folder:  # one run per folder, from here
        if before_planning is not None:
            before_planning()
        traj, robot = planned_trajectory(task, method=method, progress=progress)
        pages, skipped = build_pages(traj, robot, report=report, replay=replay)  # the robot the plan loaded
        written = save(traj, folder, extra_files=pages)
    return PlannedFolder(traj, written, (*TRAJECTORY_FILES, *robot_files(traj), *pages), skipped)
