"""The compiled TOPP-RA (singplan.planning.timing.reachability) against toppra itself, the reference:
the same controllable sets and path speeds on seeded random paths, grids and limits."""

from __future__ import annotations

import numpy as np
import pytest
import toppra as ta
import toppra.algorithm as ta_algo
import toppra.constraint as ta_constraint
from toppra._CythonUtils import _create_velocity_constraint, _create_velocity_constraint_varying

from singplan.planning.timing import reachability

_REL = 1e-9  # relative agreement required (they agree bit for bit on every case tried)


def _random_path(rng: np.random.Generator, dof: int) -> tuple[ta.SplineInterpolator, np.ndarray]:
    """A cubic spline through random waypoints on [0, 1] and a random strictly increasing grid on it."""
    knots = np.concatenate([[0.0], np.sort(rng.uniform(0.02, 0.98, rng.integers(3, 9))), [1.0]])
    waypoints = np.cumsum(rng.normal(0.0, 0.5, (len(knots), dof)), axis=0)
    waypoints[:, rng.integers(dof)] = 0.3 * knots  # one coordinate that only advances (the TCP's)
    spline = ta.SplineInterpolator(knots, waypoints)
    inner = np.sort(rng.uniform(0.0, 1.0, rng.integers(60, 400)))
    grid = np.unique(np.concatenate([[0.0], inner, [1.0]]))
    return spline, grid


def _reference(constraints: list, spline: ta.SplineInterpolator,
               grid: np.ndarray) -> tuple[ta_algo.ParameterizationReturnCode, np.ndarray, np.ndarray | None]:
    instance = ta_algo.TOPPRA(constraints, spline, gridpoints=grid)
    _, sd, _, sets = instance.compute_parameterization(0.0, 0.0, return_data=True)
    return instance.problem_data.return_code, sets, sd


def _assert_same(result: reachability.Reachability, code: ta_algo.ParameterizationReturnCode,
                 sets: np.ndarray, sd: np.ndarray | None) -> None:
    assert result.code == code
    np.testing.assert_allclose(result.sets, sets, rtol=_REL, atol=0.0)
    assert sd is not None and result.sd is not None
    np.testing.assert_allclose(result.sd, sd, rtol=_REL, atol=0.0)


@pytest.mark.parametrize("seed", range(12))
def test_sets_and_speeds_equal_toppras_under_joint_speed_and_acceleration_limits(seed: int) -> None:
    rng = np.random.default_rng(seed)
    dof = int(rng.integers(2, 9))
    spline, grid = _random_path(rng, dof)
    vmax, amax = rng.uniform(0.2, 3.0, dof), rng.uniform(0.5, 10.0, dof)
    reference = _reference([ta_constraint.JointVelocityConstraint(np.stack([-vmax, vmax], axis=1)),
                            ta_constraint.JointAccelerationConstraint(np.stack([-amax, amax], axis=1))], spline, grid)
    d1, d2 = spline(grid, 1), spline(grid, 2)
    result = reachability.solve(grid, [reachability.acceleration_rows(grid, d1, d2, amax)],
                                reachability.velocity_x_bounds(d1, vmax))
    _assert_same(result, *reference)


@pytest.mark.parametrize("seed", range(6))
def test_speed_limits_varying_along_the_path_as_toppras_varying_constraint(seed: int) -> None:
    rng = np.random.default_rng(100 + seed)
    dof = int(rng.integers(2, 8))
    spline, grid = _random_path(rng, dof)
    steps = np.sort(rng.uniform(0.0, 1.0, 3))
    levels = rng.uniform(0.2, 3.0, (4, dof))

    def bounds(s: float) -> np.ndarray:
        v = levels[int(np.searchsorted(steps, s))]
        return np.stack([-v, v], axis=1)

    amax = rng.uniform(0.5, 10.0, dof)
    reference = _reference([ta_constraint.JointVelocityConstraintVarying(bounds),
                            ta_constraint.JointAccelerationConstraint(np.stack([-amax, amax], axis=1))], spline, grid)
    d1, d2 = spline(grid, 1), spline(grid, 2)
    vmax = np.array([bounds(s)[:, 1] for s in grid])  # (G, dof)
    result = reachability.solve(grid, [reachability.acceleration_rows(grid, d1, d2, amax)],
                                reachability.velocity_x_bounds(d1, vmax))
    _assert_same(result, *reference)


def _torque_constraint(rng: np.random.Generator, dof: int, limit: float, gravity: float
                       ) -> ta_constraint.JointTorqueConstraint:
    """tau = M qdd + (qd^T B qd) + gravity * sin(q): a fixed random inertia and Coriolis-like term."""
    inertia = rng.normal(0.0, 1.0, (dof, dof))
    inertia = inertia @ inertia.T + dof * np.eye(dof)
    coriolis = rng.normal(0.0, 0.2, (dof, dof))

    def inverse_dynamics(q: np.ndarray, qd: np.ndarray, qdd: np.ndarray) -> np.ndarray:
        return inertia @ qdd + coriolis @ (qd * qd) + gravity * np.sin(q)

    bound = np.full(dof, limit)
    return ta_constraint.JointTorqueConstraint(inverse_dynamics, np.stack([-bound, bound], axis=1), np.zeros(dof))


@pytest.mark.parametrize("seed", range(4))
def test_torque_rows_from_toppras_constraint_give_its_sets_and_speeds(seed: int) -> None:
    rng = np.random.default_rng(200 + seed)
    dof = int(rng.integers(2, 7))
    spline, grid = _random_path(rng, dof)
    vmax, amax = rng.uniform(0.5, 3.0, dof), rng.uniform(2.0, 10.0, dof)
    torque = _torque_constraint(rng, dof, limit=15.0, gravity=1.0)
    reference = _reference([ta_constraint.JointVelocityConstraint(np.stack([-vmax, vmax], axis=1)),
                            ta_constraint.JointAccelerationConstraint(np.stack([-amax, amax], axis=1)), torque],
                           spline, grid)
    d1, d2 = spline(grid, 1), spline(grid, 2)
    result = reachability.solve(grid, [reachability.acceleration_rows(grid, d1, d2, amax),
                                       reachability.toppra_rows(torque, spline, grid)],
                                reachability.velocity_x_bounds(d1, vmax))
    _assert_same(result, *reference)


def test_an_empty_controllable_set_is_reported_where_toppra_finds_it() -> None:
    """Holding the path still takes more torque than the limit somewhere: the backward pass empties
    at the same stage as toppra's, and no profile is given."""
    rng = np.random.default_rng(300)
    dof = 3
    spline, grid = _random_path(rng, dof)
    amax = np.full(dof, 5.0)
    torque = _torque_constraint(rng, dof, limit=1.0, gravity=1.5)  # |sin q| > 2/3 somewhere on the path
    acceleration = ta_constraint.JointAccelerationConstraint(np.stack([-amax, amax], axis=1))
    speed = ta_constraint.JointVelocityConstraint(np.stack([-np.ones(dof), np.ones(dof)], axis=1))
    instance = ta_algo.TOPPRA([speed, acceleration, torque], spline, gridpoints=grid)
    sets = instance.compute_controllable_sets(0.0, 0.0)
    empty = np.flatnonzero(np.isnan(sets[:, 0]))
    assert len(empty) == 1  # the reference's set empties (then stops)
    d1, d2 = spline(grid, 1), spline(grid, 2)
    result = reachability.solve(grid, [reachability.acceleration_rows(grid, d1, d2, amax),
                                       reachability.toppra_rows(torque, spline, grid)],
                                reachability.velocity_x_bounds(d1, np.ones(dof)))
    assert result.code == ta_algo.ParameterizationReturnCode.FailUncontrollable
    assert result.sd is None and result.empty_at == int(empty[0])
    np.testing.assert_array_equal(result.sets[empty[0]:], sets[empty[0]:])


def test_speed_bounds_are_toppras_single_precision_ones() -> None:
    """x bounds bit for bit those of toppra's joint speed constraints (single precision, as its
    Cython computes them), zero derivatives ignored, capped at sd = 1e8; fixed and varying limits."""
    rng = np.random.default_rng(5)
    d1 = rng.normal(0.0, 1.0, (50, 4))
    d1[3] = 0.0  # no coordinate moves: only the cap
    d1[7, :2] = 0.0
    vmax = rng.uniform(0.1, 2.0, 4)
    _, _, c = _create_velocity_constraint(d1, np.stack([-vmax, vmax], axis=1))
    np.testing.assert_array_equal(reachability.velocity_x_bounds(d1, vmax), -c[:, 0])
    assert np.all(c[:, 1] == 0.0)  # the lower bound on x
    varying = rng.uniform(0.1, 2.0, (50, 4))
    _, _, c = _create_velocity_constraint_varying(d1, np.stack([-varying, varying], axis=2))
    np.testing.assert_array_equal(reachability.velocity_x_bounds(d1, varying), -c[:, 0])


def test_only_constraints_with_a_fixed_inequality_matrix_become_rows() -> None:
    spline = ta.SplineInterpolator(np.linspace(0.0, 1.0, 5), np.arange(10.0).reshape(5, 2))
    speed = ta_constraint.JointVelocityConstraint(np.array([[-1.0, 1.0], [-1.0, 1.0]]))
    with pytest.raises(ValueError, match="fixed inequality matrix"):
        reachability.toppra_rows(speed, spline, np.linspace(0.0, 1.0, 5))
