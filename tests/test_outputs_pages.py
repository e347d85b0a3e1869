"""report.html and replay.html: the shared TCP track, the timeline of stretch kinds (blends,
null-space pauses, weave, kinds unknown to this version), the SVG plots, the programmed path
drawn from the trajectory record alone and the packed animation.

The trajectories are the demo's plan (planned once) and synthetic variants of it: segments
relabelled as a fly-by blend or a kind this version does not know, and a null-space pause made
by holding the joints still for 50 samples inside the crossing.
"""

from __future__ import annotations

import itertools
import json
import re
import subprocess
import sys
import xml.etree.ElementTree as ET
from collections.abc import Callable
from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest
import umsgpack

from singplan.kinematics.robot import Robot
from singplan.outputs import timeline as timeline_module
from singplan.outputs import viewer as viewer_module
from singplan.outputs.pages import build_pages
from singplan.outputs.report import report_html
from singplan.outputs.scene import AnimationCommand
from singplan.outputs.svgplot import LIMIT_COLOUR, PALETTE, Panel, envelope, figure_svg, nice_ticks
from singplan.outputs.timeline import (
    SEGMENT_COLOURS,
    SHADED_OPACITY,
    joint_speed_ratios,
    pause_window,
    speed_limits,
    tcp_track,
    timeline,
)
from singplan.outputs.viewer import joint_travel, programmed_points, replay_html, robot_of, tcp_path, viewer_dir
from singplan.planning.path.pieces import move_piece
from singplan.results.metrics import CrossingFigures
from singplan.results.plan import plan
from singplan.results.trajectory import Segment, Trajectory
from singplan.task.load import parse_task
from singplan.task.schema import Move, PoseSpec, Weave

from .task_strategies import seeded_task

ROOT = Path(__file__).resolve().parents[1]
HOLD = 50  # samples of the synthetic null-space pause


@pytest.fixture(scope="module")
def demo() -> Trajectory:
    return plan(ROOT / "singplan" / "demo_task.yaml")


@pytest.fixture(scope="module")
def robot(demo: Trajectory) -> Robot:
    return robot_of(demo)


def _with_pause_and_blend(traj: Trajectory) -> tuple[Trajectory, int]:
    """The demo with its joints held still for HOLD samples in the crossing's middle (a crossing
    with ``pause_s``), and the last quarter of move 0's post segment a fly-by ``blend``.
    Returns the trajectory and the first sample of the hold."""
    crossing = next(s for s in traj.segments if s.kind == "crossing")
    k = round(0.5 * (crossing.t0 + crossing.t1) / traj.period)
    hold_s = HOLD * traj.period

    def held(a: np.ndarray) -> np.ndarray:
        return np.concatenate([a[:k + 1], np.repeat(a[k:k + 1], HOLD, axis=0), a[k + 1:]])

    def later(t: float) -> float:
        return t + hold_s if t > crossing.t0 + 1e-9 else t

    segments = []
    for s in traj.segments:
        s = replace(s, t0=later(s.t0), t1=later(s.t1))
        if s.kind == "crossing":
            assert isinstance(s.details, CrossingFigures)
            s = replace(s, details=replace(s.details, pause_s=hold_s))
        if s.kind == "post":
            corner = s.t1 - 0.25 * (s.t1 - s.t0)
            corner = round(corner / traj.period) * traj.period
            segments += [replace(s, t1=corner), replace(s, kind="blend", t0=corner)]
            continue
        segments.append(s)
    t = np.arange(len(traj.t) + HOLD) * traj.period
    return replace(traj, t=t, q=held(traj.q), qd=held(traj.qd), qdd=held(traj.qdd),
                   samples={name: held(v) for name, v in traj.samples.items()}, segments=tuple(segments)), k


def _page_data(page: str) -> dict:
    match = re.search(r"const SINGPLAN = (.*?);</script>", page, re.S)
    assert match is not None
    return json.loads(match.group(1).replace("<\\/", "</"))


# -- timeline -------------------------------------------------------------------------------


def test_pause_window_is_the_longest_still_run() -> None:
    step = np.array([1e-3, 0.0, 0.0, 1e-3, 0.0, 0.0, 0.0, 1e-9, 2e-3])  # between samples 0..9
    assert pause_window(step, 0, 9) == (4, 8)  # steps 4-7 still: samples 4..8
    assert pause_window(step, 0, 4) == (1, 3)
    assert pause_window(np.full(5, 1e-3), 0, 5) is None


def test_timeline_colours_blends_pauses_and_tiles_the_trajectory(demo: Trajectory, robot: Robot) -> None:
    traj, k = _with_pause_and_blend(demo)
    stretches = timeline(traj, tcp_track(traj, robot))
    kinds = [s.kind for s in stretches]
    assert kinds == ["pre", "crossing", "pause", "crossing", "post", "blend", "ptp"]
    pause = stretches[2]
    assert (pause.k0, pause.k1) == (k, k + HOLD)  # exactly the held samples
    assert pause.t1 - pause.t0 == pytest.approx(HOLD * traj.period, abs=1e-12)
    assert all(a.k1 == b.k0 for a, b in itertools.pairwise(stretches))  # no gap, no overlap
    assert stretches[0].k0 == 0 and stretches[-1].k1 == len(traj.t) - 1
    assert {s.colour for s in stretches if s.kind in ("blend", "pause")} == {SEGMENT_COLOURS["blend"],
                                                                              SEGMENT_COLOURS["pause"]}


def test_a_segment_kind_unknown_to_this_version_is_drawn_not_refused(demo: Trajectory, robot: Robot) -> None:
    traj = replace(demo, segments=tuple(replace(s, kind="glide") if s.kind == "post" else s for s in demo.segments))
    stretches = timeline(traj, tcp_track(traj, robot))
    assert [s.colour for s in stretches if s.kind == "glide"] == [timeline_module.OTHER_COLOUR]
    assert "glide" in report_html(traj, robot)
    assert _page_data(replay_html(traj, robot))["colours"]["glide"] == timeline_module.OTHER_COLOUR


# -- pages ------------------------------------------------------------------------------------


def test_report_and_replay_show_blends_and_pauses(demo: Trajectory, robot: Robot) -> None:
    traj, k = _with_pause_and_blend(demo)
    report = report_html(traj, robot)
    assert "fly-by blend" in report and "null-space pause" in report  # the timeline's legend
    for kind in ("blend", "pause", "crossing"):
        assert f"#{SEGMENT_COLOURS[kind]:06x}" in report  # in the timeline strip and the shading
    data = _page_data(replay_html(traj, robot))
    assert {"blend", "pause"} <= set(data["colours"])
    pause = next(b for b in data["bands"] if b["kind"] == "pause")
    assert (pause["t0"], pause["t1"]) == pytest.approx((traj.t[k], traj.t[k + HOLD]), abs=1e-9)
    crossing = next(s for s in data["segments"] if s["kind"] == "crossing")
    assert f"TCP paused {HOLD * traj.period:.3f} s" in crossing["detail"]
    assert [s["kind"] for s in data["segments"]] == [s.kind for s in traj.segments]  # one list entry a segment
    blend = next(s for s in data["segments"] if s["kind"] == "blend")
    assert blend["colour"] == SEGMENT_COLOURS["blend"] and blend["title"] == "move 0: fly-by blend"


def test_pages_share_one_fk_pass_timeline_and_speed_over_the_samples(demo: Trajectory, robot: Robot,
                                                  monkeypatch: pytest.MonkeyPatch) -> None:
    calls: list[int] = []
    original = Robot.tcp_positions

    def counted(self: Robot, q: np.ndarray) -> np.ndarray:
        calls.append(len(q))
        return original(self, q)

    monkeypatch.setattr(Robot, "tcp_positions", counted)
    runs: list[str] = []

    def counting(name: str, f: Callable[..., object]) -> Callable[..., object]:
        def run(*args: object) -> object:
            runs.append(name)
            return f(*args)
        return run

    for module, name in ((timeline_module, "timeline"), (timeline_module, "joint_speed_ratios"),
                         (viewer_module, "joint_travel")):
        monkeypatch.setattr(module, name, counting(name, getattr(module, name)))
    pages, skipped = build_pages(demo, robot, report=True, replay=True)
    assert skipped == {} and set(pages) == {"report.html", "replay.html"}
    assert sum(calls) == len(demo.t)  # every sample once, for both pages
    assert sorted(runs) == ["joint_speed_ratios", "joint_travel", "timeline"]  # each once for both pages


def test_report_plots_are_svg_and_bounded_for_long_trajectories(demo: Trajectory, robot: Robot) -> None:
    page = report_html(demo, robot)
    figures = re.findall(r'<figure id="plot-(\w+)">(<svg.*?</svg>)', page, re.S)
    # the bundled KUKA has collision shapes and an SRDF: its self-collision check's least distance too
    assert [key for key, _ in figures] == ["joints", "speed", "distances", "deviation", "tcp", "stopping",
                                           "clearance"]
    for _, svg in figures:
        ET.fromstring(svg)  # well-formed
    # 10 and 100 times the samples (every sample repeated): the plots are envelopes of a bounded
    # number of points, not one point a sample
    sizes = []
    for factor in (10, 100):
        long = replace(demo, t=np.arange(len(demo.t) * factor) * demo.period / factor,
                       period=demo.period / factor, q=np.repeat(demo.q, factor, axis=0),
                       samples={k: np.repeat(v, factor, axis=0) for k, v in demo.samples.items()})
        sizes.append(len(report_html(long, robot)))
    assert sizes[1] < 1.1 * sizes[0]


# -- svg plots --------------------------------------------------------------------------------


def test_nice_ticks_cover_the_range_with_round_steps() -> None:
    for lo, hi in ((0.0, 6.508), (-172.5, 185.0), (1e-4, 3.7e-4), (-0.01, 0.01)):
        ticks = nice_ticks(lo, hi)
        step = ticks[1] - ticks[0]
        mantissa = step / 10 ** np.floor(np.log10(step))
        assert min(abs(mantissa - m) for m in (1.0, 2.0, 2.5, 5.0)) < 1e-9
        assert lo <= ticks[0] < lo + step and hi - step < ticks[-1] <= hi
        assert 3 <= len(ticks) <= 11


def test_envelope_keeps_every_peak_and_bounds_the_points() -> None:
    rng = np.random.default_rng(7)
    y = rng.normal(size=100_000)
    y[31_337] = 50.0
    y[77_777] = -40.0
    _, e = envelope(np.arange(len(y)), y, 500)
    assert len(e) == 1000 and e.max() == 50.0 and e.min() == -40.0
    assert envelope(np.arange(10), np.arange(10.0), 500)[1].tolist() == list(range(10))


def test_figure_places_curves_inside_their_panel_and_ids_are_unique() -> None:
    a, b = Panel(title="a"), Panel(title="b", legend=True)
    a.curve(np.array([0.0, 1.0, 2.0]), np.array([0.0, 10.0, 5.0]))
    a.hline(12.0)
    a.span(0.5, 1.5, "#f4b400", 0.2)
    b.curve(np.array([0.0, 1.0]), np.array([1.0, 2.0]), label="j1")
    b.point(1.0, 2.0, "worst")
    svg = figure_svg("k", [a, b], columns=2, height_in=3.0)
    root = ET.fromstring(svg)
    ns = "{http://www.w3.org/2000/svg}"
    clips = [c.get("id") for c in root.iter(f"{ns}clipPath")]
    assert clips == ["k-clip0", "k-clip1"]
    curve = next(p for p in root.iter(f"{ns}path") if p.get("stroke") == "#1f77b4")
    xy = np.array([[float(v) for v in pair.split()] for pair in re.split("[ML]", curve.get("d"))[1:]])
    assert xy[:, 0].min() >= 0 and xy[:, 0].max() <= 480  # the left half of a 960 px figure
    assert xy[1, 1] < xy[2, 1] < xy[0, 1]  # SVG y grows downwards: 10 above 5 above 0
    assert "j1" in svg and "worst" in svg


def test_report_and_replay_show_the_joint_speed_the_metrics_and_checker_measure(demo: Trajectory,
                                                                                 robot: Robot) -> None:
    ratios = joint_speed_ratios(demo, speed_limits(demo, robot))
    forward = np.abs(np.diff(demo.q, axis=0)) / demo.period / speed_limits(demo, robot)  # the checker's qd
    assert ratios.shape == forward.shape and np.allclose(ratios, forward, rtol=1e-6, atol=0)
    assert float(ratios.max()) == pytest.approx(demo.metrics.max_joint_speed_ratio, rel=1e-6)
    strip = _page_data(replay_html(demo, robot))["speed"]
    assert max(strip["ratio"]) == pytest.approx(demo.metrics.max_joint_speed_ratio, abs=1e-4)
    assert strip["t"][0] == pytest.approx(demo.t[1])  # step 0 -> 1, drawn where it ends


# -- replay -----------------------------------------------------------------------------------


def test_programmed_path_comes_from_the_record_not_the_task_parser(monkeypatch: pytest.MonkeyPatch) -> None:
    traj = plan(ROOT / "examples" / "kuka_program.yaml")  # LIN, CIRC, PTP
    robot = robot_of(traj)
    monkeypatch.setattr("singplan.task.load.parse_task", lambda *a, **k: pytest.fail("the task was re-parsed"))
    path = programmed_points(traj, robot, tcp_path(traj, tcp_track(traj, robot), joint_travel(traj.q)))
    lin, circ = traj.task.moves[0], traj.task.moves[1]
    assert lin.to is not None and circ.to is not None and circ.via_xyz is not None
    assert np.allclose(path[0], robot.fk(traj.q[0]).translation, atol=1e-12)
    assert np.allclose(path[63], lin.to.xyz, atol=1e-12)  # the LIN's 64 points end on its target
    assert np.allclose(path[127], circ.to.xyz, atol=1e-12)
    arc = path[64:128]
    centre_distance = np.linalg.norm(arc - np.asarray(circ.via_xyz), axis=1).min()
    assert centre_distance < 0.01  # the arc passes by its via point (64 points on ~0.5 m)


@pytest.mark.parametrize("seed", range(20))
def test_a_task_comes_back_from_its_recorded_mapping(seed: int) -> None:
    task = parse_task(seeded_task(seed))
    weave = Move("lin", to=PoseSpec((0.5, 0.1, 0.4)), speed_m_s=0.1, weave=Weave("triangle", 2.0, 15.0),
                 blend_mm=5.0)
    last = Move("lin", to=PoseSpec((0.5, 0.1, 0.45)))  # a blend needs a move after it
    task = replace(task, moves=(*task.moves, weave, last))
    recorded = json.loads(json.dumps(task.to_mapping()))  # as trajectory.json keeps it
    assert parse_task(recorded) == task  # what singplan.results.reading does with trajectory.json's task


def test_the_programmed_path_is_the_planners_piece(demo: Trajectory, robot: Robot) -> None:
    path = programmed_points(demo, robot, tcp_path(demo, tcp_track(demo, robot), joint_travel(demo.q)))
    piece = move_piece(0, demo.task.moves[0], robot.fk(demo.q[0]))
    count = piece.drawing_count()
    assert np.array_equal(path[:count], piece.positions(np.linspace(0.0, 1.0, count)))


def test_the_replay_takes_the_reports_colours_from_the_page_data(demo: Trajectory, robot: Robot) -> None:
    palette = _page_data(replay_html(demo, robot))["palette"]
    assert palette["limit"] == LIMIT_COLOUR and palette["curve"] == PALETTE[0]
    assert palette["label"] == SEGMENT_COLOURS["crossing"]
    assert palette["shaded"] == {kind: SHADED_OPACITY[kind] for kind in ("crossing", "blend", "pause")}
    script, style = ((viewer_dir() / name).read_text() for name in ("replay.js", "replay.css"))
    written = {int(c, 16) for c in re.findall(r"#([0-9a-fA-F]{6})\b", script + style)}
    ours = {*SEGMENT_COLOURS.values(), *(int(c[1:], 16) for c in (*PALETTE, LIMIT_COLOUR))}
    assert not written & ours and "rgba(" not in script  # no colour of the report written again


def test_the_viewer_imports_neither_the_planner_nor_pinocchio_viewers() -> None:
    # singplan.task.load is imported: a trajectory.json's task is checked as a task when it is read
    # (singplan.results.reading); the programmed path is still drawn from the record, not re-parsed
    code = ("import sys, singplan.outputs.viewer, singplan.outputs.report; "
            "print([m for m in ('singplan.planning.orchestration.planner', 'pinocchio.visualize', "
            "'matplotlib') if m in sys.modules])")
    run = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, cwd=ROOT, check=True,
                         env={"PYTHONPATH": str(ROOT), "PATH": ""})
    assert run.stdout.strip() == "[]"


@pytest.mark.parametrize("count", [3, 20, 70_000])
def test_packed_animation_is_the_lowered_command_in_single_precision(count: int) -> None:
    rng = np.random.default_rng(count)
    xyz, quat = rng.normal(size=(count, 2, 3)), rng.normal(size=(count, 2, 4))
    command = AnimationCommand(("/meshcat/a", "/meshcat/b"), np.arange(count) * 5.0, xyz, quat, 250.0, False, 7)
    packed, lowered = umsgpack.unpackb(command.packed()), command.lower()
    assert packed["options"] == lowered["options"] == {"play": False, "repetitions": 7}
    for got, want in zip(packed["animations"], lowered["animations"], strict=True):
        assert got["path"] == want["path"] and got["clip"]["fps"] == want["clip"]["fps"] == 250.0
        for track_got, track_want in zip(got["clip"]["tracks"], want["clip"]["tracks"], strict=True):
            assert track_got["name"] == track_want["name"] and track_got["type"] == track_want["type"]
            times = np.array([key["time"] for key in track_got["keys"]])
            values = np.array([key["value"] for key in track_got["keys"]])
            assert np.array_equal(times, [key["time"] for key in track_want["keys"]])
            assert np.allclose(values, [key["value"] for key in track_want["keys"]], rtol=1e-7, atol=1e-7)


def test_thousands_of_blends_keep_the_report_bounded(demo: Trajectory, robot: Robot) -> None:
    """A program of thousands of fly-by corners: the shading and the timeline strip merge spans
    closer than a plot bucket instead of drawing one element a corner in every plot."""
    factor = 20
    long = replace(demo, t=np.arange(len(demo.t) * factor) * demo.period / factor,
                   period=demo.period / factor, q=np.repeat(demo.q, factor, axis=0),
                   samples={k: np.repeat(v, factor, axis=0) for k, v in demo.samples.items()})
    edges = long.t[::4]
    kinds = ["path", "blend"] * len(edges)
    long = replace(long, segments=tuple(Segment(0, kinds[i], float(a), float(b), "F U N", "F U N")
                                        for i, (a, b) in enumerate(itertools.pairwise(edges))))
    assert len(long.segments) > 2000
    page = report_html(long, robot)
    blend = f"#{SEGMENT_COLOURS['blend']:06x}"
    for key, svg in re.findall(r'<figure id="plot-(\w+)">(<svg.*?</svg>)', page, re.S):
        panels = svg.count("<clipPath")
        assert svg.count(f'fill="{blend}"') <= panels * 1001, key
    strip = re.search(r'<div id="timeline".*?</div>', page, re.S)
    assert strip is not None and strip.group(0).count("<i ") <= 2 * 1001
