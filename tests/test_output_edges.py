"""Outputs written correctly and one run per output folder (issue 22).

* Joint names of any characters survive trajectory.csv and the degree CSV: read back by Python's
  csv module, every row has the header's width and the header gives the names (hypothesis).
* The ROS 2 export checks its numbers against the message types: a time_from_start past int32
  seconds is refused naming ``t``, not written wrong; ``ik --seed-deg nan`` exits 2 naming the option.
* A folder another run holds (plan, replay --html, export, batch) is refused naming it; the files
  a killed run left (its own temporary names and lock only) are removed by the next run; two real
  runs at once never leave a mixed set of files.
* ``replay --serve`` warns on a host that is not loopback, and its meshcat server dies with it even
  when it is killed with SIGKILL.
"""

from __future__ import annotations

import csv
import io
import json
import os
import signal
import subprocess
import sys
import time
from collections.abc import Iterator
from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest
import yaml
from hypothesis import given, settings
from hypothesis import strategies as st

from singplan.cli import main
from singplan.errors import InputError
from singplan.outputs import exports
from singplan.outputs.viewer import is_loopback
from singplan.results import files
from singplan.results.metrics import Metrics
from singplan.results.trajectory import Trajectory, load, save, write_csv
from singplan.task.schema import Move, Task

from .conftest import listening_ports

ROOT = Path(__file__).resolve().parents[1]
START_DEG = [10, -80, 95, 20, 40, 0]
TARGET = {"xyz": [0.55, -0.08, 0.66], "rpy_deg": [-157.09, 31.93, -172.02]}  # ~40 mm from the start


def _synthetic(names: tuple[str, ...], samples: int = 5, period: float = 0.004) -> Trajectory:
    t = np.arange(samples) * period
    q = np.linspace(0.0, 1.0, samples * len(names)).reshape(samples, len(names))
    zeros = (0.0,) * len(names)
    task = Task("r", (Move("ptp", to_joints_deg=zeros),), start_joints_deg=zeros)
    return Trajectory("r", "/r.urdf", "tool0", {"xyz": [0, 0, 0], "rpy_deg": [0, 0, 0]}, task, names, period,
                      t, q, q * 0.5, q * 0.25, (), (), Metrics.of_samples(float(t[-1]), samples))


def _read_csv(text: str) -> list[list[str]]:
    return list(csv.reader(io.StringIO(text, newline="")))


NAMES = st.lists(st.text(st.characters(blacklist_categories=("Cs",)), min_size=1, max_size=12), min_size=1,
                 max_size=7, unique=True)


@settings(max_examples=60, deadline=None, derandomize=True, database=None)
@given(names=NAMES)
def test_joint_names_of_any_characters_are_quoted_in_both_csvs(names: list[str]) -> None:
    traj = _synthetic(tuple(names))
    stream = io.StringIO(newline="")
    write_csv(stream, traj)
    rows = _read_csv(stream.getvalue())
    assert rows[0] == ["t", *names]
    assert {len(row) for row in rows} == {1 + len(names)} and len(rows) == 1 + len(traj.t)
    np.testing.assert_array_equal(np.array(rows[1:], dtype=float)[:, 1:], traj.q)  # %.17g: exact
    rows = _read_csv(exports.to_csv_deg(traj))
    assert rows[0] == ["t [s]", *(f"{n} [deg]" for n in names), *(f"{n} [deg/s]" for n in names)]
    assert {len(row) for row in rows} == {1 + 2 * len(names)}


def test_printable_joint_names_round_trip_through_trajectory_json(tmp_path: Path) -> None:
    names = ('a,1', 'b"2', "c;3", "d 4", "é5", "f'6")
    again = load(save(_synthetic(names), tmp_path / "out"))
    assert again.joint_names == names
    assert _read_csv((tmp_path / "out" / "trajectory.csv").read_text())[0] == ["t", *names]


def test_a_planned_urdf_with_awkward_joint_names_gives_a_readable_csv(tmp_path: Path) -> None:
    urdf = (ROOT / "robots" / "urdf" / "kuka_kr6_r900_2.urdf").read_text()
    names = ['j,1', 'j"2', "j 3", "jé4", "j;5", "j'6"]
    for k, name in enumerate(names, start=1):
        urdf = urdf.replace(f'"joint_{k}"', '"' + name.replace('"', "&quot;") + '"')
    (tmp_path / "arm.urdf").write_text(urdf)
    (tmp_path / "task.yaml").write_text(yaml.safe_dump({"robot": "arm.urdf", "tip": "tool0",
                                                        "start": {"joints_deg": START_DEG},
                                                        "moves": [{"lin": {"to": TARGET, "speed": 0.25}}]}))
    out = tmp_path / "out"
    assert main(["plan", str(tmp_path / "task.yaml"), "-o", str(out), "--quiet", "--no-report", "--no-replay"]) == 0
    rows = _read_csv((out / "trajectory.csv").read_text())
    assert rows[0] == ["t", *names] and {len(row) for row in rows} == {7}
    assert main(["export", str(out), "--format", "csv-deg"]) == 0
    assert _read_csv((out / "trajectory_deg.csv").read_text())[0][1:7] == [f"{n} [deg]" for n in names]


@pytest.mark.parametrize(("t_end", "ok"), [(2**31 - 1 + 0.999, True), (2**31 + 0.0, False), (3e9, False)])
def test_the_ros2_export_keeps_time_from_start_inside_int32_seconds(tmp_path: Path, t_end: float, ok: bool) -> None:
    base = _synthetic(("a", "b"), samples=3)
    traj = replace(base, t=np.array([0.0, 1.0, t_end]))
    for fmt in ("ros2", "ros2-json"):
        target = tmp_path / f"x.{fmt}"
        if ok:
            exports.export(traj, fmt, target)
            text = target.read_text()
            assert "2147483647" in text and "999000" in text
        else:
            with pytest.raises(InputError, match=r"t\[2\]: .* beyond what a ROS 2 Duration holds \(sec is an int32"):
                exports.export(traj, fmt, target)
            assert not target.exists()


@pytest.mark.parametrize(("seed", "words"), [(["nan", "0", "0", "0", "0", "0"], "--seed-deg[0]: must be finite"),
                                             (["0", "0", "1e300", "0", "0", "0"], "--seed-deg[2]: must be at most"),
                                             (["0", "0"], "--seed-deg: expected 6 numbers, got 2")])
def test_ik_seed_must_be_finite_joint_values(seed: list[str], words: str) -> None:
    err = io.StringIO()
    assert main(["ik", "abb_irb2400", "--xyz", "1", "0", "1", "--seed-deg", *seed], out=io.StringIO(), err=err) == 2
    assert words in err.getvalue() and "Traceback" not in err.getvalue()


# --- one run per folder --------------------------------------------------------------------------------

def _task(folder: Path, name: str = "task.yaml", speed: float = 0.25) -> Path:
    path = folder / name
    path.write_text(yaml.safe_dump({"robot": "kuka_kr6_r900_2", "tip": "tool0", "start": {"joints_deg": START_DEG},
                                    "moves": [{"lin": {"to": TARGET, "speed": speed}}]}))
    return path


@pytest.fixture
def holder(tmp_path: Path) -> Iterator[tuple[Path, subprocess.Popen[str]]]:
    """Another process holding tmp_path/out (as a run writing there would), until the test ends."""
    folder = tmp_path / "out"
    code = ("import sys; from singplan.results.files import hold_output_folder\n"
            f"with hold_output_folder({str(folder)!r}):\n    print('held', flush=True); sys.stdin.read()")
    proc = subprocess.Popen([sys.executable, "-c", code], stdin=subprocess.PIPE, stdout=subprocess.PIPE, text=True,
                            env={**os.environ, "PYTHONPATH": str(ROOT)})
    assert proc.stdout is not None and proc.stdout.readline().strip() == "held"
    try:
        yield folder, proc
    finally:
        proc.kill()
        proc.wait()
        for pipe in (proc.stdin, proc.stdout):
            assert pipe is not None
            pipe.close()


def test_a_folder_another_run_holds_is_refused_by_every_writer(tmp_path: Path, planned_kuka: Path,
                                                               holder: tuple[Path, subprocess.Popen[str]]) -> None:
    folder, proc = holder
    (folder / "notes.txt").write_text("keep")
    before = sorted(p.name for p in folder.iterdir())
    runs = [["plan", str(_task(tmp_path)), "-o", str(folder), "--quiet"],
            ["replay", str(planned_kuka), "--html", str(folder / "replay.html")],
            ["export", str(planned_kuka), "--format", "ros2", "-o", str(folder / "x.yaml")],
            ["batch", str(_task(tmp_path)), "-o", str(folder), "--quiet", "--workers", "1"]]
    for argv in runs:
        err = io.StringIO()
        assert main(argv, out=io.StringIO(), err=err) == 2, (argv, err.getvalue())
        assert f"output '{folder}': in use by another singplan run (process {proc.pid})" in err.getvalue()
    assert sorted(p.name for p in folder.iterdir()) == before  # nothing added, the holder's lock kept


def test_pages_and_exports_of_an_earlier_run_are_named_as_not_showing_this_plan(tmp_path: Path) -> None:
    """A rerun with --no-report into a folder with an earlier plan's pages and export warns, naming
    them (the folder keeps them: -o only adds or replaces); a rerun that writes everything does not."""
    folder, task = tmp_path / "out", _task(tmp_path)
    assert main(["plan", str(task), "-o", str(folder), "--quiet"], out=io.StringIO(), err=io.StringIO()) == 0
    (folder / "trajectory.ros2.yaml").write_text("earlier export")
    (folder / "notes.txt").write_text("the user's own")
    err = io.StringIO()
    assert main(["plan", str(task), "-o", str(folder), "--quiet", "--no-report"], out=io.StringIO(), err=err) == 0
    assert (f"singplan: warning: report.html, trajectory.ros2.yaml in {folder} are from an earlier run and do not "
            "show this plan") in err.getvalue(), err.getvalue()
    (folder / "trajectory.ros2.yaml").unlink()
    err = io.StringIO()
    assert main(["plan", str(task), "-o", str(folder), "--quiet", "--no-replay", "--no-report"],
                out=io.StringIO(), err=err) == 0
    assert "report.html, replay.html in" in err.getvalue() and "notes.txt" not in err.getvalue()
    err = io.StringIO()
    assert main(["plan", str(task), "-o", str(folder), "--quiet"], out=io.StringIO(), err=err) == 0
    assert "earlier run" not in err.getvalue(), err.getvalue()


def test_a_killed_run_leaves_nothing_the_next_run_does_not_remove(tmp_path: Path,
                                                                  holder: tuple[Path, subprocess.Popen[str]]) -> None:
    folder, proc = holder
    proc.kill()  # SIGKILL: the kernel releases its lock; its lock file and temporary files stay
    proc.wait()
    leftovers = [".trajectory.csv.k1l2m3.singplan-tmp", ".replay.html.x9y8.singplan-tmp",
                 ".singplan-probe.ab12.singplan-tmp"]
    others = [".summary.csv.x1y2.singplan-tmp", ".trajectory.csv.backup", "mine.txt"]
    for name in leftovers + others:
        (folder / name).write_text("a killed run's, or the user's")
    assert (folder / files.LOCK_NAME).exists()
    code = main(["plan", str(_task(tmp_path)), "-o", str(folder), "--quiet"], out=io.StringIO(), err=io.StringIO())
    assert code == 0
    assert sorted(p.name for p in folder.iterdir()) == sorted([*others, "replay.html", "report.html",
                                                               "trajectory.csv", "trajectory.json"])


def test_holding_is_reentrant_within_a_process_and_the_lock_goes_with_the_last_hold(tmp_path: Path) -> None:
    with files.hold_output_folder(tmp_path / "a" / "b") as folder:
        assert (folder / files.LOCK_NAME).read_text().strip() == str(os.getpid())
        files.write_files(folder, {"x.txt": files.text_writer("x")})  # nested: same process
        assert (folder / files.LOCK_NAME).exists()
    assert sorted(p.name for p in folder.iterdir()) == ["x.txt"]
    with pytest.raises(ZeroDivisionError), files.hold_output_folder(tmp_path / "c" / "d"):
        raise ZeroDivisionError
    assert not (tmp_path / "c").exists()  # what the failed run created is gone with it


@pytest.mark.slow  # two real plans in two processes, a few seconds each
def test_two_runs_at_once_never_mix_their_files(tmp_path: Path) -> None:
    """Two `singplan plan` processes of different tasks into one folder, started together five
    times: each pair either ran one after the other or one was refused (exit 2, folder named); the
    folder's trajectory.csv always has the samples of its trajectory.json."""
    folder = tmp_path / "out"
    tasks = [_task(tmp_path, "slow.yaml", 0.05), _task(tmp_path, "fast.yaml", 0.25)]
    refused = 0
    for _ in range(5):
        procs = [subprocess.Popen([sys.executable, "-m", "singplan", "plan", str(task), "-o", str(folder), "--quiet",
                                   "--no-report", "--no-replay"], stdout=subprocess.PIPE, stderr=subprocess.PIPE,
                                  text=True, env={**os.environ, "PYTHONPATH": str(ROOT)}) for task in tasks]
        results = [(p.wait(timeout=300), p.communicate()[1]) for p in procs]
        assert all(code in (0, 2) for code, _ in results) and any(code == 0 for code, _ in results), results
        for code, err in results:
            if code == 2:
                refused += 1
                assert "in use by another singplan run" in err and str(folder) in err
        samples = len(json.loads((folder / "trajectory.json").read_text())["t"])
        assert len((folder / "trajectory.csv").read_text().splitlines()) == samples + 1
        assert sorted(p.name for p in folder.iterdir()) == ["trajectory.csv", "trajectory.json"]
    print(f"{refused} of 10 runs refused while the other wrote")


# --- the live server -------------------------------------------------------------------------------------

@pytest.mark.parametrize(("host", "loopback"), [("127.0.0.1", True), ("::1", True), ("localhost", True),
                                                ("127.3.4.5", True), ("0.0.0.0", False), ("::", False),
                                                ("192.0.2.7", False), ("no such host.invalid", False)])
def test_loopback_hosts_are_told_apart(host: str, loopback: bool) -> None:
    assert is_loopback(host) == loopback


def test_serving_on_a_host_that_is_not_loopback_warns_first(planned_kuka: Path, monkeypatch) -> None:
    def stop(*args: object, **kwargs: object) -> None:
        raise KeyboardInterrupt  # the test stops before any server starts

    monkeypatch.setattr("singplan.outputs.viewer.replay", stop)
    for host, warned in (("0.0.0.0", True), ("127.0.0.1", False)):
        err = io.StringIO()
        assert main(["replay", str(planned_kuka), "--serve", "--host", host], out=io.StringIO(), err=err) == 130
        assert ("warning: --host 0.0.0.0 is not a loopback address" in err.getvalue()) == warned, err.getvalue()


@pytest.mark.slow  # starts a live server (a few seconds)
def test_a_sigkilled_replay_takes_its_server_with_it(planned_kuka: Path) -> None:
    before = listening_ports()
    proc = subprocess.Popen([sys.executable, "-m", "singplan", "replay", str(planned_kuka), "--serve"],
                            stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True,
                            env={**os.environ, "PYTHONPATH": str(ROOT)})
    assert proc.stdout is not None
    line = proc.stdout.readline()
    assert line.startswith("replay served at http://127.0.0.1:"), line + proc.communicate()[1]
    port = int(line.split(":")[2].split("/")[0])
    assert port in listening_ports() and port not in before
    proc.send_signal(signal.SIGKILL)
    proc.communicate()
    deadline = time.monotonic() + 10
    while port in listening_ports() and time.monotonic() < deadline:
        time.sleep(0.1)
    assert port not in listening_ports()  # meshcat's server saw its stdin close and exited
