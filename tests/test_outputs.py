"""The output contract (DESIGN.md, "Outputs"), the CLI's top level and the live server's binding.

A short LIN on the bundled KUKA KR 6 R900-2 keeps every plan here well under a second.
"""

from __future__ import annotations

import io
import json
import os
import tracemalloc
from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest
import yaml

from singplan.cli import main
from singplan.entry import OUTPUT_FILES, output_names
from singplan.errors import OutputPathError
from singplan.results import files as outputs
from singplan.results import trajectory as trajectory_module
from singplan.results.metrics import Metrics
from singplan.results.trajectory import Trajectory, load, save, write_csv, write_json
from singplan.task.schema import Move, Task

from .conftest import ReplayServer

ROBOT_URDF = Path(__file__).resolve().parents[1] / "robots" / "urdf" / "kuka_kr6_r900_2.urdf"
START_DEG = [10, -80, 95, 20, 40, 0]
TARGET = {"xyz": [0.55, -0.08, 0.66], "rpy_deg": [-157.09, 31.93, -172.02]}  # ~40 mm from the start
OURS = {"trajectory.csv", "trajectory.json", "report.html", "replay.html",
        "trajectory.urdf", "trajectory.srdf"}  # the last two only for a URDF with continuous joints


def _task(folder: Path, name: str = "task.yaml", robot: str = "kuka_kr6_r900_2", **lin: object) -> Path:
    move = {"to": TARGET, "speed": 0.25, **lin}
    doc = {"robot": robot, "tip": "tool0", "start": {"joints_deg": START_DEG}, "moves": [{"lin": move}],
           "output": {"period": 0.004}}
    path = folder / name
    path.write_text(yaml.safe_dump(doc))
    return path


def _plan(task: Path, out: str | Path, *extra: str) -> tuple[int, str, str]:
    stdout, stderr = io.StringIO(), io.StringIO()
    code = main(["plan", str(task), "-o", str(out), *extra], out=stdout, err=stderr)
    return code, stdout.getvalue(), stderr.getvalue()


def _listing(folder: Path) -> dict[str, bytes | None]:
    """Every path under ``folder`` (hidden ones too) with its bytes (None for a folder)."""
    return {str(p.relative_to(folder)): (None if p.is_dir() else p.read_bytes()) for p in sorted(folder.rglob("*"))}


@pytest.fixture
def project(tmp_path: Path) -> Path:
    """A user's folder: a task, notes and a CAD folder that singplan must never touch."""
    folder = tmp_path / "project"
    (folder / "cad").mkdir(parents=True)
    (folder / "cad" / "part.step").write_text("ISO-10303-21;\n")
    (folder / "notes.txt").write_text("cell 4: check the wrist\n")
    _task(folder)
    return folder


def test_plan_into_the_task_folder_adds_only_its_own_files(project: Path, monkeypatch) -> None:
    monkeypatch.chdir(project)
    before = _listing(project)
    code, out, err = _plan(Path("task.yaml"), ".", "--no-replay")
    assert code == 0, err
    after = _listing(project)
    assert {k: v for k, v in after.items() if k not in OURS} == before  # nothing else added, changed or lost
    assert set(after) - set(before) == {"trajectory.csv", "trajectory.json", "report.html"}
    assert "wrote" in out
    code, _, err = _plan(Path("task.yaml"), ".", "--no-replay", "--no-report", "--quiet")  # a second run replaces ours
    assert code == 0, err
    assert set(_listing(project)) == set(after)


@pytest.mark.parametrize(("edit", "code"), [({"to": {"xyz": [3.0, 0.0, 0.5], "rpy_deg": [180, 0, 0]}}, 3),
                                            ({"speed": -1}, 2)])
def test_a_failing_plan_leaves_the_folder_as_it_was(project: Path, edit: dict, code: int) -> None:
    (project / "trajectory.csv").write_text("an earlier result\n")
    task = _task(project, "bad.yaml", **edit)
    before = _listing(project)
    got, _, err = _plan(task, project)
    assert got == code, err
    assert _listing(project) == before


def test_a_failing_plan_removes_the_folders_it_created(tmp_path: Path) -> None:
    task = _task(tmp_path, speed=-1)
    code, _, _ = _plan(task, tmp_path / "new" / "deeper" / "out")
    assert code == 2
    task = _task(tmp_path, to={"xyz": [3.0, 0.0, 0.5], "rpy_deg": [180, 0, 0]})
    code, _, _ = _plan(task, tmp_path / "new" / "deeper" / "out")
    assert code == 3
    assert sorted(p.name for p in tmp_path.iterdir()) == ["task.yaml"]


def test_unusable_output_paths_exit_2_naming_the_path_before_planning(tmp_path: Path, monkeypatch) -> None:
    task = _task(tmp_path)
    (tmp_path / "a_file").write_text("keep me\n")

    def no_planning(*args: object, **kwargs: object) -> None:
        raise AssertionError("planned although the output path is unusable")

    monkeypatch.setattr("singplan.entry.planned_trajectory", no_planning)  # the stage `singplan plan` runs
    for out in (tmp_path / "a_file", tmp_path / "a_file" / "sub", "/proc/singplan-x", "", task):
        code, _, err = _plan(task, out)
        assert code == 2, (out, err)
        assert err.startswith(f"singplan: error: output {str(out)!r}:") and err.count("\n") == 1, err
    assert (tmp_path / "a_file").read_text() == "keep me\n"
    assert sorted(p.name for p in tmp_path.iterdir()) == ["a_file", "task.yaml"]
    (tmp_path / "busy" / "replay.html").mkdir(parents=True)  # a folder where one of singplan's files goes
    code, _, err = _plan(task, tmp_path / "busy")
    assert code == 2 and "replay.html is a folder" in err, err


@pytest.mark.skipif(os.geteuid() == 0, reason="root writes into read-only folders")
def test_a_read_only_folder_is_bad_input(tmp_path: Path) -> None:
    task = _task(tmp_path)
    locked = tmp_path / "locked"
    locked.mkdir(mode=0o555)
    code, _, err = _plan(task, locked / "out")
    assert code == 2 and "locked" in err


def test_a_symlink_to_a_folder_is_written_through_and_kept(tmp_path: Path) -> None:
    task = _task(tmp_path)
    (tmp_path / "real").mkdir()
    (tmp_path / "real" / "mine.txt").write_text("x")
    (tmp_path / "link").symlink_to(tmp_path / "real", target_is_directory=True)
    code, _, err = _plan(task, tmp_path / "link", "--no-report", "--no-replay")
    assert code == 0, err
    assert (tmp_path / "link").is_symlink()
    assert sorted(p.name for p in (tmp_path / "real").iterdir()) == ["mine.txt", "trajectory.csv", "trajectory.json"]


@pytest.mark.parametrize("stop", [KeyboardInterrupt, OSError(28, "No space left on device")])
def test_an_interrupted_write_leaves_no_temporary_file_and_the_old_results(project: Path, monkeypatch,
                                                                           stop: BaseException) -> None:
    (project / "trajectory.csv").write_text("an earlier result\n")
    before = _listing(project)

    def fail(stream: io.TextIOBase, traj: Trajectory, urdf_copy: str | None = None) -> None:
        stream.write('{"format": ')
        raise stop

    monkeypatch.setattr(trajectory_module, "write_json", fail)
    code, _, err = _plan(project / "task.yaml", project, "--no-report", "--no-replay")
    assert code == (130 if stop is KeyboardInterrupt else 2), err
    assert _listing(project) == before  # trajectory.csv was written first, yet nothing was renamed
    code, _, _ = _plan(project / "task.yaml", project / "fresh" / "out", "--no-report", "--no-replay")
    assert code == (130 if stop is KeyboardInterrupt else 2)
    assert not (project / "fresh").exists()


def test_a_page_that_cannot_be_built_is_a_warning_and_the_trajectory_is_written(tmp_path: Path) -> None:
    urdf = ROBOT_URDF.read_text()
    box = '<cylinder radius="0.089145" length="0.4"/>'
    assert box in urdf
    (tmp_path / "no_mesh.urdf").write_text(urdf.replace(box, '<mesh filename="meshes/base_missing.stl"/>', 1))
    task = _task(tmp_path, robot="no_mesh.urdf")
    code, out, err = _plan(task, tmp_path / "out")
    assert code == 0, err
    assert sorted(p.name for p in (tmp_path / "out").iterdir()) == ["report.html", "trajectory.csv",
                                                                     "trajectory.json"]
    assert err.startswith("singplan: warning: replay.html not written") and "base_missing.stl" in err
    assert "not written: replay.html" in out and "base_missing.stl" in out


def test_a_report_that_fails_unexpectedly_is_a_warning(tmp_path: Path, monkeypatch) -> None:
    def broken(*args: object) -> str:
        raise ZeroDivisionError("in a plot")

    monkeypatch.setattr("singplan.outputs.report.report_html", broken)
    code, _, err = _plan(_task(tmp_path), tmp_path / "out", "--no-replay", "--quiet")
    assert code == 0
    assert "report.html not written" in err and "ZeroDivisionError: in a plot" in err
    assert sorted(p.name for p in (tmp_path / "out").iterdir()) == ["trajectory.csv", "trajectory.json"]


def test_replay_html_follows_the_same_rules(tmp_path: Path, monkeypatch) -> None:
    code, _, err = _plan(_task(tmp_path), tmp_path / "out", "--no-report", "--no-replay")
    assert code == 0, err
    (tmp_path / "a_file").write_text("keep me\n")
    too_long = tmp_path / ("a" * 300 + ".html")  # the file system refuses the name: bad input, not a crash
    for target in (tmp_path / "out", tmp_path / "a_file" / "x.html", "", "/proc/singplan-x/r.html", too_long):
        stderr = io.StringIO()
        assert main(["replay", str(tmp_path / "out"), "--html", str(target)], out=io.StringIO(), err=stderr) == 2
        assert str(target) in stderr.getvalue()
    page = tmp_path / "pages" / "deep" / "r.html"  # missing parents are created
    assert main(["replay", str(tmp_path / "out"), "--html", str(page)], out=io.StringIO()) == 0
    assert page.stat().st_size > 100_000
    (tmp_path / "link.html").symlink_to(page)  # a link to a file: the file is rewritten, the link kept
    page.write_text("old")
    assert main(["replay", str(tmp_path / "out"), "--html", str(tmp_path / "link.html")], out=io.StringIO()) == 0
    assert (tmp_path / "link.html").is_symlink() and page.stat().st_size > 100_000

    def interrupted(*args: object) -> str:
        raise KeyboardInterrupt

    monkeypatch.setattr("singplan.outputs.viewer.replay_html", interrupted)
    stderr = io.StringIO()
    assert main(["replay", str(tmp_path / "out"), "--html", str(tmp_path / "new" / "r.html")], err=stderr) == 130
    assert stderr.getvalue() == "singplan: interrupted\n"
    assert not (tmp_path / "new").exists()
    assert [p.name for p in tmp_path.rglob(".*")] == []  # no temporary or backup file anywhere


def test_save_streams_the_same_bytes_as_one_json_dump_and_load_keeps_the_series(tmp_path: Path) -> None:
    traj = _synthetic(10_000)  # more than two writing chunks
    stream = io.StringIO()
    write_json(stream, traj)
    assert stream.getvalue() == json.dumps(traj.to_json())
    stream = io.StringIO()
    write_csv(stream, traj)
    header, *rows = stream.getvalue().splitlines()
    assert header == "t," + ",".join(traj.joint_names)
    # every number its shortest round-trip text, read back exactly
    assert rows == [",".join(repr(v) for v in row) for row in np.hstack([traj.t[:, None], traj.q]).tolist()]
    folder = save(traj, tmp_path / "out")
    again = load(folder)
    for name, series in traj.samples.items():
        np.testing.assert_allclose(again.samples[name], series, rtol=1e-12, atol=1e-18)
    np.testing.assert_array_equal(again.q, traj.q)


@pytest.mark.slow  # tracemalloc traces every allocation of a 20 000-sample save
def test_saving_needs_little_memory_beyond_the_arrays(tmp_path: Path, monkeypatch) -> None:
    monkeypatch.setattr(trajectory_module, "_CHUNK_ROWS", 512)  # small chunks: the fixed part stays small
    traj = _synthetic(20_000)
    arrays_bytes = sum(a.nbytes for a in (traj.t, traj.q, traj.qd, traj.qdd, *traj.samples.values()))
    tracemalloc.start()
    try:
        save(traj, tmp_path / "out")
        peak_bytes = tracemalloc.get_traced_memory()[1]
    finally:
        tracemalloc.stop()
    # the per-sample series in file units (5 of the 22 columns) and a few MiB of chunks; one json.dumps took ~10x
    assert peak_bytes < 0.25 * arrays_bytes + 2**20, (peak_bytes, arrays_bytes)


def _synthetic(samples: int) -> Trajectory:
    rng = np.random.default_rng(11)
    t = np.arange(samples) * 0.004
    q = rng.uniform(-3, 3, (samples, 6))
    series = {"position_error_m": rng.uniform(0, 1e-5, samples), "orientation_error_rad": rng.uniform(0, 1e-4, samples),
              "distances": rng.uniform(0, 1, (samples, 3))}
    task = Task("r", (Move("ptp", to_joints_deg=(0.0,) * 6),), start_joints_deg=(0.0,) * 6)
    return Trajectory("r", "/r.urdf", "tool0", {"xyz": [0, 0, 0], "rpy_deg": [0, 0, 0]}, task,
                      tuple(f"j{i}" for i in range(6)), 0.004, t, q, q * 2, q * 3, (), (),
                      replace(Metrics.of_samples(float(t[-1]), samples), max_position_error_mm=float("nan")), series)


@pytest.mark.parametrize("error", [RuntimeError("boom\nsecond line"), RecursionError("maximum recursion depth"),
                                   MemoryError(), OverflowError("int too large to convert to float")])
def test_an_unexpected_exception_is_one_line_and_exit_1(tmp_path: Path, monkeypatch, error: Exception) -> None:
    def explode(*args: object) -> None:
        raise error

    monkeypatch.setattr("singplan.task.load.load_task", explode)
    monkeypatch.delenv("SINGPLAN_DEBUG", raising=False)
    stderr = io.StringIO()
    assert main(["plan", str(_task(tmp_path)), "-o", str(tmp_path / "o")], out=io.StringIO(), err=stderr) == 1
    text = stderr.getvalue()
    assert text.count("\n") == 1 and "Traceback" not in text
    assert text.startswith(f"singplan: internal error: {type(error).__name__}: ")
    assert "please report this; run with SINGPLAN_DEBUG=1 for the traceback" in text
    monkeypatch.setenv("SINGPLAN_DEBUG", "1")
    stderr = io.StringIO()
    assert main(["plan", str(_task(tmp_path)), "-o", str(tmp_path / "o")], out=io.StringIO(), err=stderr) == 1
    assert "Traceback" in stderr.getvalue()


def test_an_interrupt_is_one_line_and_exit_130(tmp_path: Path, monkeypatch) -> None:
    def interrupted(*args: object, **kwargs: object) -> None:
        raise KeyboardInterrupt

    monkeypatch.setattr("singplan.entry.planned_trajectory", interrupted)  # the stage `singplan plan` runs
    stderr = io.StringIO()
    assert main(["plan", str(_task(tmp_path)), "-o", str(tmp_path / "o")], out=io.StringIO(), err=stderr) == 130
    assert stderr.getvalue() == "singplan: interrupted\n"
    assert sorted(p.name for p in tmp_path.iterdir()) == ["task.yaml"]


@pytest.mark.skipif(not os.path.exists("/proc/net/tcp"), reason="reads Linux's socket tables")
def test_replay_serve_listens_on_loopback_only(replay_server: ReplayServer) -> None:
    line = replay_server.line
    assert line.startswith("replay served at http://127.0.0.1:"), line + replay_server.errors()
    web_port = int(line.split(":")[2].split("/")[0])
    opened = {port: addresses for port, addresses in replay_server.ports_serving.items()
              if port not in replay_server.ports_before}
    assert web_port in opened
    loopback = {"0100007F", "00000000000000000000000001000000"}  # 127.0.0.1 and ::1
    assert all(addresses <= loopback for addresses in opened.values()), opened
    # that SIGTERM stops this server with exit 0 is checked in tests/test_plan.py (the same server)


def test_replay_host_that_cannot_be_served_is_bad_input(tmp_path: Path) -> None:
    code, _, err = _plan(_task(tmp_path), tmp_path / "out", "--no-report", "--no-replay")
    assert code == 0, err
    stderr = io.StringIO()
    assert main(["replay", str(tmp_path / "out"), "--serve", "--host", "192.0.2.1"], err=stderr) == 2  # TEST-NET
    assert "192.0.2.1" in stderr.getvalue()
    stderr = io.StringIO()
    assert main(["replay", str(tmp_path / "out"), "--html", str(tmp_path / "r.html"), "--host", "::1"],
                err=stderr) == 2
    assert "--host goes with --serve" in stderr.getvalue()


def test_write_files_is_all_or_nothing_for_any_writer(tmp_path: Path) -> None:
    (tmp_path / "a.txt").write_text("old a")

    def fails(stream: io.TextIOBase) -> None:
        raise ValueError("half way")

    with pytest.raises(ValueError, match="half way"):
        outputs.write_files(tmp_path, {"a.txt": outputs.text_writer("new a"), "b.txt": fails})
    assert _listing(tmp_path) == {"a.txt": b"old a"}
    outputs.write_files(tmp_path, {"a.txt": outputs.text_writer("new a"), "b.txt": outputs.text_writer("b")})
    assert _listing(tmp_path) == {"a.txt": b"new a", "b.txt": b"b"}
    assert oct((tmp_path / "b.txt").stat().st_mode & 0o777) == oct(0o666 & ~_umask())
    (tmp_path / "c.txt").mkdir()  # a folder where a file goes: refused before anything is renamed
    with pytest.raises(OutputPathError, match=r"c\.txt is a folder"):
        outputs.write_files(tmp_path, {"a.txt": outputs.text_writer("newer a"), "c.txt": outputs.text_writer("c")})
    assert _listing(tmp_path) == {"a.txt": b"new a", "b.txt": b"b", "c.txt": None}


def _umask() -> int:
    mask = os.umask(0o022)
    os.umask(mask)
    return mask


def test_output_files_are_the_contracts_four_and_plan_into_checks_only_those_asked_for() -> None:
    assert set(OUTPUT_FILES) == OURS and len(OUTPUT_FILES) == len(OURS)
    copies = ("trajectory.urdf", "trajectory.srdf")
    assert output_names(report=False, replay=False) == ("trajectory.csv", "trajectory.json", *copies)
    assert output_names(report=False, replay=True) == ("trajectory.csv", "trajectory.json", *copies, "replay.html")


def test_temporary_files_a_killed_writer_left_are_removed_and_nothing_else(tmp_path: Path) -> None:
    seen: list[str] = []

    def peek(stream: io.TextIOBase) -> None:  # the real writer's temporary name, while it exists
        seen.extend(p.name for p in tmp_path.iterdir() if p.name.startswith(".") and p.name != outputs.LOCK_NAME)

    outputs.write_files(tmp_path, {"trajectory.json": peek})
    assert len(seen) == 1 and seen[0].startswith(".trajectory.json.")
    assert not (tmp_path / outputs.LOCK_NAME).exists()  # the writer's lock went with it
    (tmp_path / seen[0]).write_text("half a file")  # as if the writer had been killed before its rename
    (tmp_path / ".summary.csv.x1y2.singplan-tmp").write_text("not one of the names given")
    (tmp_path / "mine.txt").write_text("keep")
    outputs.remove_temporary_files(tmp_path, OUTPUT_FILES)
    assert sorted(p.name for p in tmp_path.iterdir()) == [".summary.csv.x1y2.singplan-tmp", "mine.txt",
                                                         "trajectory.json"]


def test_a_urdf_without_visuals_gets_a_replay_and_a_warning_that_says_so(tmp_path: Path) -> None:
    """SCORBOT's URDF has no <visual>: the replay is written (paths only) and the CLI says why it
    shows no robot, on stderr, instead of a page that looks broken."""
    urdf = Path(__file__).parent / "data" / "five_scorbot_er4u.urdf"
    task = tmp_path / "t.yaml"
    task.write_text(yaml.safe_dump({"robot": str(urdf), "start": {"pose": {"xyz": [0.40, -0.10, 0.15],
                                                                            "rpy_deg": [180, 0, 0]}},
                                    "moves": [{"lin": {"to": {"xyz": [0.40, 0.0, 0.15]}, "speed": 0.1}}]}))
    out, err = io.StringIO(), io.StringIO()
    assert main(["plan", str(task), "-o", str(tmp_path / "o"), "--no-report", "--quiet"], out, err) == 0
    assert f"singplan: warning: replay: {urdf} has no <visual> geometry" in err.getvalue()
    assert (tmp_path / "o" / "replay.html").stat().st_size > 0
    err = io.StringIO()  # a URDF with visuals: no such warning
    demo = Path(__file__).parent.parent / "singplan" / "demo_task.yaml"
    assert main(["plan", str(demo), "-o", str(tmp_path / "d"), "--no-report", "--quiet"], io.StringIO(), err) == 0
    assert "warning" not in err.getvalue()
