"""planning.path.zones on its own: zones found from sampled distances against a brute-force scan written
from the definition (maximal runs under the threshold, entry and exit interpolated linearly, closest
sample, kept only when it comes within SINGULAR_REACH), the refinement of the closest point against an
analytic minimum, and the batched distances against the geometric ones computed one pose at a time."""

from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from hypothesis.extra.numpy import arrays

from singplan.kinematics.configuration import singularity_distances
from singplan.kinematics.robot import load_robot
from singplan.planning.path.zones import KINDS, SINGULAR_REACH, Zone, distances_along, find_zones

# wrist [rad], shoulder [m], elbow [rad]: wider than SINGULAR_REACH, so that runs further off are left out
THRESHOLDS = np.array([math.radians(20.0), 0.1, math.radians(20.0)])


def _brute_force(u: np.ndarray, dist: np.ndarray, thresholds: np.ndarray) -> list[Zone]:
    """Each kind's runs of samples with |d| < threshold, scanned one sample at a time."""
    zones = []
    for i, kind in enumerate(KINDS):
        d, thr = np.abs(dist[:, i]), thresholds[i]
        k = 0
        while k < len(u):
            if d[k] >= thr:
                k += 1
                continue
            start = k
            while k < len(u) and d[k] < thr:
                k += 1
            end = k - 1

            def cross(a: int, b: int, d: np.ndarray = d, thr: float = thr) -> float:
                if d[a] == d[b]:
                    return float(u[a])
                return float(u[a] + min(1.0, max(0.0, (thr - d[a]) / (d[b] - d[a]))) * (u[b] - u[a]))

            entry = 0.0 if start == 0 else cross(start - 1, start)
            exit_ = 1.0 if end == len(u) - 1 else cross(end, end + 1)
            closest = min(range(start, end + 1), key=lambda j, d=d: (d[j], j))
            if d[closest] < SINGULAR_REACH[kind]:
                zones.append(Zone(kind, entry, exit_, float(u[closest]), float(d[closest]), float(thr)))
    return sorted(zones, key=lambda z: z.u_entry)


@settings(max_examples=80, deadline=None, derandomize=True)
@given(st.integers(2, 40).flatmap(lambda n: arrays(float, (n, 3), elements=st.floats(-0.4, 0.4))))
def test_zones_are_the_runs_a_sample_by_sample_scan_finds(dist: np.ndarray) -> None:
    u = np.linspace(0.0, 1.0, len(dist))
    found = find_zones(u, dist, THRESHOLDS)
    expected = _brute_force(u, dist, THRESHOLDS)
    assert sorted(found, key=lambda z: (z.u_entry, z.kind)) == sorted(expected, key=lambda z: (z.u_entry, z.kind))
    for z in found:
        assert 0.0 <= z.u_entry <= z.u_closest <= z.u_exit <= 1.0 and z.min_distance < z.threshold


def test_a_zone_open_at_the_start_of_a_continued_stretch_is_kept_and_not_refined() -> None:
    u = np.linspace(0.0, 1.0, 11)
    dist = np.full((11, 3), 1.0)
    dist[:3, 0] = [0.2, 0.21, 0.24]  # under the threshold from the start, never within SINGULAR_REACH (10 deg)
    assert find_zones(u, dist, np.array([0.25, 0.05, 0.25])) == []

    def never(x: np.ndarray, index: int) -> np.ndarray:
        raise AssertionError("a continued zone is not refined again")

    zones = find_zones(u, dist, np.array([0.25, 0.05, 0.25]), never, continued="wrist")
    assert [(z.kind, z.u_entry, z.u_closest) for z in zones] == [("wrist", 0.0, 0.0)]


@pytest.mark.parametrize("u_star", [0.3137, 0.5, 0.0512])
def test_the_closest_point_is_refined_to_the_true_minimum_between_samples(u_star: float) -> None:
    """|d(u)| = 3 |u - u*| + 0.001 (rad): sampled every 0.02, the minimum lies between samples."""
    u = np.linspace(0.0, 1.0, 51)

    def abs_distance(x: np.ndarray, index: int) -> np.ndarray:
        return 3.0 * np.abs(x - u_star) + 0.001

    dist = np.column_stack([abs_distance(u, 0), np.ones(51), np.ones(51)])
    (zone,) = find_zones(u, dist, THRESHOLDS, abs_distance)
    # 17 points in 4 rounds narrow two sample intervals (0.04) 8^4-fold
    assert abs(zone.u_closest - u_star) <= 0.04 / 8**3
    assert zone.min_distance == pytest.approx(0.001, abs=3.0 * 0.04 / 8**3)
    half = (THRESHOLDS[0] - 0.001) / 3.0  # linear on each side: the interpolated entry and exit are exact
    assert zone.u_entry == pytest.approx(max(u_star - half, 0.0), abs=1e-12)
    assert zone.u_exit == pytest.approx(u_star + half, abs=1e-12)


@pytest.mark.parametrize("name", ["abb_irb2400", "ur5"])
def test_batched_distances_are_the_geometric_ones_pose_by_pose(name: str, rng: np.random.Generator) -> None:
    robot = load_robot(name)
    lo, hi = np.maximum(robot.lower_rad, -np.pi), np.minimum(robot.upper_rad, np.pi)
    q = rng.uniform(lo, hi, size=(8, robot.n_joints))
    d, labels = distances_along(robot, q)
    for k in range(len(q)):
        one = singularity_distances(robot, q[k])
        np.testing.assert_allclose(d[k], [one.wrist_rad, one.shoulder_m, one.elbow_rad], atol=1e-9)
        assert labels[k].replace(" ", "") == "".join(
            (pos if v >= 0 else neg) for v, pos, neg in ((one.shoulder_m, "F", "B"), (one.elbow_rad, "U", "D"),
                                                         (one.wrist_rad, "N", "F")))
