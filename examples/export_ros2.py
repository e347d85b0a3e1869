# /// script
# requires-python = ">=3.10"
# dependencies = ["singplan"]
# ///
"""Plan a task and hand it to ROS 2: a trajectory_msgs/JointTrajectory as YAML, plus the vendor
configuration data at the end of every move.

    python examples/export_ros2.py [TASK.yaml] [OUT]

then, with a joint trajectory controller running:

    ros2 topic pub --once /joint_trajectory_controller/joint_trajectory \\
        trajectory_msgs/msg/JointTrajectory "$(cat OUT/trajectory.ros2.yaml)"
"""

from __future__ import annotations

import sys
from pathlib import Path

import singplan
from singplan.outputs import exports
from singplan.results.trajectory import load


def main() -> int:
    task = Path(sys.argv[1]) if len(sys.argv) > 1 else Path(__file__).with_name("kuka_program.yaml")
    out = Path(sys.argv[2]) if len(sys.argv) > 2 else Path("singplan-export")
    singplan.save(singplan.plan(task), out)
    traj = load(out)  # the same as the plan; an export needs only the folder
    written = exports.export(traj, "ros2", out / exports.DEFAULT_FILE_NAMES["ros2"])
    print(f"{task.name}: {len(traj.t)} points, {traj.duration_s:.3f} s -> {written}")
    for move in traj.moves:
        print(f"  move {move.move} ({move.kind}) ends at {move.t1:.3f} s in {move.config_end}: {move.vendor_config}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
