"""TOPP-RA engines side by side on the passes singplan really solves (issue 24).

    python bench/bench_toppra.py [--moves 40] [--repeat 3] [--write docs/benchmarks.md]

The passes are captured while planning: the 40-move wrist-crossing LIN program of
bench/bench_program.py (auto), a fly-by program (chains: joint speed limits varying along the
path) and a torque-limited UR5 task (tests/test_dynamics.py's). Each pass is then solved by:

- toppra 0.6 itself: its ``TOPPRA`` instance with its Seidel solver and the constraints singplan
  handed it before (``JointVelocityConstraint`` or ``...Varying``, ``JointAccelerationConstraint``
  with its default interpolation scheme, ``JointTorqueConstraint``): the reference;
- singplan's compiled port (``singplan.planning.timing.reachability``, what ``timing`` calls now);
- copp-py's TOPP2-RA (Rust), when installed (it is not a dependency: ``pip install copp-py``),
  on the same rows (toppra's single-precision speed bounds as its first-order rows, the
  acceleration rows at both ends of each interval as its second-order rows), with its default
  and with tight (1e-12) tolerances. cmeel-toppra (TOPP-RA's C++ library) ships no Python
  bindings and roboplan-toppra needs roboplan's own scene and joint path, so neither is here.

Per engine: the median and total time of a pass, and the largest relative difference from
toppra of the controllable sets' upper bounds, of the path speeds and of each pass's duration.
"""

from __future__ import annotations

import argparse
import importlib.util
import os
import platform
import time
from collections.abc import Callable
from importlib.metadata import version
from pathlib import Path
from typing import Any

import numpy as np
import toppra.algorithm as ta_algo
import toppra.constraint as ta_constraint

from singplan.planning.timing import move, reachability, toppra
from singplan.planning.timing.records import LimitScale, MoveLimits
from singplan.results.plan import plan
from singplan.task.load import parse_task

HERE = Path(__file__).resolve().parent
MARK = "bench_toppra"
FLYBY = HERE.parent / "examples" / "flyby_pick_place.yaml"
UR5_TORQUE = {"robot": "ur5", "start": {"joints_deg": [0, -90, 90, -90, -90, 0]},
              "moves": [{"ptp": {"to": {"joints_deg": [90, -30, 30, -90, -90, 0]}}},
                        {"lin": {"to": {"xyz": [0.3, 0.3, 0.4], "rpy_deg": [180, 0, 0]}, "speed": 1.0}}],
              "limits": {"acceleration": 40.0, "torque_scale": 0.45}}

Case = tuple[toppra.TimingPath, MoveLimits, LimitScale]


def capture(moves: int) -> list[Case]:
    """Every TOPP-RA pass (path, limits, scale) of the three plans."""
    from bench_program import program  # its neighbour's program (bench/ is on the path of a script run)

    cases: list[Case] = []
    solve = move.toppra_profile

    def recording(path: toppra.TimingPath, limits: MoveLimits, scale: LimitScale, move: int) -> Any:
        cases.append((path, limits, scale))
        return solve(path, limits, scale, move)

    move.toppra_profile = recording  # type: ignore[assignment]
    try:
        plan(parse_task(program(moves, "auto")))
        plan(FLYBY)
        plan(parse_task(UR5_TORQUE))
    finally:
        move.toppra_profile = solve  # type: ignore[assignment]
    return cases


def toppra_pass(path: toppra.TimingPath, limits: MoveLimits, scale: LimitScale
                ) -> tuple[np.ndarray | None, np.ndarray | None]:
    """toppra's own instance on the pass: (controllable sets (G, 2), path speeds (G,)); None if it fails."""
    tau, vmax_1, amax_1 = path.scaled_limits(limits, scale)
    speeds = toppra._velocity_bounds(limits, vmax_1, scale.velocity * tau / path.length, scale.tcp_speed * tau,
                                     path.grid)
    if speeds.ndim == 1:
        velocity: ta_constraint.LinearConstraint = ta_constraint.JointVelocityConstraint(
            np.stack([-speeds, speeds], axis=1))
    else:
        rows = dict(zip(path.grid.tolist(), speeds, strict=True))
        velocity = ta_constraint.JointVelocityConstraintVarying(lambda s: np.stack([-rows[s], rows[s]], axis=1))
    constraints = [velocity, ta_constraint.JointAccelerationConstraint(np.stack([-amax_1, amax_1], axis=1))]
    if limits.torque is not None:
        constraints.append(toppra._torque_constraint(limits.torque, path.q[0], path.length, tau, scale.torque))
    instance = ta_algo.TOPPRA(constraints, path.spline, gridpoints=path.grid)
    _, sd, _, sets = instance.compute_parameterization(0.0, 0.0, return_data=True)
    return sets, sd


def compiled_pass(path: toppra.TimingPath, limits: MoveLimits, scale: LimitScale
                  ) -> tuple[np.ndarray | None, np.ndarray | None]:
    """singplan's compiled engine with the rows timing builds."""
    tau, vmax_1, amax_1 = path.scaled_limits(limits, scale)
    d1, d2 = path.derivatives
    rows = [reachability.acceleration_rows(path.grid, d1, d2, amax_1)]
    if limits.torque is not None:
        torque = toppra._torque_constraint(limits.torque, path.q[0], path.length, tau, scale.torque)
        rows.append(reachability.toppra_rows(torque, path.spline, path.grid))
    speeds = toppra._velocity_bounds(limits, vmax_1, scale.velocity * tau / path.length, scale.tcp_speed * tau,
                                     path.grid)
    result = reachability.solve(path.grid, rows, reachability.velocity_x_bounds(d1, speeds))
    return result.sets, result.sd


def copp_pass(tolerance: float | None) -> Callable[[toppra.TimingPath, MoveLimits, LimitScale],
                                                   tuple[np.ndarray | None, np.ndarray | None]]:
    """copp-py's TOPP2-RA on toppra's rows (its default tolerances, or all set to ``tolerance``)."""
    import copp_py as copp

    options = (None if tolerance is None else
               copp.solver.topp2_ra.Options(lp_feas_tol=tolerance, a_cmp_abs_tol=tolerance, a_cmp_rel_tol=tolerance))

    def solve(path: toppra.TimingPath, limits: MoveLimits, scale: LimitScale
              ) -> tuple[np.ndarray | None, np.ndarray | None]:
        tau, vmax_1, amax_1 = path.scaled_limits(limits, scale)
        d1, d2 = path.derivatives
        speeds = toppra._velocity_bounds(limits, vmax_1, scale.velocity * tau / path.length, scale.tcp_speed * tau,
                                     path.grid)
        g, m = d1.shape
        rows = copp.constraints.Constraints(m, capacity=g)
        rows.append_s(path.grid)
        rows.add_constraint_1st(np.minimum(reachability.velocity_x_bounds(d1, speeds), 1e8)[:, None], 0)
        amax = np.tile(amax_1, (g, 1))
        rows.add_constraint_2nd(d2, d1, amax, 0)  # q'' x + q' u <= amax, both ends of each interval
        rows.add_constraint_2nd(-d2, -d1, amax, 0)
        problem = copp.solver.topp2_ra.Problem(rows, (0, g - 1), (0.0, 0.0))
        try:
            sets = copp.solver.reach_set2.backward(problem, options)
            x = copp.solver.topp2_ra.solve(problem, options)
        except copp.CoppError:
            return None, None
        return np.stack([sets.a_min, sets.a_max], axis=1), np.sqrt(np.maximum(x, 0.0))

    return solve


def _duration(grid: np.ndarray, sd: np.ndarray) -> float:
    return float(np.sum(2.0 * np.diff(grid) / (sd[:-1] + sd[1:])))


def compare(cases: list[Case], engines: dict[str, Any], repeat: int) -> dict[str, dict[str, float]]:
    out: dict[str, dict[str, float]] = {}
    reference = [toppra_pass(*case) for case in cases]
    for name, engine in engines.items():
        times, torque_times, d_sets, d_sd, d_time, failed = [], [], 0.0, 0.0, 0.0, 0
        for case, (sets_ref, sd_ref) in zip(cases, reference, strict=True):
            best = np.inf
            for _ in range(repeat):
                t0 = time.perf_counter()
                sets, sd = engine(*case)
                best = min(best, time.perf_counter() - t0)
            if torque_only(case):
                torque_times.append(best)
                if name.startswith("copp"):
                    continue  # the torque rows are not handed to copp here
            else:
                times.append(best)
            if sd_ref is None or sd is None or sets_ref is None or sets is None:
                failed += (sd_ref is None) != (sd is None)
                continue
            high = sets_ref[:, 1] > 1e-9 * np.max(sets_ref[:, 1])
            d_sets = max(d_sets, float(np.max(np.abs(sets[high, 1] - sets_ref[high, 1]) / sets_ref[high, 1])))
            inner = sd_ref > 0.1 * np.max(sd_ref)
            d_sd = max(d_sd, float(np.max(np.abs(sd[inner] - sd_ref[inner]) / sd_ref[inner])))
            d_time = max(d_time, abs(_duration(case[0].grid, sd) / _duration(case[0].grid, sd_ref) - 1.0))
        out[name] = {"median_ms": float(np.median(times)) * 1e3, "total_s": float(np.sum(times)),
                     "torque_ms": float(np.median(torque_times)) * 1e3 if torque_times else float("nan"),
                     "sets": d_sets, "sd": d_sd, "duration": d_time, "failed": failed}
    return out


def torque_only(case: Case) -> bool:
    return case[1].torque is not None


def report(cases: list[Case], figures: dict[str, dict[str, float]]) -> str:
    from bench_ik import machine

    grids = [len(c[0].grid) for c in cases]
    load = os.getloadavg()
    copp_version = version("copp-py") if importlib.util.find_spec("copp_py") else "not installed"
    lines = [
        "### TOPP-RA engines on singplan's own passes", "",
        f"Machine: {machine()}, load average {load[0]:.1f} (shared: compare ratios); "
        f"Python {platform.python_version()}, toppra {version('toppra')}, "
        f"numba {version('numba')}, copp-py {copp_version}.", "",
        f"{len(cases)} passes captured while planning (40 wrist-crossing LINs with auto, "
        f"examples/flyby_pick_place.yaml, the torque-limited UR5 task); grid points a pass: median "
        f"{int(np.median(grids))}, max {max(grids)}. "
        "Times: the best of the runs of each pass; median and total over the passes without torque, the "
        "torque passes apart (their rows come from RNEA at every grid point, in Python, for toppra and singplan "
        "alike). Differences from toppra, relative: the controllable sets' "
        "upper bounds (where above 1e-9 of their peak), the path speeds (above a tenth of their peak), each "
        "pass's duration on its grid; 'disagree' counts passes one solves and the other does not "
        "(copp-py gets no torque rows: the torque passes are timed, not compared).", "",
        "| engine | median ms a pass | total s | vs toppra | torque passes: median ms | sets | path speeds "
        "| duration | disagree |",
        "|---|---:|---:|---:|---:|---:|---:|---:|---:|"]
    base = figures["toppra (reference)"]["total_s"]
    for name, f in figures.items():
        torque = "(no torque rows)" if name.startswith("copp") else f"{f['torque_ms']:.1f}"
        lines.append(f"| {name} | {f['median_ms']:.2f} | {f['total_s']:.2f} | {base / f['total_s']:.1f}x | {torque} "
                     f"| {f['sets']:.1e} | {f['sd']:.1e} | {f['duration']:.1e} | {f['failed']:.0f} |")
    return "\n".join(lines)


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--moves", type=int, default=40)
    parser.add_argument("--repeat", type=int, default=3)
    parser.add_argument("--write", type=Path)
    args = parser.parse_args(argv)
    cases = capture(args.moves)
    engines: dict[str, Any] = {"toppra (reference)": toppra_pass, "singplan compiled": compiled_pass}
    if importlib.util.find_spec("copp_py"):
        engines["copp-py TOPP2-RA, default tolerances"] = copp_pass(None)
        engines["copp-py TOPP2-RA, tolerances 1e-12"] = copp_pass(1e-12)
    text = report(cases, compare(cases, engines, args.repeat))
    from bench_ik import emit  # here, not above: it loads py-opw-kinematics

    emit(text, args.write, MARK)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
