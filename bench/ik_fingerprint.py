"""A fingerprint of what ``solve_all`` returns, to prove a speed-up changed nothing (issue 24).

    python bench/ik_fingerprint.py record OUT.jsonl [--poses 300] [--singular 150] [--seed 2024]
    python bench/ik_fingerprint.py compare BEFORE.jsonl AFTER.jsonl

``record`` calls ``solve_all`` on every OPW and UR arm the registry bundles (and on three of them
with a tool, and on the numeric five- and seven-joint arms with fewer poses): random poses (FK of
joints inside the limits), and poses on or near a singularity (the wrist, shoulder or elbow
distance set, by bisection on one joint, to 0, to the label threshold, to the margin where the
labels are computed one by one, just past it, near +-pi), plus q = 0 and the OPW zero; each pose
without a seed, with a seed near it, with one whole turns away and with its own joints. One JSON
line per call: the SHA-256 of the pose and seed, and of the rows' bytes, dtype and shape, the
labels and the branches. ``compare`` prints the calls that differ and exits 1 if any does.

Run it with the tree before a change and after it (``PYTHONPATH=TREE``; both draw the same poses
from the seed): an unchanged ``solve_all`` leaves every line identical, bit for bit.
"""

from __future__ import annotations

import argparse
import hashlib
import json
import sys
from collections.abc import Iterator
from pathlib import Path

import numpy as np
import pinocchio as pin

from singplan.kinematics.configuration import LABEL_ZERO, distances_batch
from singplan.kinematics.ik.solve import solve_all
from singplan.kinematics.robot import Robot, bundled_robots, load_robot

NUMERIC = ("so100", "panda")  # a few poses each: the numeric solver takes milliseconds a pose
TOOLED = ("kuka_kr6_r900_2", "ur5", "fanuc_m10ia")
# distances at and around a label change: its threshold, labels_batch's margin (10 LABEL_ZERO), past it
_TARGETS = (0.0, 1e-13, 1e-9, LABEL_ZERO, 1.0001 * LABEL_ZERO, 0.9999 * LABEL_ZERO, 1e-4, 1.0001e-4, 0.9999e-4, 1e-3)
_JOINT_OF_KIND = (4, 1, 2)  # wrist: q5, shoulder: q2, elbow: q3


def arms() -> dict[str, Robot]:
    """The bundled OPW and UR arms, three of them with a tool, and the numeric ones."""
    names = [name for name, entry in bundled_robots().items() if entry.family in ("opw", "ur")]
    out = {name: load_robot(name) for name in [*names, *NUMERIC]}
    tool = pin.SE3(pin.rpy.rpyToMatrix(0.3, -0.2, 0.5), np.array([0.02, -0.03, 0.15]))
    out.update({f"{name}+tool": load_robot(name, tool=tool) for name in TOOLED})
    return out


def _limits(robot: Robot) -> tuple[np.ndarray, np.ndarray]:
    return np.maximum(robot.lower_rad, -2 * np.pi), np.minimum(robot.upper_rad, 2 * np.pi)


def near_singular(robot: Robot, rng: np.random.Generator, count: int) -> np.ndarray:
    """Joints (<= count + 2, n) with a singular distance set to a value of _TARGETS (either sign, or
    an angle that far from +-pi) by bisection on one joint, then q = 0 and the OPW zero."""
    lo, hi = _limits(robot)
    found: list[np.ndarray] = []
    for _ in range(20 * count):
        if len(found) == count:
            break
        q, kind = rng.uniform(lo, hi), int(rng.integers(3))
        target = float(rng.choice(_TARGETS)) * float(rng.choice([-1.0, 1.0]))
        if kind != 1 and rng.random() < 0.3:
            target = float(np.copysign(np.pi - abs(target), target))
        joint = _JOINT_OF_KIND[kind] if kind != 1 or rng.random() < 0.5 else (3 if robot.ur is not None else 2)
        q_on = _bisect(robot, q, joint, kind, target)
        if q_on is not None:
            found.append(q_on)
    found.append(np.zeros(robot.n_joints))
    if robot.opw is not None:
        found.append(robot.opw.offsets * robot.opw.signs)
    return np.array(found)


def _bisect(robot: Robot, q: np.ndarray, joint: int, kind: int, target: float) -> np.ndarray | None:
    """q with ``joint`` moved so that distance ``kind`` is ``target`` (None when it does not cross it)."""
    lo, hi = _limits(robot)
    grid = np.linspace(lo[joint], hi[joint], 241)
    trial = np.repeat(q[None], len(grid), axis=0)
    trial[:, joint] = grid
    f = distances_batch(robot, trial)[:, kind] - target
    crossing = np.flatnonzero((np.sign(f[:-1]) != np.sign(f[1:])) & (np.abs(f[:-1] - f[1:]) < 1.0))  # not a wrap
    if len(crossing) == 0:
        return None
    i = int(crossing[0])
    a, b, fa = grid[i], grid[i + 1], f[i]
    q = q.copy()
    for _ in range(80):
        q[joint] = 0.5 * (a + b)
        fm = distances_batch(robot, q[None])[0, kind] - target
        a, b, fa = (q[joint], b, fm) if np.sign(fm) == np.sign(fa) else (a, q[joint], fa)
    q[joint] = 0.5 * (a + b)
    return q


def calls(seed: int, poses: int, singular: int) -> Iterator[tuple[str, int, str, pin.SE3, np.ndarray | None, Robot]]:
    """(arm, pose index, seed kind, pose, seed, robot) of every call, the same for every tree."""
    rng = np.random.default_rng(seed)
    for name, robot in arms().items():
        numeric = name in NUMERIC
        lo, hi = _limits(robot)
        q = rng.uniform(lo, hi, size=(poses // 15 if numeric else poses, robot.n_joints))
        if not numeric:
            q = np.concatenate([q, near_singular(robot, rng, singular)])
        near = q + rng.normal(0.0, 0.3, q.shape)
        turned = q + rng.choice([-1, 0, 1], size=q.shape) * 2 * np.pi + rng.normal(0.0, 1.0, q.shape)
        for k, qk in enumerate(q):
            T = robot.fk(qk)
            for kind, s in (("none", None), ("near", near[k]), ("turned", turned[k]), ("own", qk)):
                yield name, k, kind, T, s, robot


def _sha(*parts: bytes) -> str:
    digest = hashlib.sha256()
    for part in parts:
        digest.update(part)
    return digest.hexdigest()[:24]


def record(out: Path, seed: int, poses: int, singular: int) -> int:
    with out.open("w") as f:
        for name, k, kind, T, s, robot in calls(seed, poses, singular):
            sol = solve_all(robot, T, seed=s)
            line = {"arm": name, "pose": k, "seed": kind,
                    "input": _sha(T.homogeneous.tobytes(), b"" if s is None else s.tobytes()),
                    "rows": len(sol),
                    "output": _sha(sol.q.tobytes(), str((sol.q.dtype, sol.q.shape, type(sol).__name__)).encode(),
                                   json.dumps(list(sol.labels)).encode(), sol.branches.tobytes(),
                                   str((sol.branches.dtype, sol.branches.shape)).encode())}
            f.write(json.dumps(line) + "\n")
    return 0


def compare(before: Path, after: Path) -> int:
    old, new = (p.read_text().splitlines() for p in (before, after))
    differ = [(a, b) for a, b in zip(old, new, strict=False) if a != b]
    for a, b in differ[:20]:
        sys.stdout.write(f"- {a}\n+ {b}\n")
    rows = sum(json.loads(line)["rows"] for line in old)
    sys.stdout.write(f"{len(old)} calls ({rows} rows) before, {len(new)} after; {len(differ)} differ\n")
    return 1 if differ or len(old) != len(new) else 0


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    sub = parser.add_subparsers(dest="command", required=True)
    rec = sub.add_parser("record", help="call solve_all on every pose and write one line a call")
    rec.add_argument("out", type=Path)
    rec.add_argument("--poses", type=int, default=300, help="random poses an arm (a fifteenth for numeric arms)")
    rec.add_argument("--singular", type=int, default=150, help="near-singular poses an OPW or UR arm")
    rec.add_argument("--seed", type=int, default=2024)
    cmp = sub.add_parser("compare", help="the calls whose results differ")
    cmp.add_argument("before", type=Path)
    cmp.add_argument("after", type=Path)
    args = parser.parse_args(argv)
    if args.command == "record":
        return record(args.out, args.seed, args.poses, args.singular)
    return compare(args.before, args.after)


if __name__ == "__main__":
    sys.exit(main())
