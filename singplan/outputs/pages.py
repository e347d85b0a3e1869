"""The HTML pages of a planned trajectory (report and replay), built after a successful plan.

A page that cannot be built (e.g. a visual mesh is missing) is a warning: the plan stands,
the trajectory files are written, and the caller says which page was left out and why.

The replay's module is imported when that page is built: it needs meshcat with Pinocchio's
visualisers and trimesh, about 1 s of start-up that a plan written without it does not pay
(the report's module is light but follows the same rule). That is for start-up time, not an
import cycle.
"""

from __future__ import annotations

from collections.abc import Callable, Mapping
from dataclasses import dataclass
from pathlib import Path

from singplan.errors import SingplanError
from singplan.kinematics.robot import Robot
from singplan.outputs.timeline import PageBasis, page_basis
from singplan.results.trajectory import Trajectory

REPORT_FILE = "report.html"
REPLAY_FILE = "replay.html"
PAGE_FILES = (REPORT_FILE, REPLAY_FILE)


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


def page_names(report: bool, replay: bool) -> tuple[str, ...]:
    """The file names of the pages asked for, in the order they are built and written."""
    return tuple(name for name, asked in zip(PAGE_FILES, (report, replay), strict=True) if asked)


def build_pages(traj: Trajectory, robot: Robot, report: bool, replay: bool) -> tuple[dict[str, str], dict[str, str]]:
    """The pages asked for ({file name: html}) and why any could not be built ({file name: reason}).

    What both pages draw (:class:`~singplan.outputs.timeline.PageBasis`: forward kinematics of every
    sample, the timeline, the joint speeds) is computed once and shared.
    """
    pages: dict[str, str] = {}
    skipped: dict[str, str] = {}
    wanted = page_names(report, replay)
    if not wanted:
        return pages, skipped
    try:
        basis = page_basis(traj, robot)
    except Exception as exc:  # no page then, but the trajectory stands
        return {}, dict.fromkeys(wanted, _reason(exc))
    for name in wanted:
        try:
            pages[name] = _builder(name)(traj, robot, basis)
        except Exception as exc:  # a page that cannot be built loses that page only, never the trajectory
            skipped[name] = _reason(exc)
    return pages, skipped


def _reason(exc: Exception) -> str:
    return str(exc) if isinstance(exc, SingplanError) else f"{type(exc).__name__}: {exc}"


def _builder(name: str) -> Callable[[Trajectory, Robot, PageBasis], str]:
    if name == REPORT_FILE:
        from singplan.outputs.report import report_html

        return report_html
    from singplan.outputs.viewer import replay_html

    return replay_html
