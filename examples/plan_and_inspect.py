# /// script
# requires-python = ">=3.10"
# dependencies = ["singplan"]
# ///
"""Plan an example task from Python and print what happened at each singular zone.

    python examples/plan_and_inspect.py [TASK.yaml]
"""

from __future__ import annotations

import sys
from pathlib import Path

import singplan
from singplan.results.metrics import Alternative, CrossingFigures


def _outcome(alt: Alternative) -> str:
    """A candidate planned and timed, not timed (it could not win: the least it can take), or infeasible."""
    if alt.feasible:
        return f"{alt.duration_s:.3f} s"
    if alt.feasible is None:
        return f">= {alt.at_least_s:.3f} s, {alt.reason}"  # the reason says why it was not timed
    return f"infeasible: {alt.reason}"


def main() -> int:
    task = Path(sys.argv[1]) if len(sys.argv) > 1 else Path(__file__).with_name("abb_near_miss_auto.yaml")
    traj = singplan.plan(task)
    print(f"{task.name}: {traj.duration_s:.3f} s, {len(traj.t)} samples")
    for seg in traj.segments:
        line = f"  move {seg.move} {seg.kind:9s} {seg.t0:7.3f} .. {seg.t1:7.3f} s"
        d = seg.details
        if isinstance(d, CrossingFigures):  # a crossing segment's figures
            line += (f"  {seg.singularity} via {seg.method}: {seg.config_before} -> {seg.config_after}, "
                     f"orientation dev {d.max_orientation_error_deg:.3f} deg, time lost {d.time_lost_s:.3f} s")
            for alt in d.alternatives:
                variant = f" ({alt.variant})" if alt.variant else ""
                line += f"\n      compared: {alt.method}{variant} " + _outcome(alt)
        print(line)
    return 0


if __name__ == "__main__":
    sys.exit(main())
