"""planning.timing.trace on its own: the TCP's own travel along a joint map that leaves its path, against
chords measured with Pinocchio's forward kinematics pose by pose (each step the longer of the path's
advance and the TCP's chord), and no trace where every part keeps to the path."""

from __future__ import annotations

import numpy as np
import pinocchio as pin
import pytest

from singplan.kinematics.robot import load_robot
from singplan.planning.path.cartesian import make_lin
from singplan.planning.path.jointmap import JointMap, JointPart
from singplan.planning.path.tracking import track
from singplan.planning.timing.trace import tcp_trace

ROBOT = load_robot("abb_irb2400")


def _lin_with_a_joint_line() -> tuple[JointMap, float]:
    """A LIN tracked exactly, with its middle fifth replaced by a straight joint line (off the path)."""
    q0 = np.radians([10, 20, 15, 40, 50, -30])
    T0 = ROBOT.fk(q0)
    piece = make_lin(T0, pin.SE3(T0.rotation, T0.translation + np.array([0.0, -0.3, -0.1])), "m")
    tracked = track(ROBOT, piece.poses, piece.grid(0.01, 0.05), q0)
    u, q = tracked.u, tracked.q
    a, b = int(np.searchsorted(u, 0.4)), int(np.searchsorted(u, 0.6))
    parts = [JointPart("track", u[:a + 1], q[:a + 1]), JointPart("ptp", u[[a, b]], q[[a, b]]),
             JointPart("track", u[b:], q[b:])]
    return JointMap(ROBOT, piece.poses, parts), piece.length_m


def test_the_trace_is_the_longer_of_the_paths_advance_and_the_tcps_chord_step_by_step() -> None:
    jmap, length_m = _lin_with_a_joint_line()
    trace = tcp_trace(jmap, length_m)
    assert trace is not None
    assert trace.u[0] == 0.0 and trace.u[-1] == 1.0 and np.all(np.diff(trace.u) > 0) and trace.s_m[0] == 0.0
    q = jmap.evaluate(trace.u)
    chords = np.array([np.linalg.norm(ROBOT.fk(q[k + 1]).translation - ROBOT.fk(q[k]).translation)
                       for k in range(len(q) - 1)])
    np.testing.assert_allclose(np.diff(trace.s_m), np.maximum(np.diff(trace.u) * length_m, chords), rtol=1e-9,
                               atol=1e-15)
    # a joint line leaves the straight path: its TCP travels further than the path there
    assert trace.s_m[-1] > length_m * (1 + 1e-6)
    inside = (trace.u > 0.4) & (trace.u < 0.6)
    assert np.count_nonzero(inside) >= 64  # the part off the path sampled densely
    assert trace.at(np.array([0.0, 1.0]))[1] == pytest.approx(trace.s_m[-1])


def test_no_trace_where_the_map_keeps_to_its_path_or_has_none() -> None:
    jmap, length_m = _lin_with_a_joint_line()
    on_path = JointMap(ROBOT, jmap.poses, [jmap.parts[0], JointPart("track", *_joined(jmap.parts[1:]))])
    assert tcp_trace(on_path, length_m) is None  # no part leaves the path
    assert tcp_trace(jmap, 0.0) is None  # a pure reorientation: no TCP speed to cap
    ptp = JointMap(ROBOT, None, [jmap.parts[1]])
    assert tcp_trace(ptp, length_m) is None  # a PTP has no path


def _joined(parts: list[JointPart]) -> tuple[np.ndarray, np.ndarray]:
    u = np.concatenate([parts[0].u, *(p.u[1:] for p in parts[1:])])
    q = np.concatenate([parts[0].q, *(p.q[1:] for p in parts[1:])])
    return u, q
