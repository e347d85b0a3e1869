"""The HTML pages of a planned trajectory (report and replay), built after a successful plan.

A page that cannot be built (e.g. a visual mesh is missing) is a warning: the plan stands,
the trajectory files are written, and the caller says which page was left out and why.

Each page's module is imported when that page is built: the report needs matplotlib and the
replay meshcat (with Pinocchio's visualisers and trimesh), together about 1.5 s of start-up
that a plan written without pages does not pay. That is for start-up time, not an import cycle.
"""

from __future__ import annotations

from collections.abc import Callable

from singplan.errors import SingplanError
from singplan.kinematics.robot import Robot
from singplan.results.trajectory import Trajectory


def build_pages(traj: Trajectory, robot: Robot, report: bool, replay: bool) -> tuple[dict[str, str], dict[str, str]]:
    """The pages asked for ({file name: html}) and why any could not be built ({file name: reason})."""
    pages, skipped = {}, {}
    for name, wanted in (("report.html", report), ("replay.html", replay)):
        if not wanted:
            continue
        try:
            pages[name] = _builder(name)(traj, robot)
        except Exception as exc:  # a page that cannot be built loses that page only, never the trajectory
            skipped[name] = str(exc) if isinstance(exc, SingplanError) else f"{type(exc).__name__}: {exc}"
    return pages, skipped


def _builder(name: str) -> Callable[[Trajectory, Robot], str]:
    if name == "report.html":
        from singplan.outputs.report import report_html

        return report_html
    from singplan.outputs.viewer import replay_html

    return replay_html
