"""Configuration labels and singular distances: sign changes are singularities."""

from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from singplan.errors import TaskError
from singplan.kinematics.configuration import (
    Configuration,
    classify,
    distances_batch,
    label_and_distances,
    labels_from_distances,
    parse_configuration,
    singularity_distances,
)
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
    """Along a random straight joint-space segment, every label flip sits at a sign change of
    its distance, and the bisected sign change is a real singularity (sigma_min ~ 0)."""
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
            sign_changed = (d0[dist_index] >= 0) != (d1[dist_index] >= 0)
            assert flipped == sign_changed
            assert getattr(c0, part) == letters[0 if d0[dist_index] >= 0 else 1]
            if flipped:
                root = _bisect(lambda s, i=dist_index: singularity_distances(robot, at(s))[i],
                               float(ss[k]), float(ss[k + 1]), d0[dist_index])
                sigma = singularity_distances(robot, at(root)).sigma_min
                assert sigma < 1e-6, f"{part} label flips at s={root} where sigma_min={sigma}"


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
