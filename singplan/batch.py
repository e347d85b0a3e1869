"""Plan many tasks: one output folder per task and a summary table (DESIGN.md, "Outputs": Batch).

Each task is planned by :func:`plan_task` in a worker and written into ``DIR/<folder>`` under
the output folder rules of :mod:`singplan.results.files`; ``DIR/summary.csv`` and
``DIR/summary.json`` are written the same way once every task has finished (or the batch was
interrupted). Two ways to run the workers:

- local (default): ``workers`` long-lived worker processes, each planning one task at a time.
  A worker that dies (a segfault, the kernel's OOM killer) loses only its current task, which
  is recorded with exit code 1, and is replaced. Each worker is a whole process, so each task
  has the memory budget of :mod:`singplan.planning.orchestration.budget`; N workers may take N x 1.5 GB in all.
  A worker that dies before taking any task (WorkerStartError) means none can start: the
  tasks not yet run are recorded as not run, with exit code 1.
- Dask (``scheduler``): the tasks are submitted to a ``dask.distributed`` cluster. The workers
  read the task files and write the folders themselves, so DIR and the tasks must be on a file
  system they share (paths are made absolute first). Dask is imported only then.

One task's failure (exit 2 or 3, an internal error, a dead worker) never stops the others.
"""

from __future__ import annotations

import csv
import json
import multiprocessing
import os
import signal
import sys
import time
import uuid
from collections.abc import Callable, Generator, Iterator, Sequence
from dataclasses import asdict, dataclass, fields
from multiprocessing.connection import Connection, wait
from pathlib import Path
from typing import Any, TextIO

from singplan.entry import OUTPUT_FILES, load_task, plan_into
from singplan.errors import InputError, SingplanError
from singplan.results.files import check_output_dir, hold_output_folder, remove_temporary_files, write_files
from singplan.results.trajectory import Trajectory
from singplan.task.schema import TASK_MEMORY_MB

FORMAT = "singplan.batch/1"
SUMMARY_CSV = "summary.csv"
SUMMARY_JSON = "summary.json"
SUMMARY_FILES = (SUMMARY_CSV, SUMMARY_JSON)
INTERRUPTED = 130  # the exit code of an interrupted batch, and of its tasks that did not finish
DEAD_WORKER = 1  # a task whose worker died: no result, so an internal failure rather than 2 or 3
_MESSAGE_CHARS = 2000  # a record travels through a pipe; an error message longer than this is cut
_STOP_WAIT_S = 30.0  # how long an interrupted worker may take to remove its temporary files
CONNECT_TIMEOUT_S = 10.0  # how long to try reaching a Dask scheduler before --scheduler is refused


@dataclass(frozen=True)
class TaskJob:
    """One task to plan: ``task`` and ``folder`` absolute; ``shown`` the path as the user gave it."""

    index: int
    task: str
    shown: str
    folder: str
    method: str | None = None
    report: bool = True
    replay: bool = True
    folder_existed: bool = False  # a folder that was there before the batch is never removed


@dataclass(frozen=True)
class TaskRecord:
    """The outcome of one task: a row of the summary.

    ``folder`` is relative to the batch folder; the figures are None unless the task planned
    (exit code 0). ``wall_s`` is the worker's time on the task (reading, planning, writing) [s].
    """

    task: str
    folder: str
    exit_code: int
    message: str
    robot: str = ""
    duration_s: float | None = None
    samples: int | None = None
    crossings: int | None = None
    max_position_error_mm: float | None = None
    max_orientation_error_deg: float | None = None
    planning_time_s: float | None = None
    wall_s: float | None = None


@dataclass(frozen=True)
class BatchResult:
    """Every task's record, in the order the tasks were given, and where the summary is."""

    out_dir: Path
    records: tuple[TaskRecord, ...]
    interrupted: bool
    wall_s: float

    @property
    def exit_code(self) -> int:
        """0 when every task planned; 130 when interrupted; otherwise the largest task exit code."""
        if self.interrupted:
            return INTERRUPTED
        return max((r.exit_code for r in self.records), default=0)

    @property
    def summary_csv(self) -> Path:
        return self.out_dir / SUMMARY_CSV

    @property
    def summary_json(self) -> Path:
        return self.out_dir / SUMMARY_JSON


Runner = Callable[[TaskJob], TaskRecord]
Progress = Callable[[TaskRecord, int, int], None]  # (record, finished so far, total)


def plan_task(job: TaskJob) -> TaskRecord:
    """Plan one task and write its folder; any failure becomes the record's exit code and message."""
    started = time.perf_counter()
    robot = ""
    try:
        task = load_task(job.task)
        robot = task.robot
        done = plan_into(task, job.folder, method=job.method, report=job.report, replay=job.replay)
    except SingplanError as exc:
        return _failed(job, exc.exit_code, str(exc), robot, started)
    except Exception as exc:  # a bug: recorded like the CLI's internal error, and the batch goes on
        return _failed(job, 1, f"internal error: {type(exc).__name__}: {exc}", robot, started)
    message = "planned" + "".join(f"; {name} not written: {why}" for name, why in done.skipped.items())
    message += f"; from an earlier run: {', '.join(done.stale)}" if done.stale else ""
    return _planned(job, done.traj, message, time.perf_counter() - started)


def _planned(job: TaskJob, traj: Trajectory, message: str, wall_s: float) -> TaskRecord:
    m = traj.metrics
    return TaskRecord(job.shown, Path(job.folder).name, 0, message, traj.robot, traj.duration_s, len(traj.t),
                      len(m.crossings), float(m.max_position_error_mm),
                      float(m.max_orientation_error_deg), float(m.planning_time_s), wall_s)


def _failed(job: TaskJob, code: int, message: str, robot: str, started: float) -> TaskRecord:
    text = message if len(message) <= _MESSAGE_CHARS else message[:_MESSAGE_CHARS] + " ..."
    return TaskRecord(job.shown, Path(job.folder).name, code, text, robot, wall_s=time.perf_counter() - started)


def folder_names(tasks: Sequence[str | os.PathLike[str]]) -> list[str]:
    """Each task's folder name: its file name without the extension.

    The first task with a given name gets it; later tasks with the same name (compared without
    case, for case-insensitive file systems), and a name equal to a summary file's, get ``-2``,
    ``-3``, ... (the first suffix not yet taken), in the order the tasks are given. A name that
    would mean the batch folder or its parent (``..yaml``) becomes ``task``.
    """
    taken = {name.casefold() for name in SUMMARY_FILES}
    names = []
    for task in tasks:
        stem = Path(task).stem
        if stem in (".", ".."):
            stem = "task"
        name, k = stem, 1
        while name.casefold() in taken:
            k += 1
            name = f"{stem}-{k}"
        taken.add(name.casefold())
        names.append(name)
    return names


def make_jobs(tasks: Sequence[str | os.PathLike[str]], out_dir: Path, method: str | None = None,
              report: bool = True, replay: bool = True) -> list[TaskJob]:
    """The jobs of a batch; the same task file given twice is bad input (it would be planned twice)."""
    seen: dict[str, str] = {}
    for task in tasks:
        key = os.path.realpath(task)
        if key in seen:
            raise InputError(f"task {os.fspath(task)!r} is given twice (as {seen[key]!r}); give each task once")
        seen[key] = os.fspath(task)
    return [TaskJob(i, os.path.abspath(task), os.fspath(task), os.path.abspath(out_dir / name), method, report, replay,
                    (out_dir / name).exists())
            for i, (task, name) in enumerate(zip(tasks, folder_names(tasks), strict=True))]


def plan_many(tasks: Sequence[str | os.PathLike[str]], out_dir: str | os.PathLike[str], *,
              workers: int | None = None, scheduler: str | None = None, method: str | None = None,
              report: bool = True, replay: bool = True, progress: Progress | None = None,
              runner: Runner = plan_task) -> BatchResult:
    """Plan every task into ``out_dir/<task name>`` and write the summary files; see the module doc.

    ``workers``: local worker processes (default ``os.cpu_count()``, at most one per task);
    ``scheduler``: a Dask scheduler's address instead. ``runner`` plans one job in a worker
    (a module-level function, so that it can be sent to a process). The batch's own problems
    (an unusable ``out_dir``, a task given twice, no Dask, no scheduler) raise InputError;
    a task's never do. Ctrl-C stops the workers and still writes the summary of what finished.
    """
    if workers is not None and scheduler is not None:
        raise InputError("give either workers (local processes) or scheduler (a Dask cluster), not both")
    if workers is not None and workers < 1:
        raise InputError(f"--workers: {workers} is not a positive number of worker processes")
    if not tasks:
        raise InputError("no tasks given")
    folder = check_output_dir(out_dir, SUMMARY_FILES)
    jobs = make_jobs(tasks, folder, method, report, replay)
    client = _connect(scheduler) if scheduler is not None else None  # refused before DIR is created
    try:
        # created before the workers, which would race to create it; held until the summary is written
        with hold_output_folder(folder, SUMMARY_FILES):
            started = time.perf_counter()
            results = (_on_dask(jobs, client, runner) if client is not None
                       else _on_processes(jobs, local_workers(workers, len(jobs)), runner))
            done, stopped = _collect(results, len(jobs), progress)
            result = BatchResult(Path(os.path.abspath(folder)), _records(jobs, done, stopped),
                                 stopped == _INTERRUPTION, time.perf_counter() - started)
            write_summary(result)
    finally:
        if client is not None:
            client.close()
    return result


_INTERRUPTION = (INTERRUPTED, "not finished: the batch was interrupted")


def _collect(results: Generator[tuple[int, TaskRecord], None, None], total: int,
             progress: Progress | None) -> tuple[dict[int, TaskRecord], tuple[int, str] | None]:
    """The records by job index as they finish, and what stopped the batch early (exit code and message)."""
    done: dict[int, TaskRecord] = {}
    try:
        for index, record in results:
            done[index] = record
            if progress is not None:
                progress(record, len(done), total)
    except KeyboardInterrupt:
        return done, _INTERRUPTION
    except WorkerStartError as exc:
        return done, (exc.exit_code, f"not run: {exc}")
    finally:
        results.close()  # stops the workers, whatever ended the loop
    return done, None


def _records(jobs: list[TaskJob], done: dict[int, TaskRecord],
             stopped: tuple[int, str] | None) -> tuple[TaskRecord, ...]:
    """The finished tasks' records and, for the others, why they did not finish."""
    code, message = stopped or _INTERRUPTION  # without a stop, every task has its record
    return tuple(done.get(job.index) or TaskRecord(job.shown, Path(job.folder).name, code, message)
                 for job in jobs)


def write_summary(result: BatchResult) -> list[Path]:
    """summary.csv and summary.json in the batch folder, written together (temporary names, renamed)."""
    rows = [asdict(r) for r in result.records]
    doc = {"format": FORMAT, "exit_code": result.exit_code, "interrupted": result.interrupted,
           "wall_s": result.wall_s, "tasks": rows}

    def write_csv(stream: TextIO) -> None:
        writer = csv.DictWriter(stream, [f.name for f in fields(TaskRecord)], lineterminator="\n")
        writer.writeheader()
        writer.writerows({k: ("" if v is None else v) for k, v in row.items()} for row in rows)

    def write_json(stream: TextIO) -> None:
        json.dump(doc, stream, indent=1, allow_nan=False)
        stream.write("\n")

    return write_files(result.out_dir, {SUMMARY_CSV: write_csv, SUMMARY_JSON: write_json})


def local_workers(workers: int | None, n_tasks: int) -> int:
    """The number of local worker processes: ``workers`` (default one per CPU), at most one per task."""
    return min(workers or os.cpu_count() or 1, n_tasks)


def memory_warning(workers: int) -> str | None:
    """A warning when ``workers`` tasks at their memory budget could exceed this machine's memory."""
    try:
        total_mb = os.sysconf("SC_PAGE_SIZE") * os.sysconf("SC_PHYS_PAGES") / 2**20
    except (AttributeError, ValueError, OSError):  # no sysconf (Windows): nothing to compare with
        return None
    need_mb = workers * TASK_MEMORY_MB
    if need_mb <= total_mb:
        return None
    fitting = max(1, int(total_mb // TASK_MEMORY_MB))
    return (f"{workers} workers may take up to {workers} x {TASK_MEMORY_MB:.0f} MB = {need_mb / 1024:.1f} GB, "
            f"more than this machine's {total_mb / 1024:.1f} GB; use --workers {fitting} or fewer for large tasks")


# --- local worker processes -----------------------------------------------------------------


class WorkerStartError(SingplanError):
    """A local worker process died before it could take a task (exit code 1): no task can run."""

    def __init__(self, how: str) -> None:
        self.how = how
        super().__init__(f"a worker process could not start ({how}); a script that calls plan_many must guard its "
                         "top level with `if __name__ == \"__main__\":` (the workers import it)")


class _Worker:
    """A worker process and the two ends of its job pipe."""

    def __init__(self, ctx: Any, runner: Runner) -> None:
        self.jobs, child_end = ctx.Pipe()
        self.process = ctx.Process(target=_serve, args=(child_end, runner), daemon=True)
        self.process.start()
        child_end.close()
        self.job: TaskJob | None = None
        self.started = 0.0

    def wait_ready(self) -> None:
        """Block until the process runs its loop; WorkerStartError when it died first."""
        try:
            self.jobs.recv()
        except (EOFError, OSError):
            self.stop()
            raise WorkerStartError(_death(self.process.exitcode)) from None

    def give(self, job: TaskJob) -> bool:
        """Send the job and wait for the worker to take it; False when it died first (stopped, job not taken)."""
        try:
            self.jobs.send(job)
            self.jobs.recv()  # "started": from here on, a death is this job's
        except (EOFError, OSError):
            self.stop()
            return False
        self.job, self.started = job, time.perf_counter()
        return True

    def take(self) -> TaskRecord | None:
        """The finished job's record, or None when the process died without sending one."""
        try:
            record: TaskRecord = self.jobs.recv()
        except (EOFError, OSError):
            return None
        self.job = None
        return record

    def stop(self) -> None:
        """Interrupt the current job (its temporary files are removed) and end the process."""
        # terminate() is SIGTERM that tolerates a process already gone (a fork server's child may be
        # reaped between any is_alive() and a kill, which then raises ProcessLookupError)
        self.process.terminate()
        self.process.join(_STOP_WAIT_S)
        if self.process.is_alive():
            self.process.kill()
            self.process.join()
        self.jobs.close()


def _serve(jobs: Connection, runner: Runner) -> None:
    """A worker's loop: plan each job received until the pipe closes; SIGTERM interrupts a job."""
    signal.signal(signal.SIGINT, signal.SIG_IGN)  # a terminal's Ctrl-C reaches the parent, which stops us once
    signal.signal(signal.SIGTERM, _interrupt)
    try:
        jobs.send("ready")
        while True:
            try:
                job = jobs.recv()
            except EOFError:
                return
            jobs.send("started")
            jobs.send(runner(job))
    except KeyboardInterrupt:
        return


def _interrupt(signum: int, frame: object) -> None:
    raise KeyboardInterrupt


def _context() -> Any:
    """Fork a preloaded server where possible: workers start without importing the planner again."""
    methods = multiprocessing.get_all_start_methods()
    main_file = getattr(sys.modules.get("__main__"), "__file__", None)
    if main_file is not None and not os.path.isfile(main_file) and "fork" in methods:
        return multiprocessing.get_context("fork")  # a script read from stdin: a new process could not re-read it
    if "forkserver" in methods:
        ctx = multiprocessing.get_context("forkserver")
        ctx.set_forkserver_preload([__name__])
        return ctx
    return multiprocessing.get_context("spawn")


def _on_processes(jobs: list[TaskJob], n_workers: int,
                  runner: Runner) -> Generator[tuple[int, TaskRecord], None, None]:
    """Run the jobs on ``n_workers`` processes; yield (job index, record) as each finishes."""
    ctx = _context()
    pending = list(reversed(jobs))
    workers: list[_Worker] = []
    try:
        while pending or any(w.job is not None for w in workers):
            # a busy worker stays until _finished has recorded its job, even when it has died meanwhile
            workers = [w for w in workers if w.job is not None or w.process.is_alive()]
            started = [_Worker(ctx, runner) for _ in range(min(n_workers - len(workers), len(pending)))]
            workers += started  # stopped in `finally` even when one of them does not start
            for w in started:
                w.wait_ready()
            for w in workers:
                if w.job is None and pending and w.give(pending[-1]):
                    pending.pop()  # else the worker died idle: a new one takes the job on the next round
            if any(w.job is not None for w in workers):
                yield from _finished(workers)
    finally:
        for w in workers:
            w.stop()


def _finished(workers: list[_Worker]) -> Iterator[tuple[int, TaskRecord]]:
    """Wait for at least one busy worker to finish its job (or die); yield those records."""
    busy = [w for w in workers if w.job is not None]
    ready = set(wait([w.jobs for w in busy] + [w.process.sentinel for w in busy]))
    for w in busy:
        if w.jobs not in ready and w.process.sentinel not in ready:
            continue
        job = w.job
        assert job is not None
        record = w.take()
        if record is None:
            w.stop()
            record = _dead(job, _death(w.process.exitcode), time.perf_counter() - w.started)
            w.job = None
        yield job.index, record


def _death(exitcode: int | None) -> str:
    if exitcode is not None and exitcode < 0:
        try:
            return f"killed by signal {signal.Signals(-exitcode).name}"
        except ValueError:
            return f"killed by signal {-exitcode}"
    return f"exit status {exitcode}"


def _dead(job: TaskJob, how: str, wall_s: float | None) -> TaskRecord:
    """The record of a task whose worker died, after removing the temporary files it left."""
    _remove_leftovers(Path(job.folder), remove_folder=not job.folder_existed)
    return TaskRecord(job.shown, Path(job.folder).name, DEAD_WORKER,
                      f"the worker process died while planning this task ({how}); no result", wall_s=wall_s)


def _remove_leftovers(folder: Path, remove_folder: bool) -> None:
    """A killed worker cannot clean up: remove its temporary files, and the folder it created if left empty."""
    try:
        remove_temporary_files(folder, OUTPUT_FILES)
        if remove_folder:
            folder.rmdir()  # only an empty folder: one that holds anything else stays
    except OSError:
        return


# --- Dask -----------------------------------------------------------------------------------


def _connect(scheduler: str) -> Any:
    """A Dask client of the scheduler at ``scheduler`` (InputError without Dask or without a scheduler there)."""
    distributed = _import_distributed()
    try:
        return distributed.Client(scheduler, timeout=CONNECT_TIMEOUT_S)
    except (OSError, ValueError, TypeError) as exc:
        raise InputError(f"--scheduler {scheduler!r}: cannot connect to a Dask scheduler there: {exc}") from None


def _on_dask(jobs: list[TaskJob], client: Any, runner: Runner) -> Generator[tuple[int, TaskRecord], None, None]:
    """Submit the jobs to the client's cluster; yield (job index, record) as each finishes."""
    distributed = _import_distributed()
    batch = uuid.uuid4().hex[:8]
    futures = {client.submit(runner, job, key=f"singplan-{batch}-{job.index}", pure=False): job for job in jobs}
    try:
        for future in distributed.as_completed(futures):
            job = futures[future]
            yield job.index, _dask_record(future, job, distributed)
    finally:
        client.cancel(list(futures))  # the tasks not yet finished (running ones finish on their own)


def _dask_record(future: Any, job: TaskJob, distributed: Any) -> TaskRecord:
    try:
        record: TaskRecord = future.result()
    except distributed.KilledWorker as exc:
        return _dead(job, f"Dask: {exc}", None)
    except Exception as exc:  # the runner itself cannot raise; this is Dask failing to run it
        return TaskRecord(job.shown, Path(job.folder).name, 1, f"Dask could not run the task: {type(exc).__name__}: "
                          f"{exc}")
    return record


def _import_distributed() -> Any:
    try:
        import distributed
    except ImportError:
        raise InputError("--scheduler needs Dask, which is not installed: pip install 'singplan[batch]' "
                         "(or pip install 'dask[distributed]')") from None
    return distributed

