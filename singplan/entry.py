"""The one entry to planning: :func:`plan` (a task to a :class:`Trajectory`), :func:`plan_into` (a
task planned into an output folder: the pipeline ``singplan plan`` and each batch task run),
:func:`detect` (what ``singplan check`` reports), tasks read with their crossing method's name
checked (:func:`load_task`, :func:`parse_task`) and the crossing methods by name
(:func:`method_names`, :func:`check_method_name`, :func:`method_uses`). The command line, the
batch runner and the public names of ``singplan`` all come through here; nothing above it reaches
into :mod:`singplan.planning` itself (import-linter contracts in pyproject.toml: this module is
its own layer, between batch and outputs).

In :func:`plan_into` the folder is checked and held before planning (nobody waits for a plan that cannot be written,
and no second run writes there meanwhile: :func:`~singplan.results.files.hold_output_folder`), the
task is planned once, the pages are built on the robot the plan loaded, and every file is
written by the rules of :mod:`singplan.results.files` (DESIGN.md, "Outputs"). The names of
singplan's files live with their writers (:mod:`singplan.results.trajectory`,
:mod:`singplan.outputs.pages`); :data:`OUTPUT_FILES` is all of them.
"""

from __future__ import annotations

import os
from collections.abc import Callable
from pathlib import Path
from typing import Any, NamedTuple

from singplan.kinematics.robot import Robot
from singplan.outputs.choices import DEFAULT_FILE_NAMES
from singplan.outputs.pages import PAGE_FILES, PlannedFolder, build_pages, page_names
from singplan.planning.crossing import registry
from singplan.planning.crossing.registry import check_name as check_method_name  # a method name, or bad input
from singplan.planning.crossing.registry import names as method_names  # auto, built-in, registered
from singplan.results.detect import MoveZones as MoveZones  # what detect() returns
from singplan.results.detect import detect as detect  # the public name singplan.detect
from singplan.results.files import hold_output_folder
from singplan.results.plan import Progress, planned_trajectory
from singplan.results.plan import plan as plan  # the public name singplan.plan: a task to a Trajectory
from singplan.results.trajectory import ROBOT_FILES, TRAJECTORY_FILES, robot_files, save
from singplan.task import load as task_load
from singplan.task.schema import Task

# every file singplan may write into a task's output folder
OUTPUT_FILES = (*TRAJECTORY_FILES, *ROBOT_FILES, *PAGE_FILES)
# ... and those `singplan export` writes there by default
EXPORT_FILES = tuple(DEFAULT_FILE_NAMES.values())


class MethodUse(NamedTuple):
    """Whether a crossing method serves an arm (``singplan info``): ``note`` says why not, or how
    it serves where that differs by arm ("" otherwise)."""

    method: str
    applies: bool
    note: str


def method_uses(robot: Robot) -> list[MethodUse]:
    """Every crossing method name (:func:`method_names`) and whether it serves ``robot``."""
    refused, notes = registry.refusals(robot.recognition), registry.notes(robot.recognition)
    return [MethodUse(m, m not in refused, refused.get(m, notes.get(m, ""))) for m in method_names()]


def load_task(path: str | Path) -> Task:
    """Read and validate a task file (:func:`singplan.task.load.load_task`), its crossing method
    name included (the registry's: a registered method's name is accepted).

    Raises:
        TaskError: the file or a field is bad input, named (exit code 2).
    """
    return _named_method(task_load.load_task(path))


def parse_task(doc: Any, base_dir: Path | None = None) -> Task:
    """Validate a task mapping (:func:`singplan.task.load.parse_task`), its crossing method name included."""
    return _named_method(task_load.parse_task(doc, base_dir))


def _named_method(task: Task) -> Task:
    check_method_name("singularity.method", task.singularity.method)
    return task


def output_names(report: bool, replay: bool) -> tuple[str, ...]:
    """The files a plan may write: the trajectory's, the robot's copy (a URDF with continuous joints),
    then the pages asked for."""
    return (*TRAJECTORY_FILES, *ROBOT_FILES, *page_names(report, replay))


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
    check_method_name("singularity.method", task.singularity.method)  # bad input before the folder is touched
    if method is not None:
        check_method_name("method", method)
    with hold_output_folder(out_dir, output_names(report, replay)) as folder:  # one run per folder, from here
        if before_planning is not None:
            before_planning()
        traj, robot = planned_trajectory(task, method=method, progress=progress)
        pages, skipped = build_pages(traj, robot, report=report, replay=replay)  # the robot the plan loaded
        copies = robot_files(traj)  # the URDF read and converted once, for the files and their names
        folder = save(traj, folder, extra_files=pages, robot_copies=copies)
    files = (*TRAJECTORY_FILES, *copies, *pages)
    return PlannedFolder(traj, folder, files, skipped, _stale(folder, files))


def _stale(folder: Path, written: tuple[str, ...]) -> tuple[str, ...]:
    """singplan's own files in ``folder`` that this run did not write (a page it was told not to
    build, an earlier export): they show an earlier plan."""
    return tuple(name for name in (*OUTPUT_FILES, *EXPORT_FILES)
                 if name not in written and (folder / name).is_file())
