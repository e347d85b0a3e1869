"""Configuration labels and singular distances: sign changes are singularities."""

from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from singplan.errors import TaskError
from singplan.kinematics.configuration import (
    LABEL_ZERO,
    Configuration,
    classify,
    distances_batch,
    label_and_distances,
    labels_batch,
    labels_from_distances,
    parse_configuration,
    positive_sides,
    singularity_distances,
)
from singplan.kinematics.ik.solve import solve_all
from singplan.kinematics.robot import load_robot

from .conftest import OPW_NAMES

ROBOT_NAMES = [*OPW_NAMES, "ur5"]
_ROBOTS = {name: load_robot(name) for name in ROBOT_NAMES}


def test_parse_and_format() -> None:
    assert parse_configuration("F U N") == Configuration("F", "U", "N")
    assert parse_configuration("bdf").label == "B D F"
    with pytest.raises(TaskError, match=r"shoulder F\|B"):
        parse_configuration("X U N", "moves[0].lin.config")


def test_distances_vanish_at_the_classic_singular_poses() -> None:
    robot = _ROBOTS["abb_irb2400"]
    q = np.radians([20.0, 10.0, 15.0, 30.0, 0.0, 10.0])
    assert abs(singularity_distances(robot, q).wrist_rad) < 1e-12
    kuka = _ROBOTS["kuka_kr6_r900_2"]
    d = singularity_distances(kuka, np.radians([10.0, -90.0, 90.0, 0.0, 30.0, 0.0]))
    assert d.shoulder_m > 0.4 and d.elbow_rad > 0 and d.wrist_rad > 0  # home: front, up, no flip


def _bisect(f, a: float, b: float, fa: float) -> float:
    for _ in range(60):
        m = 0.5 * (a + b)
        fm = f(m)
        if (fm >= 0) == (fa >= 0):
            a, fa = m, fm
        else:
            b = m
    return 0.5 * (a + b)


@settings(max_examples=40, deadline=None)
@given(name=st.sampled_from(ROBOT_NAMES), seed=st.integers(0, 2**32 - 1))
def test_labels_flip_exactly_where_distances_change_sign_and_the_jacobian_drops_rank(name: str, seed: int) -> None:
    """Along a random straight joint-space segment, every label flip sits where its distance changes
    side (its sign, read by the one rule: on the singularity within LABEL_ZERO counts as positive),
    and the bisected sign change is a real singularity (sigma_min ~ 0)."""
    robot = _ROBOTS[name]
    rng = np.random.default_rng(seed)
    lo, hi = np.maximum(robot.lower_rad, -np.pi), np.minimum(robot.upper_rad, np.pi)
    qa, qb = rng.uniform(lo, hi), rng.uniform(lo, hi)

    def at(s: float) -> np.ndarray:
        return qa + s * (qb - qa)

    ss = np.linspace(0.0, 1.0, 241)
    rows = [label_and_distances(robot, at(s)) for s in ss]
    for k in range(len(ss) - 1):
        (c0, d0), (c1, d1) = rows[k], rows[k + 1]
        for part, dist_index, letters in (("shoulder", 1, "FB"), ("elbow", 2, "UD"), ("wrist", 0, "NF")):
            flipped = getattr(c0, part) != getattr(c1, part)
            side0, side1 = (bool(positive_sides(np.array(d[:3]))[dist_index]) for d in (d0, d1))
            assert flipped == (side0 != side1)
            assert getattr(c0, part) == letters[0 if side0 else 1]
            if flipped and (d0[dist_index] >= 0) != (d1[dist_index] >= 0):  # through the singularity
                root = _bisect(lambda s, i=dist_index: singularity_distances(robot, at(s))[i],
                               float(ss[k]), float(ss[k + 1]), d0[dist_index])
                sigma = singularity_distances(robot, at(root)).sigma_min
                assert sigma < 1e-6, f"{part} label flips at s={root} where sigma_min={sigma}"
            elif flipped:  # past the rule's margin: the positive side's end is within it of the singularity
                on_it = d0[dist_index] if side0 else d1[dist_index]
                assert -LABEL_ZERO <= on_it < 0 or (dist_index != 1 and on_it <= -math.pi + LABEL_ZERO)


@pytest.mark.parametrize("name", [*OPW_NAMES, "ur5"])
def test_closed_form_distances_equal_the_frame_based_ones(name: str) -> None:
    robot = _ROBOTS[name]
    rng = np.random.default_rng(7)
    q = rng.uniform(np.maximum(robot.lower_rad, -np.pi), np.minimum(robot.upper_rad, np.pi), size=(300, 6))
    frames = np.array([singularity_distances(robot, qk)[:3] for qk in q])
    np.testing.assert_allclose(distances_batch(robot, q), frames, atol=1e-12)
    assert labels_from_distances(distances_batch(robot, q)) == [classify(robot, qk).label for qk in q]


def test_classify_matches_label_and_distances() -> None:
    robot = _ROBOTS["fanuc_lrmate200id"]
    q = np.radians([5.0, 10.0, -20.0, 40.0, -35.0, 10.0])
    label, d = label_and_distances(robot, q)
    assert label == classify(robot, q)
    assert math.isclose(abs(d.wrist_rad), math.radians(35.0), abs_tol=1e-9)  # angle between axes 4 and 6


def _boundary_rows(robot, rng: np.random.Generator, n: int) -> np.ndarray:
    """n random joint vectors, most put on or within round-off of a singularity or of a label
    boundary (LABEL_ZERO from it): the wrist at q5 = 0 or +-pi (exactly, or 1e-17 .. 1e-9 off, or
    +-LABEL_ZERO and that off), the elbow stretched, the wrist point on axis 1 (distance 0 or
    -LABEL_ZERO, found by bisection, then 1e-17 .. 1e-9 off)."""
    lo, hi = np.maximum(robot.lower_rad, -2 * np.pi), np.minimum(robot.upper_rad, 2 * np.pi)
    q = rng.uniform(lo, hi, size=(n, robot.n_joints))
    offsets = np.array([0.0, 1e-17, -1e-17, 1e-13, -1e-13, 1e-9, -1e-9])
    wrist = slice(0, n // 3)
    q[wrist, 4] = (rng.choice([0.0, math.pi, -math.pi], n // 3) + rng.choice(offsets, n // 3)
                   + rng.choice([0.0, LABEL_ZERO, -LABEL_ZERO], n // 3))
    for column, rows in ((2, slice(n // 3, 2 * n // 3)), (1, slice(2 * n // 3, n - n // 10))):
        for level, half in ((0.0, slice(0, None, 2)), (-LABEL_ZERO, slice(1, None, 2))):
            q[rows][half] = _zero_of(robot, q[rows][half], column, 2 if column == 2 else 1, level)
        q[rows, column] += rng.choice(offsets, len(q[rows]))
    return q


def _zero_of(robot, q: np.ndarray, joint: int, distance: int, level: float = 0.0) -> np.ndarray:
    """q with ``joint`` moved (bisection, to round-off) where ``distance`` (elbow 2, shoulder 1) crosses ``level``."""
    grid = np.linspace(-math.pi, math.pi, 73)
    out = q.copy()
    for k, row in enumerate(q):
        trial = np.repeat(row[None], len(grid), axis=0)
        trial[:, joint] = grid
        d = distances_batch(robot, trial)[:, distance] - level
        flips = np.flatnonzero((np.sign(d[:-1]) != np.sign(d[1:])) & (np.abs(np.diff(d)) < 1.0))
        if not len(flips):
            continue
        a, b = grid[flips[0]], grid[flips[0] + 1]
        da = d[flips[0]]
        for _ in range(60):
            mid = 0.5 * (a + b)
            row_mid = row.copy()
            row_mid[joint] = mid
            dm = distances_batch(robot, row_mid)[0, distance] - level
            a, b, da = (mid, b, dm) if np.sign(dm) == np.sign(da) else (a, mid, da)
        out[k, joint] = a
    return out


@pytest.mark.parametrize("name", ["abb_irb2400", "kuka_kr6_r900_2", "fanuc_lrmate200id", "staubli_tx2_60", "ur5",
                                  "so100", "panda"])
def test_labels_batch_equals_classify_row_by_row_at_the_boundaries(name: str) -> None:
    robot = load_robot(name)
    rng = np.random.default_rng(20261123)
    q = _boundary_rows(robot, rng, 600)
    d = distances_batch(robot, q)
    expected = [classify(robot, qk).label for qk in q]
    assert labels_batch(robot, q) == expected
    if robot.family in ("opw", "ur"):  # the rows did reach the boundaries, where the closed forms alone disagree
        assert labels_from_distances(d) != expected
        assert np.sum(np.min(np.minimum(np.abs(d), np.abs(np.abs(d) - LABEL_ZERO)), axis=1) < 1e-9) > 100


@pytest.mark.parametrize("name", ["abb_irb2400", "ur5"])
def test_ik_solutions_of_singular_poses_carry_classify_s_labels(name: str) -> None:
    robot = load_robot(name)
    rng = np.random.default_rng(7)
    q = [qk for qk in _boundary_rows(robot, rng, 60) if robot.within_limits(qk)]  # the bisection ignores limits
    assert len(q) >= 20
    for qk in q:
        sols = solve_all(robot, robot.fk(qk))
        assert len(sols) > 0
        assert list(sols.labels) == [classify(robot, row).label for row in sols.q]
