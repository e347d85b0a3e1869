"""`singplan batch` and singplan.batch.plan_many: folders, summary, failures, crashes, Ctrl-C, Dask.

The local tasks are short LINs on the bundled KUKA KR 6 R900-2 (well under a second each). The
comparison with one-at-a-time planning uses public scenarios from ../shared (skipped when absent,
required under CI=true) and a Dask LocalCluster of two worker processes. Each worker process
imports singplan (seconds on a loaded machine): the tests that start worker processes or a Python
subprocess are marked slow (CI runs them: ``python -m pytest -q -m slow``).
"""

from __future__ import annotations

import csv
import dataclasses
import io
import json
import os
import signal
import subprocess
import sys
import time
from collections.abc import Iterator
from pathlib import Path

import numpy as np
import pytest
import yaml

from singplan import batch
from singplan.batch import TaskJob, TaskRecord, folder_names, make_jobs, plan_many, plan_task
from singplan.cli import main
from singplan.planning.orchestration import targets
from tests.cli_helpers import run_cli

START_DEG = [10, -80, 95, 20, 40, 0]
TARGET = {"xyz": [0.55, -0.08, 0.66], "rpy_deg": [-157.09, 31.93, -172.02]}  # ~40 mm from the start
SHARED = Path(__file__).resolve().parents[2] / "shared"
SCENARIOS = ["kuka_kr6_r900_2__wrist_near_lin", "fanuc_lrmate200id__wrist_circ", "fanuc_lrmate200id__tool_reorient",
             "abb_irb2400__wrist_exact_lin", "bad__nan_target", "fanuc_lrmate200id__unreachable_lin"]
SAME_TOL = 1e-12  # batch and one-at-a-time run the same code on the same input: equal to round-off at most


def _task(folder: Path, name: str, **lin: object) -> Path:
    move = {"to": TARGET, "speed": 0.25, **lin}
    doc = {"robot": "kuka_kr6_r900_2", "tip": "tool0", "start": {"joints_deg": START_DEG}, "moves": [{"lin": move}],
           "output": {"period": 0.004}}
    folder.mkdir(parents=True, exist_ok=True)
    path = folder / name
    path.write_text(yaml.safe_dump(doc))
    return path


def _summary(folder: Path) -> tuple[list[dict[str, str]], dict]:
    with (folder / "summary.csv").open(newline="") as f:
        rows = list(csv.DictReader(f))
    return rows, json.loads((folder / "summary.json").read_text())


def _hidden(folder: Path) -> list[Path]:
    return [p for p in folder.rglob(".*")]


# runners sent to worker processes: module level, so a worker can import them


def crash_or_plan(job: TaskJob) -> TaskRecord:
    """Kill the worker (as a segfault or the OOM killer would) on tasks named crash*, after a temporary file."""
    if Path(job.task).stem.startswith("crash"):
        Path(job.folder).mkdir(parents=True, exist_ok=True)
        (Path(job.folder) / ".trajectory.json.x1y2.singplan-tmp").write_text("half a file")
        os.kill(os.getpid(), signal.SIGKILL)
    return plan_task(job)


def plan_and_tell_pid(job: TaskJob) -> TaskRecord:
    record = plan_task(job)
    return dataclasses.replace(record, message=f"{record.message} pid {os.getpid()}")


def slow_unless_first(job: TaskJob) -> TaskRecord:
    """The first task plans; the others take long enough for the batch to be interrupted meanwhile."""
    if job.index > 0:
        time.sleep(60)
    return plan_task(job)


def test_folder_names_are_the_file_names_made_unique_in_order() -> None:
    tasks = ["a/cell.yaml", "b/cell.yaml", "cell-2.yaml", "c/CELL.yml", "summary.csv.yaml", "x.yaml"]
    assert folder_names(tasks) == ["cell", "cell-2", "cell-2-2", "CELL-3", "summary.csv-2", "x"]
    assert folder_names(list(reversed(tasks))) == ["x", "summary.csv-2", "CELL", "cell-2", "cell-3", "cell-4"]
    assert folder_names(["d/..yaml", "d/...yaml", "task.yaml"]) == ["task", "task-2", "task-3"]  # never . or ..


@pytest.mark.slow
def test_a_batch_plans_every_task_and_a_failing_one_stops_none(tmp_path: Path) -> None:
    good = [_task(tmp_path / "tasks", f"lin{i}.yaml", speed=0.1 * (i + 1)) for i in range(3)]
    bad = _task(tmp_path / "tasks", "bad.yaml", speed=-1)
    far = _task(tmp_path / "tasks", "far.yaml", to={"xyz": [3.0, 0.0, 0.5], "rpy_deg": [180, 0, 0]})
    same_name = _task(tmp_path / "tasks" / "other", "lin0.yaml", speed=0.3)
    out = tmp_path / "out"
    (out / "lin1").mkdir(parents=True)
    (out / "notes.txt").write_text("keep\n")
    (out / "lin1" / "mine.txt").write_text("keep too\n")
    tasks = [good[0], bad, good[1], far, good[2], same_name]
    code, stdout, stderr = run_cli("batch", *tasks, "-o", out, "--workers", "2", "--no-replay")
    assert code == 3, stderr  # the largest task exit code: 3 (no plan) over 2 (bad input)
    rows, doc = _summary(out)
    assert [r["task"] for r in rows] == [str(t) for t in tasks]  # the order given, whatever order they finished in
    assert [int(r["exit_code"]) for r in rows] == [0, 2, 0, 3, 0, 0]
    assert [r["folder"] for r in rows] == ["lin0", "bad", "lin1", "far", "lin2", "lin0-2"]
    assert "speed" in rows[1]["message"] and "move 0" in rows[3]["message"]
    assert doc["format"] == "singplan.batch/1" and doc["exit_code"] == 3 and not doc["interrupted"]
    for row, entry in zip(rows, doc["tasks"], strict=True):
        assert entry["exit_code"] == int(row["exit_code"]) and entry["robot"] == row["robot"]
        assert row["robot"] == ("" if entry["exit_code"] == 2 else "kuka_kr6_r900_2")  # a malformed task names none
        if entry["exit_code"] == 0:
            traj = json.loads((out / row["folder"] / "trajectory.json").read_text())
            assert entry["duration_s"] == pytest.approx(traj["t"][-1], abs=SAME_TOL)
            assert entry["crossings"] == len(traj["metrics"]["crossings"]) and entry["samples"] == len(traj["t"])
            assert sorted(p.name for p in (out / row["folder"]).iterdir() if p.name != "mine.txt") == [
                "report.html", "trajectory.csv", "trajectory.json"]
        else:
            assert entry["duration_s"] is None and row["duration_s"] == ""
    assert not (out / "bad").exists() and not (out / "far").exists()  # a failed task leaves no folder behind
    assert (out / "notes.txt").read_text() == "keep\n" and (out / "lin1" / "mine.txt").read_text() == "keep too\n"
    assert _hidden(out) == []
    assert [line.split("]")[0] for line in stderr.splitlines()] == [f"[{i}/6" for i in range(1, 7)]
    assert "6 task(s) (4 exit 0, 1 exit 2, 1 exit 3)" in stdout


@pytest.mark.slow
def test_quiet_prints_no_progress_and_all_planned_exits_0(tmp_path: Path) -> None:
    task = _task(tmp_path, "one.yaml")
    code, stdout, stderr = run_cli("batch", task, "-o", tmp_path / "out", "--workers", "1", "--quiet", "--no-report",
                                   "--no-replay")
    assert code == 0 and stderr == "" and stdout.startswith("batch done: 1 task(s) (1 exit 0)")


@pytest.mark.slow
def test_a_worker_that_dies_loses_only_its_task(tmp_path: Path) -> None:
    tasks = [_task(tmp_path, "crash.yaml"), _task(tmp_path, "a.yaml"), _task(tmp_path, "crash_again.yaml"),
             _task(tmp_path, "b.yaml"), _task(tmp_path, "crash_into_mine.yaml")]
    (tmp_path / "out" / "crash_into_mine").mkdir(parents=True)  # the user's empty folder: kept
    result = plan_many(tasks, tmp_path / "out", workers=2, report=False, replay=False, runner=crash_or_plan)
    codes = [r.exit_code for r in result.records]
    assert codes == [1, 0, 1, 0, 1] and result.exit_code == 1 and not result.interrupted
    for dead in (result.records[0], result.records[2], result.records[4]):
        assert "worker process died" in dead.message and "SIGKILL" in dead.message, dead.message
    assert sorted(p.name for p in (tmp_path / "out").iterdir()) == ["a", "b", "crash_into_mine", "summary.csv",
                                                                   "summary.json"]
    assert _hidden(tmp_path / "out") == []  # the dead worker's temporary file is removed, and its empty folder


@pytest.mark.slow
def test_a_worker_killed_between_tasks_costs_no_task(tmp_path: Path) -> None:
    tasks = [_task(tmp_path, f"t{i}.yaml") for i in range(3)]

    def kill_the_worker(record: TaskRecord, done: int, total: int) -> None:
        if done == 1:  # the worker that planned it is idle now, waiting for the next task
            os.kill(int(record.message.split(" pid ")[1]), signal.SIGKILL)

    result = plan_many(tasks, tmp_path / "out", workers=1, report=False, replay=False, progress=kill_the_worker,
                       runner=plan_and_tell_pid)
    assert [r.exit_code for r in result.records] == [0, 0, 0], result.records
    assert len({r.message for r in result.records}) == 2  # the first worker's pid, then its replacement's


@pytest.mark.slow
def test_ctrl_c_stops_the_workers_and_writes_the_summary_of_what_finished(tmp_path: Path) -> None:
    tasks = [_task(tmp_path, f"t{i}.yaml") for i in range(4)]

    def interrupt(record: TaskRecord, done: int, total: int) -> None:
        raise KeyboardInterrupt  # as Ctrl-C arriving once the first task has finished

    started = time.perf_counter()
    result = plan_many(tasks, tmp_path / "out", workers=2, report=False, replay=False, progress=interrupt,
                       runner=slow_unless_first)
    assert time.perf_counter() - started < 30  # the sleeping worker was stopped, not waited for
    assert result.interrupted and result.exit_code == 130
    assert [r.exit_code for r in result.records] == [0, 130, 130, 130]
    rows, doc = _summary(tmp_path / "out")
    assert doc["interrupted"] and [r["exit_code"] for r in rows] == ["0", "130", "130", "130"]
    assert "interrupted" in rows[1]["message"]
    assert sorted(p.name for p in (tmp_path / "out").iterdir()) == ["summary.csv", "summary.json", "t0"]


@pytest.mark.slow
def test_a_real_sigint_to_the_process_group_stops_every_process(tmp_path: Path) -> None:
    """Ctrl-C in a terminal signals the batch and its workers at once: the workers ignore it and are stopped."""
    tasks = [str(_task(tmp_path, f"t{i}.yaml")) for i in range(3)]
    code = ("import sys; from singplan.batch import plan_many; from tests.test_batch import slow_unless_first; "
            "r = plan_many(sys.argv[1:-1], sys.argv[-1], workers=2, report=False, replay=False, "
            "runner=slow_unless_first, progress=lambda rec, d, t: print('finished', d, flush=True)); "
            "print('exit', r.exit_code, flush=True)")
    # as from a terminal: a shell's background job (CI runners) starts with SIGINT ignored, which a
    # Python child inherits and then never sees Ctrl-C
    run = subprocess.Popen([sys.executable, "-c", code, *tasks, str(tmp_path / "out")], stdout=subprocess.PIPE,
                           text=True, start_new_session=True, cwd=Path(__file__).resolve().parents[1],
                           preexec_fn=lambda: signal.signal(signal.SIGINT, signal.SIG_DFL))
    assert run.stdout is not None
    assert run.stdout.readline() == "finished 1\n"  # t0 planned; t1 is sleeping in the other worker
    os.killpg(run.pid, signal.SIGINT)
    assert run.communicate(timeout=60)[0] == "exit 130\n"
    rows, _ = _summary(tmp_path / "out")
    assert [r["exit_code"] for r in rows] == ["0", "130", "130"] and _hidden(tmp_path / "out") == []
    deadline = time.monotonic() + 10
    while _group_alive(run.pid) and time.monotonic() < deadline:
        time.sleep(0.1)
    assert not _group_alive(run.pid), "a worker or the fork server outlived the batch"


def _group_alive(pgid: int) -> bool:
    try:
        os.killpg(pgid, 0)
    except ProcessLookupError:
        return False
    return True


def test_batch_level_bad_input_exits_2_and_creates_nothing(tmp_path: Path, monkeypatch) -> None:
    task = _task(tmp_path / "tasks", "a.yaml")
    out = tmp_path / "out"
    code, _, err = run_cli("batch", task, str(task), "-o", out)
    assert code == 2 and "given twice" in err
    code, _, err = run_cli("batch", task, "-o", out, "--workers", "0")
    assert code == 2 and "workers" in err
    code, _, err = run_cli("batch", task, "-o", out, "--workers", "2", "--scheduler", "tcp://127.0.0.1:1")
    assert code == 2 and "not allowed with" in err  # argparse's own message, on main's err as every other
    (tmp_path / "file").write_text("x")
    code, _, err = run_cli("batch", task, "-o", tmp_path / "file")
    assert code == 2 and "is not a folder" in err
    monkeypatch.setitem(sys.modules, "distributed", None)  # as if Dask were not installed
    code, _, err = run_cli("batch", task, "-o", out, "--scheduler", "tcp://127.0.0.1:8786")
    assert code == 2 and "pip install 'dask[distributed]'" in err and err.count("\n") == 1, err
    assert not out.exists()


@pytest.mark.slow
def test_plain_batch_does_not_import_dask(tmp_path: Path) -> None:
    task = _task(tmp_path, "a.yaml")
    code = ("import sys; from singplan.cli import main; "
            f"c = main(['batch', {str(task)!r}, '-o', {str(tmp_path / 'out')!r}, '--workers', '1', '--quiet', "
            "'--no-report', '--no-replay']); print(c, sorted(m for m in sys.modules if m.split('.')[0] in "
            "('dask', 'distributed')))")
    run = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=300)
    assert run.stdout.splitlines()[-1] == "0 []", run.stdout + run.stderr


@pytest.mark.slow
def test_a_script_read_from_stdin_can_run_a_batch(tmp_path: Path) -> None:
    """Workers are normally started from a server that re-imports the main script; stdin cannot be re-read."""
    task = _task(tmp_path, "a.yaml")
    script = ("from singplan.batch import plan_many\n"
              f"r = plan_many([{str(task)!r}], {str(tmp_path / 'out')!r}, workers=1, report=False, replay=False)\n"
              "print(r.records[0].exit_code, r.records[0].message)\n")
    run = subprocess.run([sys.executable, "-"], input=script, capture_output=True, text=True, timeout=300)
    assert run.stdout == "0 planned\n", run.stdout + run.stderr[-2000:]


@pytest.mark.slow
def test_workers_that_cannot_start_stop_the_batch_with_a_clear_message(tmp_path: Path) -> None:
    """A script without the `__main__` guard: each worker re-runs it and dies; no task can run anywhere."""
    tasks = [str(_task(tmp_path, f"{n}.yaml")) for n in "abc"]
    script = tmp_path / "unguarded.py"
    script.write_text("from singplan.batch import plan_many\n"
                      f"r = plan_many({tasks!r}, {str(tmp_path / 'out')!r}, workers=2, report=False, replay=False)\n"
                      "print(r.exit_code, sorted({(x.exit_code, x.message) for x in r.records}))\n")
    run = subprocess.run([sys.executable, str(script)], capture_output=True, text=True, timeout=300)
    code, reasons = run.stdout.split(" ", 1)
    assert code == "1" and "[(1, 'not run: a worker process could not start (exit status 1)" in reasons, run.stdout
    assert "__main__" in reasons
    assert sorted(p.name for p in (tmp_path / "out").iterdir()) == ["summary.csv", "summary.json"]


# --- the same results as one at a time: public scenarios, local workers and Dask ------------------


def _require(what: str, present: bool, reason: str) -> None:
    if not present:
        if os.environ.get("CI") == "true":
            raise RuntimeError(f"CI=true but {what} is missing: {reason}")
        pytest.skip(reason)


@pytest.fixture(scope="module")
def scenarios() -> list[Path]:
    _require("../shared", (SHARED / "scenarios").is_dir(), f"no shared scenarios at {SHARED} (not in a user's clone)")
    return [SHARED / "scenarios" / f"{name}.yaml" for name in SCENARIOS]


@pytest.fixture(scope="module")
def one_at_a_time(scenarios: list[Path], tmp_path_factory: pytest.TempPathFactory) -> dict[str, tuple[int, Path]]:
    """Each scenario planned alone by `singplan plan`: its exit code and folder."""
    root = tmp_path_factory.mktemp("sequential")
    results = {}
    for task in scenarios:
        out, err = io.StringIO(), io.StringIO()
        code = main(["plan", str(task), "-o", str(root / task.stem), "--quiet", "--no-report", "--no-replay"],
                    out=out, err=err)
        results[task.stem] = (code, root / task.stem)
    return results


@pytest.fixture(scope="module")
def dask_cluster() -> Iterator[str]:
    try:
        import dask
        from distributed import LocalCluster
    except ImportError:
        _require("Dask", False, "dask[distributed] is not installed (pip install 'singplan[batch]')")
    # a task whose worker dies fails at once instead of being run again on another worker (Dask's default: 3 more)
    with dask.config.set({"distributed.scheduler.allowed-failures": 0}), \
            LocalCluster(n_workers=2, processes=True, threads_per_worker=1, dashboard_address=None) as cluster:
        yield cluster.scheduler_address


def _check_same(result: batch.BatchResult, one_at_a_time: dict[str, tuple[int, Path]]) -> None:
    assert [r.task for r in result.records] == [str(SHARED / "scenarios" / f"{n}.yaml") for n in SCENARIOS]
    for record in result.records:
        code, alone = one_at_a_time[Path(record.task).stem]
        assert record.exit_code == code, (record.task, record.message)
        if code != 0:
            continue
        mine = json.loads((result.out_dir / record.folder / "trajectory.json").read_text())
        theirs = json.loads((alone / "trajectory.json").read_text())
        assert record.duration_s == pytest.approx(theirs["t"][-1], abs=SAME_TOL)
        assert mine["t"][-1] == pytest.approx(theirs["t"][-1], abs=SAME_TOL)
        q_mine, q_theirs = np.asarray(mine["q"]), np.asarray(theirs["q"])
        assert q_mine.shape == q_theirs.shape, record.task
        np.testing.assert_allclose(q_mine, q_theirs, rtol=0, atol=SAME_TOL, err_msg=record.task)
    assert sorted(r.exit_code for r in result.records) == [0, 0, 0, 0, 2, 3]


@pytest.mark.slow
def test_two_local_workers_give_the_same_results_as_one_at_a_time(scenarios: list[Path], one_at_a_time,
                                                                  tmp_path: Path) -> None:
    result = plan_many(scenarios, tmp_path / "out", workers=2, report=False, replay=False)
    _check_same(result, one_at_a_time)
    assert result.exit_code == 3


@pytest.mark.slow
def test_a_dask_cluster_gives_the_same_results_as_one_at_a_time(scenarios: list[Path], one_at_a_time,
                                                                dask_cluster: str, tmp_path: Path) -> None:
    code, _, err = run_cli("batch", *scenarios, "-o", tmp_path / "out", "--scheduler", dask_cluster, "--no-report",
                           "--no-replay")
    assert code == 3, err
    _, doc = _summary(tmp_path / "out")
    records = tuple(TaskRecord(**entry) for entry in doc["tasks"])
    _check_same(batch.BatchResult(tmp_path / "out", records, False, doc["wall_s"]), one_at_a_time)


@pytest.mark.slow
def test_a_dask_worker_that_dies_loses_only_its_task(dask_cluster: str, tmp_path: Path) -> None:
    tasks = [_task(tmp_path, "crash.yaml"), _task(tmp_path, "a.yaml")]
    result = plan_many(tasks, tmp_path / "out", scheduler=dask_cluster, report=False, replay=False,
                       runner=crash_or_plan)
    assert [r.exit_code for r in result.records] == [1, 0], result.records
    assert "worker process died" in result.records[0].message
    assert _hidden(tmp_path / "out") == []


def test_an_unreachable_scheduler_is_bad_input(tmp_path: Path, monkeypatch) -> None:
    pytest.importorskip("distributed")
    monkeypatch.setattr(batch, "CONNECT_TIMEOUT_S", 1.0)
    code, _, err = run_cli("batch", _task(tmp_path, "a.yaml"), "-o", tmp_path / "out", "--scheduler", "tcp://127.0.0.1:9")
    assert code == 2 and "cannot connect" in err, err
    assert not (tmp_path / "out").exists()


def test_a_memory_warning_when_the_workers_budgets_exceed_the_machine() -> None:
    total_gb = os.sysconf("SC_PAGE_SIZE") * os.sysconf("SC_PHYS_PAGES") / 2**30
    assert batch.memory_warning(1) is None or total_gb < 1.5
    many = int(total_gb / 1.5) + 2  # their 1.5 GB budgets add up to more than the machine has
    warning = batch.memory_warning(many)
    assert warning is not None and f"{many} x 1500 MB" in warning and "--workers" in warning


# plan_task in this process: the one task pipeline `singplan plan` runs, and its record


def _job(tmp_path: Path, task: Path, report: bool = True, replay: bool = False) -> TaskJob:
    return make_jobs([task], tmp_path / "out", report=report, replay=replay)[0]


def test_plan_task_loads_the_robot_once_and_writes_what_singplan_plan_writes(tmp_path: Path, monkeypatch) -> None:
    loads: list[str] = []
    real_load = targets.load_robot

    def counting(name: str, **kwargs: object) -> object:
        loads.append(name)
        return real_load(name, **kwargs)

    monkeypatch.setattr(targets, "load_robot", counting)
    task = _task(tmp_path, "lin.yaml")
    record = plan_task(_job(tmp_path, task))
    assert record.exit_code == 0, record.message
    assert loads == ["kuka_kr6_r900_2"]  # planning and the report share the robot the plan loaded
    out, err = io.StringIO(), io.StringIO()
    assert main(["plan", str(task), "-o", str(tmp_path / "alone"), "--quiet", "--no-replay"], out=out, err=err) == 0
    assert sorted(p.name for p in (tmp_path / "out" / "lin").iterdir()) == sorted(
        p.name for p in (tmp_path / "alone").iterdir()) == ["report.html", "trajectory.csv", "trajectory.json"]
    mine = json.loads((tmp_path / "out" / "lin" / "trajectory.json").read_text())
    theirs = json.loads((tmp_path / "alone" / "trajectory.json").read_text())
    np.testing.assert_allclose(np.asarray(mine["q"]), np.asarray(theirs["q"]), rtol=0, atol=SAME_TOL)
    assert (record.task, record.folder, record.message, record.robot) == (str(task), "lin", "planned",
                                                                           "kuka_kr6_r900_2")
    assert record.duration_s == pytest.approx(mine["t"][-1], abs=SAME_TOL) and record.samples == len(mine["t"])
    assert record.crossings == len(mine["metrics"]["crossings"])
    assert record.max_position_error_mm == pytest.approx(mine["metrics"]["max_position_error_mm"], abs=SAME_TOL)
    assert record.wall_s is not None and record.wall_s > 0


def test_plan_task_records_a_failure_with_its_robot_and_leaves_no_folder(tmp_path: Path) -> None:
    far = _task(tmp_path, "far.yaml", to={"xyz": [3.0, 0.0, 0.5], "rpy_deg": [180, 0, 0]})
    record = plan_task(_job(tmp_path, far))
    assert (record.exit_code, record.robot, record.folder) == (3, "kuka_kr6_r900_2", "far")
    assert "move 0" in record.message and record.duration_s is None and record.wall_s is not None
    bad = _task(tmp_path, "bad.yaml", speed=-1)
    record = plan_task(_job(tmp_path, bad))
    assert (record.exit_code, record.robot) == (2, "") and "speed" in record.message  # malformed: no robot named
    assert not (tmp_path / "out").exists()


def test_plan_task_names_a_page_it_could_not_build_and_keeps_the_trajectory(tmp_path: Path, monkeypatch) -> None:
    def broken(*args: object) -> str:
        raise ZeroDivisionError("in a plot")

    monkeypatch.setattr("singplan.outputs.report.report_html", broken)
    record = plan_task(_job(tmp_path, _task(tmp_path, "lin.yaml")))
    assert record.exit_code == 0
    assert record.message == "planned; report.html not written: ZeroDivisionError: in a plot"
    assert sorted(p.name for p in (tmp_path / "out" / "lin").iterdir()) == ["trajectory.csv", "trajectory.json"]
