"""The replay page stays small and quick whatever the number of samples, and keeps what it shows exact.

A long trajectory here is a planned one resampled at a finer period (the same motion, 100 or
1000 times the samples), so that the page of 0.16 M or 1.6 M samples can be compared with the
page of the original without planning for minutes.
"""

from __future__ import annotations

import base64
import copy
import json
import re
import time
from dataclasses import replace
from pathlib import Path

import numpy as np
import pinocchio as pin
import pytest
import umsgpack
import yaml

from singplan.kinematics.robot import bundled_robots, load_robot
from singplan.outputs.viewer import (
    _KEYFRAME_TURN_RAD,
    _KEYFRAMES,
    _PATH_POINTS,
    _STRIP_POINTS,
    ANIMATION_STEP_S,
    joint_travel,
    kept_samples,
    replay_html,
    robot_of,
)
from singplan.results.plan import plan
from singplan.results.trajectory import Trajectory

EXAMPLES = Path(__file__).resolve().parents[1] / "examples"
SIXTY_MOVES_MAX_BYTES = 5_000_000  # the page of a 60-move program (DESIGN: a page to mail, not a dump)


@pytest.fixture(scope="module")
def program() -> Trajectory:
    """examples/kuka_program.yaml: a LIN through a wrist singularity (a crossing), a CIRC and a PTP."""
    return plan(EXAMPLES / "kuka_program.yaml")


def _resampled(traj: Trajectory, factor: int) -> Trajectory:
    """The same motion at a period ``factor`` times finer (every series linearly interpolated)."""
    period = traj.period / factor
    t = np.arange(round(traj.duration_s / period) + 1) * period

    def fine(series: np.ndarray) -> np.ndarray:
        columns = series.reshape(len(traj.t), -1).T
        return np.column_stack([np.interp(t, traj.t, c) for c in columns]).reshape(len(t), *series.shape[1:])

    return replace(traj, period=period, t=t, q=fine(traj.q), qd=fine(traj.qd), qdd=fine(traj.qdd),
                   samples={k: fine(v) for k, v in traj.samples.items()})


def _page(html: str) -> tuple[dict, list[dict]]:
    """The page's data and its meshcat commands, decoded."""
    match = re.search(r"const SINGPLAN = (.*?);</script>", html, re.S)
    assert match is not None
    data = json.loads(match.group(1).replace("<\\/", "</"))
    return data, [umsgpack.unpackb(base64.b64decode(c)) for c in data.pop("commands")]


def _keyframes(commands: list[dict]) -> dict[str, tuple[np.ndarray, np.ndarray, np.ndarray]]:
    """Per animated node: keyframe times [s], positions (m, 3) and quaternions xyzw (m, 4)."""
    animation = next(c for c in commands if c["type"] == "set_animation")
    out = {}
    for clip in animation["animations"]:
        tracks = {tr["name"]: tr["keys"] for tr in clip["clip"]["tracks"]}
        times = np.array([k["time"] for k in tracks[".position"]]) / clip["clip"]["fps"]
        out[clip["path"]] = (times, np.array([k["value"] for k in tracks[".position"]]),
                             np.array([k["value"] for k in tracks[".quaternion"]]))
    return out


def _path_points(commands: list[dict]) -> int:
    """Points of the executed path's lines, all segments together."""
    lines = [c for c in commands if c["type"] == "set_object" and "/paths/executed/" in c["path"]]
    return sum(len(c["object"]["geometries"][0]["data"]["attributes"]["position"]["array"].data) // 12
               for c in lines)


def test_tcp_positions_match_pinocchio_fk_on_every_bundled_robot(rng: np.random.Generator) -> None:
    tool = pin.SE3(pin.rpy.rpyToMatrix(0.3, -0.2, 1.1), np.array([0.02, -0.01, 0.15]))
    for name in bundled_robots():
        robot = load_robot(name, tool=tool)
        q = rng.uniform(np.maximum(robot.lower_rad, -np.pi), np.minimum(robot.upper_rad, np.pi), (50, robot.n_joints))
        expected = np.array([robot.fk(qk).translation for qk in q])
        assert np.abs(robot.tcp_positions(q) - expected).max() < 1e-12, name
    many = np.repeat(q, 400, axis=0)  # 20 000 samples: across the chunk boundary
    assert np.abs(robot.tcp_positions(many) - np.repeat(expected, 400, axis=0)).max() < 1e-12
    assert robot.tcp_positions(q[:0]).shape == (0, 3)


def test_kept_samples_are_bounded_and_keep_boundaries_and_joint_motion(program: Trajectory) -> None:
    counts = []
    for factor in (1, 100, 1000):
        traj = program if factor == 1 else _resampled(program, factor)
        step = max(1, round(ANIMATION_STEP_S / traj.period))  # as the page's animation does
        kept = kept_samples(traj, joint_travel(traj.q), step, _KEYFRAMES, _KEYFRAME_TURN_RAD)
        counts.append(len(kept))
        assert len(kept) <= 2 * _KEYFRAMES + 2 + 3 * len(traj.segments)
        assert kept[0] == 0 and kept[-1] == len(traj.t) - 1
        for seg in traj.segments:
            k0, k1 = round(seg.t0 / traj.period), round(seg.t1 / traj.period)
            assert {k0, k1, (k0 + k1) // 2} <= set(kept.tolist())
        # between kept samples no joint turns more than the turn (plus one sample's step)
        turns = np.abs(np.diff(traj.q[kept], axis=0)).max()
        assert turns <= _KEYFRAME_TURN_RAD + np.abs(np.diff(traj.q, axis=0)).max() + 1e-12
    print(f"keyframes of {len(program.t)}, 100x and 1000x as many samples: {counts}")
    assert max(counts) <= 1.3 * min(counts)  # 1000 times the samples, about the same keyframes


def test_small_trajectory_page_keeps_every_sample_and_exact_keyframes(program: Trajectory) -> None:
    robot = robot_of(program)
    data, commands = _page(replay_html(program, robot))
    assert _path_points(commands) == sum(round(s.t1 / program.period) - round(s.t0 / program.period) + 1
                                         for s in program.segments)
    model, _, visual = pin.buildModelsFromUrdf(str(robot.urdf_path),
                                               package_dirs=[str(p) for p in robot.urdf_path.parents])
    frames = _keyframes(commands)
    times, positions, quaternions = frames["/meshcat/robot/visuals/link_6_0"]
    step = max(1, round(ANIMATION_STEP_S / program.period))
    grid = program.t[::step]  # the keyframes of the page before decimation existed are all there
    assert np.isin(np.round(grid / program.period), np.round(times / program.period)).all()
    model_data, visual_data = model.createData(), visual.createData()
    for i in (0, len(times) // 3, len(times) - 1):
        k = round(times[i] / program.period)
        pin.forwardKinematics(model, model_data, program.q[k])
        pin.updateGeometryPlacements(model, model_data, visual, visual_data)
        placement = visual_data.oMg[visual.getGeometryId("link_6_0")]
        assert np.abs(positions[i] - placement.translation).max() < 1e-6  # single precision
        quaternion = pin.Quaternion(placement.rotation).coeffs()
        assert min(np.abs(quaternions[i] - quaternion).max(), np.abs(quaternions[i] + quaternion).max()) < 1e-6
    assert "/meshcat/robot/visuals/base_link_0" not in frames  # the base never moves: not animated
    assert len(data["speed"]["t"]) <= _STRIP_POINTS


def test_long_trajectory_page_is_bounded_and_keeps_peaks(program: Trajectory) -> None:
    long = _resampled(program, 100)  # 0.16 M samples
    robot = robot_of(long)
    started = time.perf_counter()
    html = replay_html(long, robot)
    seconds = time.perf_counter() - started
    data, commands = _page(html)
    small = len(replay_html(program, robot))
    print(f"replay of {len(long.t)} samples: {len(html) / 1e6:.2f} MB in {seconds:.1f} s "
          f"({len(program.t)} samples: {small / 1e6:.2f} MB)")
    assert len(html) < 1.5 * small
    assert _path_points(commands) <= 2 * _PATH_POINTS + 2 + 4 * len(long.segments)  # not one a sample
    # the strip keeps the highest joint-speed ratio of all steps (forward differences, as the
    # checker measures), at the time the step ends
    vmax = robot.velocity_rad_s * long.task.limits.velocity_scale
    ratio = np.max(np.abs(np.diff(long.q, axis=0)) / long.period / vmax, axis=1)
    assert len(data["speed"]["t"]) <= _STRIP_POINTS
    assert max(data["speed"]["ratio"]) == pytest.approx(ratio.max(), abs=1e-4)
    assert data["speed"]["t"][int(np.argmax(data["speed"]["ratio"]))] == pytest.approx(
        long.t[1 + int(np.argmax(ratio))], abs=1e-4)
    # at the crossings' midpoints, as before (and the closest approach of the self-collision check)
    labels = [label["xyz"] for label in data["labels"] if not label["text"].startswith("closest ")]
    expected = [robot.fk(long.q[(round(s.t0 / long.period) + round(s.t1 / long.period)) // 2]).translation
                for s in long.segments if s.kind == "crossing"]
    assert np.allclose(labels, expected, atol=1e-9)


@pytest.mark.slow  # plans 60 moves (30 crossings) and builds their page
def test_sixty_move_program_page_is_small(tmp_path: Path) -> None:
    """30 LINs through the wrist singularity and 30 PTPs back: 60 moves, 30 crossings."""
    task = yaml.safe_load((EXAMPLES / "kuka_program.yaml").read_text())
    back = {"ptp": {"to": {"joints_deg": task["start"]["joints_deg"]}}}
    task["moves"] = [copy.deepcopy(move) for _ in range(30) for move in (task["moves"][0], back)]
    path = tmp_path / "sixty.yaml"
    path.write_text(yaml.safe_dump(task))
    traj = plan(path)
    assert sum(s.kind == "crossing" for s in traj.segments) == 30
    html = replay_html(traj, robot_of(traj))
    print(f"60-move program, {len(traj.t)} samples: replay.html {len(html) / 1e6:.2f} MB")
    assert len(html) < SIXTY_MOVES_MAX_BYTES
