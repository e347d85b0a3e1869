"""Peak memory of writing trajectory.csv + trajectory.json for a synthetic trajectory.

Usage: python bench/bench_save_memory.py [SAMPLES] [--old] [--trace]

``--old`` writes the way singplan did before issue 10 (np.savetxt of a stacked copy, and one
``json.dumps(traj.to_json())`` string of Python lists), for comparison. Prints the size of the
trajectory's arrays, the process's peak RSS before and after saving, the time taken and the
files' sizes; ``--trace`` adds the tracemalloc peak while saving (numpy and Python
allocations; tracing slows the writing several times over, so the time is then not meaningful).
"""

from __future__ import annotations

import json
import resource
import sys
import tempfile
import time
import tracemalloc
from pathlib import Path

import numpy as np

from singplan.results.metrics import Metrics
from singplan.results.trajectory import Trajectory, save
from singplan.task.schema import Move, PoseSpec, Task


def synthetic(samples: int, joints: int = 6, seed: int = 7) -> Trajectory:
    rng = np.random.default_rng(seed)
    period_s = 0.004
    t = np.arange(samples) * period_s
    q = np.cumsum(rng.normal(0.0, 1e-3, (samples, joints)), axis=0)
    qd = np.gradient(q, period_s, axis=0)
    qdd = np.gradient(qd, period_s, axis=0)
    series = {"position_error_m": rng.uniform(0, 1e-5, samples), "orientation_error_rad": rng.uniform(0, 1e-4, samples),
              "distances": rng.uniform(0, 1, (samples, 3))}
    task = Task("kuka_kr6_r900_2", (Move("lin", to=PoseSpec((0.5, 0.0, 0.5))),), start_joints_deg=(0.0,) * joints)
    return Trajectory("kuka_kr6_r900_2", "/robots/kuka.urdf", "tool0", {"xyz": [0, 0, 0], "rpy_deg": [0, 0, 0]}, task,
                      tuple(f"joint_{i + 1}" for i in range(joints)), period_s, t, q, qd, qdd, (), (),
                      Metrics.of_samples(float(t[-1]), samples), series)


def save_old(traj: Trajectory, folder: Path) -> None:
    folder.mkdir()
    data = np.hstack([traj.t[:, None], traj.q])
    np.savetxt(folder / "trajectory.csv", data, delimiter=",", header="t," + ",".join(traj.joint_names),
               comments="", fmt="%.17g")
    (folder / "trajectory.json").write_text(json.dumps(traj.to_json()))


def main(argv: list[str]) -> None:
    samples = int(argv[0]) if argv and not argv[0].startswith("--") else 1_000_000
    traj = synthetic(samples)
    arrays_mb = (traj.t.nbytes + traj.q.nbytes + traj.qd.nbytes + traj.qdd.nbytes
                 + sum(a.nbytes for a in traj.samples.values())) / 2**20
    trace = "--trace" in argv
    rss_before_mb = _peak_rss_mb()
    with tempfile.TemporaryDirectory() as tmp:
        folder = Path(tmp) / "out"
        if trace:
            tracemalloc.start()
        start = time.perf_counter()
        if "--old" in argv:
            save_old(traj, folder)
        else:
            save(traj, folder)
        elapsed_s = time.perf_counter() - start
        peak_mb = tracemalloc.get_traced_memory()[1] / 2**20
        traced = f"tracemalloc peak while saving {peak_mb:.0f} MiB; " if trace else ""
        tracemalloc.stop()
        sizes = {p.name: p.stat().st_size / 2**20 for p in sorted(folder.iterdir())}
    print(f"{'old' if '--old' in argv else 'new'}: {samples} samples x {len(traj.joint_names)} joints; "
          f"arrays {arrays_mb:.0f} MiB; {traced}peak RSS {rss_before_mb:.0f} MiB before saving, "
          f"{_peak_rss_mb():.0f} MiB after; {elapsed_s:.1f} s; "
          + ", ".join(f"{name} {size:.0f} MiB" for name, size in sizes.items()))


def _peak_rss_mb() -> float:
    return resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024


if __name__ == "__main__":
    main(sys.argv[1:])
