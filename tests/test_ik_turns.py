"""solve_all's whole-turn variants and labels (compiled, singplan.kinematics.ik.turns) against a
plain reference: every variant by itertools, the nearest one joint by joint, repeats dropped by
pairwise np.allclose, each row labelled by the frame-based classify; and against
py-opw-kinematics' branches. Seeded random poses on OPW and UR arms."""

from __future__ import annotations

import itertools
import math

import numpy as np
import pytest
from py_opw_kinematics import KinematicModel
from py_opw_kinematics import Robot as OpwRobot

from singplan.kinematics.angles import TWO_PI, wrap_to_pi
from singplan.kinematics.configuration import classify
from singplan.kinematics.ik import turns
from singplan.kinematics.ik.solve import closed_form_branches, solve_all
from singplan.kinematics.robot import Robot

from .conftest import random_q


def _variants(q: np.ndarray, lower: np.ndarray, upper: np.ndarray) -> list[np.ndarray]:
    options = []
    for j, value in enumerate(q):
        k_lo = math.ceil((lower[j] - value) / TWO_PI - 1e-12)
        k_hi = math.floor((upper[j] - value) / TWO_PI + 1e-12)
        options.append([value + TWO_PI * k for k in range(k_lo, k_hi + 1)])
    return [np.array(v) for v in itertools.product(*options)]


def _nearest(q: np.ndarray, seed: np.ndarray, lower: np.ndarray, upper: np.ndarray) -> np.ndarray | None:
    out = np.empty_like(q)
    for j, value in enumerate(q):
        k0 = round((seed[j] - value) / TWO_PI)
        candidates = [value + TWO_PI * k for k in (k0 - 1, k0, k0 + 1)
                      if lower[j] - 1e-9 <= value + TWO_PI * k <= upper[j] + 1e-9]
        if not candidates:
            return None
        out[j] = candidates[int(np.argmin(np.abs(np.array(candidates) - seed[j])))]
    return np.clip(out, lower, upper)


def _distinct(rows: list[np.ndarray]) -> list[int]:
    """The rows not np.allclose (rtol 1e-5, atol 1e-9) to an earlier kept one, each against all kept at once."""
    table = np.array(rows).reshape(len(rows), -1)
    kept: list[int] = []
    for k, row in enumerate(table):
        earlier = table[kept]
        if not np.any(np.all(np.abs(row - earlier) <= 1e-9 + 1e-5 * np.abs(earlier), axis=1)):
            kept.append(k)
    return kept


def _reference(robot: Robot, T: np.ndarray, seed: np.ndarray | None) -> tuple[np.ndarray, list[str], list[int]]:
    """solve_all as a plain loop: (q (M, n), labels, branches)."""
    found = []
    branches = closed_form_branches(robot, T[None], None if seed is None else seed[None])[0]
    for b, q in enumerate(branches):
        if not np.all(np.isfinite(q)):
            continue
        rows = ([_nearest(q, seed, robot.lower_rad, robot.upper_rad)] if seed is not None
                else _variants(q, robot.lower_rad, robot.upper_rad))
        found += [(row, b) for row in rows if row is not None]
    kept = _distinct([row for row, _ in found])
    q_all = np.array([found[k][0] for k in kept]).reshape(-1, robot.n_joints)
    return q_all, [classify(robot, q).label for q in q_all], [found[k][1] for k in kept]


@pytest.mark.parametrize(("name", "count"), [("kuka_kr6_r900_2", 400), ("abb_irb2400", 400),
                                             ("staubli_tx2_60", 200), ("ur5", 60)])
def test_rows_branches_and_labels_equal_the_plain_reference(name: str, count: int, robots, rng) -> None:
    robot = robots[name]
    for q in random_q(robot, rng, count):
        T = robot.fk(q)
        seed = q + rng.normal(0.0, 0.3, robot.n_joints)
        for s in (None, seed):
            ours = solve_all(robot, T, seed=s)
            q_ref, labels, branches = _reference(robot, T.homogeneous, s)
            np.testing.assert_array_equal(ours.q, q_ref)
            assert list(ours.branches) == branches
            assert list(ours.labels) == labels


@pytest.mark.parametrize("name", ["kuka_kr6_r900_2", "fanuc_lrmate200id", "staubli_tx2_60"])
def test_the_rows_are_py_opw_kinematics_branches_shifted_into_the_limits(name: str, robots, rng) -> None:
    robot = robots[name]
    p = robot.opw
    assert p is not None
    ref = OpwRobot(KinematicModel(a1=p.a1, a2=p.a2, b=p.b, c1=p.c1, c2=p.c2, c3=p.c3, c4=p.c4,
                                  offsets=tuple(p.offsets_rad), flip_axes=tuple(s < 0 for s in p.sign_corrections)),
                   degrees=False)
    for q in random_q(robot, rng, 200):
        theirs = np.array(ref.inverse(ref.forward(tuple(q))))  # (B, 6), within (-pi, pi]
        inside = [t for t in theirs if _variants(t, robot.lower_rad, robot.upper_rad)]
        ours = solve_all(robot, robot.fk(q))
        for row in ours.q:  # every row is one of theirs, whole turns apart
            assert np.min(np.abs(wrap_to_pi(theirs - row)).max(axis=1)) < 1e-9
        for t in inside:  # every one of theirs the limits allow is there
            assert np.min(np.abs(wrap_to_pi(ours.q - t)).max(axis=1)) < 1e-9
        assert len(ours) == sum(len(_variants(t, robot.lower_rad, robot.upper_rad)) for t in inside)


def test_repeats_are_dropped_as_pairwise_allclose_does_even_where_shifts_cancel_in_the_key() -> None:
    """Rows near each other (within and just outside the tolerance), and whole-turn shifts of two
    joints in opposite directions: the kept rows are those of the pairwise rule, in order."""
    rng = np.random.default_rng(11)
    base = rng.uniform(-3.0, 3.0, (40, 6))
    shifted = base.copy()
    shifted[:, 0] += TWO_PI
    shifted[:, 1] -= TWO_PI
    scale = 1e-9 + 1e-5 * np.abs(base)
    near = base + scale * rng.choice([-0.5, 0.999, 1.01, 3.0], size=base.shape)
    rows = np.concatenate([base, shifted, near, base[::-1]])[rng.permutation(160)]
    np.testing.assert_array_equal(turns._distinct(rows), _distinct(list(rows)))
