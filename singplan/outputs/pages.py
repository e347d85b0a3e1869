"""The HTML pages of a planned trajectory (report and replay), built after a successful plan.

A page that cannot be built (e.g. a visual mesh is missing) is a warning: the plan stands,
the trajectory files are written, and the caller says which page was left out and why.
"""

from __future__ import annotations

from singplan.errors import SingplanError
from singplan.kinematics.robot import Robot
from singplan.outputs.report import report_html
from singplan.outputs.viewer import replay_html
from singplan.results.trajectory import Trajectory


def build_pages(traj: Trajectory, robot: Robot, report: bool, replay: bool) -> tuple[dict[str, str], dict[str, str]]:
    """The pages asked for ({file name: html}) and why any could not be built ({file name: reason})."""
    builders = {"report.html": (report, report_html), "replay.html": (replay, replay_html)}
    pages, skipped = {}, {}
    for name, (wanted, build) in builders.items():
        if not wanted:
            continue
        try:
            pages[name] = build(traj, robot)
        except Exception as exc:  # a page that cannot be built loses that page only, never the trajectory
            skipped[name] = str(exc) if isinstance(exc, SingplanError) else f"{type(exc).__name__}: {exc}"
    return pages, skipped
