"""planning.path.tracking on its own: the nearest candidate against a brute force over every candidate
and whole-turn shift, and a tracked LIN against every branch solve_all lists at each sample (the tracked
joints reproduce the pose and are the branch nearest the previous sample, brute force)."""

from __future__ import annotations

import itertools
import math

import numpy as np
import pinocchio as pin
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from hypothesis.extra.numpy import arrays

from singplan.kinematics.ik.solve import solve_all
from singplan.kinematics.robot import load_robot
from singplan.planning.path.cartesian import make_lin
from singplan.planning.path.tracking import nearest_candidate, track

TURN = 2.0 * math.pi


def _shifted_toward(c: np.ndarray, ref: np.ndarray) -> np.ndarray:
    """Each joint of c moved by the whole turn (-3..3) that brings it nearest ref, tried one by one."""
    return np.array([min((cj + k * TURN for k in range(-3, 4)), key=lambda x, r=rj: abs(x - r))
                     for cj, rj in zip(c, ref, strict=True)])


@settings(max_examples=80, deadline=None, derandomize=True)
@given(st.integers(1, 8).flatmap(lambda b: arrays(float, (b, 4), elements=st.floats(-9.0, 9.0))),
       arrays(float, 4, elements=st.floats(-6.0, 6.0)))
def test_the_nearest_candidate_is_the_brute_force_nearest_over_rows_and_turns(candidates: np.ndarray,
                                                                              q_prev: np.ndarray) -> None:
    best, dist = nearest_candidate(candidates, q_prev)
    shifted = [_shifted_toward(c, q_prev) for c in candidates]
    distances = [float(np.max(np.abs(s - q_prev))) for s in shifted]
    assert dist == pytest.approx(min(distances), abs=1e-12)
    assert np.max(np.abs(best - q_prev)) == pytest.approx(dist, abs=1e-12)
    # the answer is one of the candidates up to whole turns
    assert any(np.allclose(np.round((best - c) / TURN) * TURN, best - c, atol=1e-9) for c in candidates)


def test_no_finite_candidate_is_infinitely_far() -> None:
    best, dist = nearest_candidate(np.full((2, 3), np.nan), np.zeros(3))
    assert dist == math.inf and np.all(np.isnan(best))
    best, dist = nearest_candidate(np.empty((0, 3)), np.zeros(3))
    assert dist == math.inf


@pytest.mark.parametrize(("name", "q_start_deg", "shift_m"), [
    ("abb_irb2400", [10, 20, 15, 40, 50, -30], [0.05, -0.25, -0.15]),
    ("ur5", [20, -80, 100, -60, -80, 30], [-0.1, 0.1, -0.1]),
])
def test_a_tracked_lin_is_the_nearest_of_all_branches_at_every_sample(name: str, q_start_deg: list[float],
                                                                       shift_m: list[float]) -> None:
    robot = load_robot(name)
    q_start = np.radians(q_start_deg)
    T0 = robot.fk(q_start)
    T1 = pin.SE3(T0.rotation @ pin.exp3(np.array([0.2, -0.1, 0.3])), T0.translation + np.array(shift_m))
    piece = make_lin(T0, T1, "m")
    tracked = track(robot, piece.poses, piece.grid(0.01, math.radians(3.0)), q_start)
    assert tracked.gap_index == -1 and tracked.max_step_rad <= math.radians(1.0)
    assert len(tracked.u) > 10 and np.all(np.diff(tracked.u) > 0)
    np.testing.assert_allclose(tracked.q[0], q_start, atol=1e-9)
    poses = piece.poses(tracked.u)
    checked = itertools.islice(range(1, len(tracked.u)), 0, None, max(1, len(tracked.u) // 40))  # ~40 samples
    for k in checked:
        T = pin.SE3(poses[k][:3, :3], poses[k][:3, 3])
        reached = robot.fk(tracked.q[k])
        assert np.linalg.norm(reached.translation - T.translation) < 1e-9
        assert np.linalg.norm(pin.log3(reached.rotation.T @ T.rotation)) < 1e-9
        # every branch (solve_all also lists whole-turn variants: one each once moved toward the previous sample)
        moved = np.unique(np.round([_shifted_toward(b, tracked.q[k - 1]) for b in solve_all(robot, T).q], 9), axis=0)
        steps = [float(np.max(np.abs(b - tracked.q[k - 1]))) for b in moved]
        taken = float(np.max(np.abs(tracked.q[k] - tracked.q[k - 1])))
        assert taken == pytest.approx(min(steps), abs=1e-9)  # no branch is nearer the previous sample
        assert sorted(steps)[1] > 10.0 * taken  # and the next one is far away: no singularity on this path
