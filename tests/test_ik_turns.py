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
from singplan.kinematics.configuration import LABEL_ZERO, classify, distances_batch
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
    q_all, labels, branches, _ = _reference_and_repeats(robot, T, seed)
    return q_all, labels, branches


def _reference_and_repeats(robot: Robot, T: np.ndarray,
                           seed: np.ndarray | None) -> tuple[np.ndarray, list[str], list[int], tuple[int, int]]:
    """:func:`_reference` and how many rows it dropped: as repeats (allclose), as the same up to whole turns."""
    found = []
    branches = closed_form_branches(robot, T[None], None if seed is None else seed[None])[0]
    for b, q in enumerate(branches):
        if not np.all(np.isfinite(q)):
            continue
        rows = ([_nearest(q, seed, robot.lower_rad, robot.upper_rad)] if seed is not None
                else _variants(q, robot.lower_rad, robot.upper_rad))
        found += [(row, b) for row in rows if row is not None]
    distinct = kept = _distinct([row for row, _ in found])
    if seed is not None:
        kept = _one_per_turn([found[k][0] for k in distinct], distinct, seed)
    q_all = np.array([found[k][0] for k in kept]).reshape(-1, robot.n_joints)
    dropped = (len(found) - len(distinct), len(distinct) - len(kept))
    return q_all, [classify(robot, q).label for q in q_all], [found[k][1] for k in kept], dropped


def _one_per_turn(rows: list[np.ndarray], index: list[int], seed: np.ndarray) -> list[int]:
    """Of rows equal up to whole turns within LABEL_ZERO in every joint (branches meeting on a
    singular pose), the one nearest the seed (max norm; the first among equals), in the first's place."""
    kept: list[tuple[np.ndarray, int]] = []
    for row, k in zip(rows, index, strict=True):
        same = [i for i, (other, _) in enumerate(kept) if np.all(np.abs(wrap_to_pi(row - other)) <= LABEL_ZERO)]
        if not same:
            kept.append((row, k))
        elif np.max(np.abs(row - seed)) < np.max(np.abs(kept[same[0]][0] - seed)):
            kept[same[0]] = (row, k)
    return [k for _, k in kept]


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


# distances on and around where a label changes: on the singularity, at LABEL_ZERO (the label's own
# threshold), at 10 LABEL_ZERO (where labels_batch classifies a row on its own) and just past it, and
# angles near +-pi (where the wrapped value jumps); an elbow 1e-7 or 2e-6 from stretched has two branches
# equal up to LABEL_ZERO but not to allclose
_BOUNDARY_DISTANCES = [0.0, 1e-12, -1e-12, 1e-7, 2e-6, LABEL_ZERO, -LABEL_ZERO, 1.0001 * LABEL_ZERO,
                       -1.0001 * LABEL_ZERO, 1e-4, -1e-4, 1.001e-4, -1.001e-4, 1.02e-4, -1.02e-4,
                       math.pi - 1e-5, -math.pi + 1e-5, math.pi - 1.02e-4, -math.pi + 1.02e-4]


def _on_boundary(robot: Robot, q: np.ndarray, kind: int, distance: float) -> np.ndarray | None:
    """q with its wrist (kind 0) or elbow (kind 2) distance set to ``distance`` by joint 5 or 3,
    moved by whole turns into the limits (None where no turn fits)."""
    q = q.copy()
    j = 4 if kind == 0 else 2
    p = robot.opw
    if p is None:  # the UR layout: wrist -q5, elbow q3
        q[j] = -distance if kind == 0 else distance
    else:  # OPW: wrist t5, elbow t3 + psi, with t = q * sign - offset
        t = distance if kind == 0 else distance - math.atan2(p.a2, p.c3)
        q[j] = (t + p.offsets[j]) * p.signs[j]
    for turn in (0, 1, -1):
        shifted = q[j] + TWO_PI * turn
        if robot.lower_rad[j] <= shifted <= robot.upper_rad[j]:
            q[j] = shifted
            return q
    return None


def test_rows_and_labels_equal_the_plain_reference_on_label_boundaries_and_where_branches_meet(robots, rng) -> None:
    """Poses whose wrist or elbow distance sits on, at or just past the margins of a label change
    (solve_all labels the branches once and the rows near a change one by one), and poses where
    branches meet (a stretched elbow, the UR5 at q = 0: solve_all looks for repeats only where two
    branches are that close), seeded and not: the same rows, branches and labels as the plain reference."""
    repeats = merged = near_change = 0
    for name in ("kuka_kr6_r900_2", "abb_irb2400", "fanuc_m10ia", "ur5"):
        robot = robots[name]
        cases = [np.zeros(6)]
        for q in random_q(robot, rng, 8 if name == "ur5" else 20):
            cases += [b for kind in (0, 2) for d in rng.choice(_BOUNDARY_DISTANCES, 4, replace=False)
                      if (b := _on_boundary(robot, q, kind, float(d))) is not None]
        for q in cases:
            T = robot.fk(q)
            for s in (None, q + rng.normal(0.0, 0.3, 6)):
                ours = solve_all(robot, T, seed=s)
                q_ref, labels, branches, dropped = _reference_and_repeats(robot, T.homogeneous, s)
                np.testing.assert_array_equal(ours.q, q_ref)
                assert list(ours.branches) == branches
                assert list(ours.labels) == labels
                repeats, merged = repeats + dropped[0], merged + dropped[1]
                d = np.abs(distances_batch(robot, q_ref))
                near_change += int(np.any((d < 1.1e-4) | (d[:, [0, 2]] > math.pi - 1.1e-4).any(axis=1, keepdims=True)))
    assert repeats > 0 and merged > 0 and near_change > 0  # solve_all's slower paths were taken
