"""One task planned into an output folder: the pipeline `singplan plan` and each batch task run.

The folder is checked and held before planning (nobody waits for a plan that cannot be written,
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

from singplan.outputs.choices import DEFAULT_FILE_NAMES
from singplan.outputs.pages import PAGE_FILES, build_pages, page_names
from singplan.planning.orchestration.planner import Progress, plan_moves
from singplan.results.files import hold_output_folder
from singplan.results.plan import trajectory_of
from singplan.results.trajectory import ROBOT_FILES, TRAJECTORY_FILES, Trajectory, robot_files, save
from singplan.task.schema import Task

# every file singplan may write into a task's output folder
OUTPUT_FILES = (*TRAJECTORY_FILES, *ROBOT_FILES, *PAGE_FILES)
# ... and those `singplan export` writes there by default
EXPORT_FILES = tuple(DEFAULT_FILE_NAMES.values())


def output_names(report: bool, replay: bool) -> tuple[str, ...]:
    """The files a plan may write: the trajectory's, the robot's copy (a URDF with continuous joints),
    then the pages asked for."""
    return (*TRAJECTORY_FILES, *ROBOT_FILES, *page_names(report, replay))


@dataclass(frozen=True)
class PlannedFolder:
    """A task planned and written: the trajectory, the folder (absolute), the files written in it
    (in order), the pages that could not be built ({file name: reason}) and singplan's files of an
    earlier run left in the folder, which do not show this plan (``-o`` only adds or replaces)."""

    traj: Trajectory
    folder: Path
    files: tuple[str, ...]
    skipped: Mapping[str, str]
    stale: tuple[str, ...] = ()


def plan_into(task: Task, out_dir: str | os.PathLike[str], *, method: str | None = None, report: bool = True,
              replay: bool = True, progress: Progress | None = None,
              before_planning: Callable[[], None] | None = None) -> PlannedFolder:
    """Plan ``task`` and write its files into ``out_dir``; a page that cannot be built is only skipped.

    ``before_planning`` runs once the folder was found usable, just before planning starts.

    Raises:
        OutputPathError: ``out_dir`` cannot receive the files, or another run is writing there
            (checked before planning, and the folder held until the files are written; exit code 2).
        InputError, PlanningError: as :func:`singplan.results.plan.plan`; the folder is left as it was.
    """
    with hold_output_folder(out_dir, output_names(report, replay)) as folder:  # one run per folder, from here
        if before_planning is not None:
            before_planning()
        planned = plan_moves(task, method=method, progress=progress)
        traj = trajectory_of(planned)
        pages, skipped = build_pages(traj, planned.full, report=report, replay=replay)  # the robot the plan loaded
        written = save(traj, folder, extra_files=pages)
    files = (*TRAJECTORY_FILES, *robot_files(traj), *pages)
    return PlannedFolder(traj, written, files, skipped, _stale(written, files))


def _stale(folder: Path, written: tuple[str, ...]) -> tuple[str, ...]:
    """singplan's own files in ``folder`` that this run did not write (a page it was told not to
    build, an earlier export): they show an earlier plan."""
    return tuple(name for name in (*OUTPUT_FILES, *EXPORT_FILES)
                 if name not in written and (folder / name).is_file())
