"""Writing singplan's files without touching anything else (DESIGN.md, "Outputs").

singplan writes only its own files into an output folder, creating the folder (and missing
parents) when absent. Each file is first written under a hidden temporary name in the folder
and renamed into place only once every file was written, so a failure or an interrupt leaves
the folder as it was: the temporary files are removed, and so are the folders singplan
created. Other files in the folder are never touched; a symbolic link to a folder is written
through and kept.

An unusable path (empty, an existing non-folder, under a file, not writable) is an
:class:`OutputPathError` (bad input, exit 2). :func:`check_output_dir` and
:func:`check_output_file` find that out before any planning, by creating what is missing and
a probe file, and removing both again.

One run writes into a folder at a time (:func:`hold_output_folder`): a run holds an exclusive
lock on ``.singplan.lock`` in the folder from its check to its last rename (``flock``, which the
kernel releases when a process dies, even by SIGKILL), so a second ``plan``, ``replay --html``,
``export`` or ``batch`` into the same folder meanwhile is refused (exit 2) naming the folder and
the process holding it, instead of leaving one run's trajectory.csv beside the other's
trajectory.json. Holding is re-entrant within a process (a plan holds its folder and its save
writes there). A run that was killed leaves its temporary files (and its lock file) behind; the
next run into the folder removes them, singplan's own temporary names of the files it writes
only, never another file, and only while it holds the lock. The lock file is removed when the
run ends.
"""

from __future__ import annotations

import contextlib
import os
import signal
import sys
import tempfile
from collections.abc import Callable, Iterable, Iterator, Mapping
from dataclasses import dataclass
from pathlib import Path
from typing import TextIO

from singplan.errors import OutputPathError

if sys.platform != "win32":
    import fcntl

Writer = Callable[[TextIO], None]
_TEMP_SUFFIX = ".singplan-tmp"
LOCK_NAME = ".singplan.lock"
_PROBE_PREFIX = ".singplan-probe."


@dataclass
class _Hold:
    """This process's lock on one folder: its descriptor and how many holds share it."""

    fd: int
    count: int = 1


_HELD: dict[str, _Hold] = {}  # folder (resolved) -> this process's lock on it


@contextlib.contextmanager
def hold_output_folder(path: str | os.PathLike[str], names: Iterable[str] = ()) -> Iterator[Path]:
    """Hold the folder ``path`` for one run writing the files ``names`` (see the module's docstring).

    Creates the folder (and missing parents) if absent and removes them again if the block
    fails while they are empty; takes the folder's lock; removes the temporary files of ``names``
    a killed run left. Yields the folder.

    Raises:
        OutputPathError: the path is unusable, cannot be written, or another run holds the folder.
    """
    folder = _usable_dir(path)
    _check_not_folders(path, folder, names)
    created = _make_dirs(folder)
    try:
        key = _lock(folder, path)
    except BaseException:
        _remove_dirs(created)
        raise
    try:
        if _HELD[key].count == 1:
            _probe(folder)
            _remove_temporaries(folder, names)
        yield folder
    except BaseException:
        _unlock(folder, key)
        _remove_dirs(created)  # only while empty: nothing renamed into it, nothing of anyone else's
        raise
    _unlock(folder, key)


def _lock(folder: Path, path: str | os.PathLike[str]) -> str:
    """Take (or share, within this process) the folder's lock; the key it is held under."""
    key = str(folder.resolve())
    held = _HELD.get(key)
    if held is not None:
        held.count += 1
        return key
    if sys.platform == "win32":  # no flock: one run per folder is then the user's to keep
        _HELD[key] = _Hold(-1)
        return key
    lock = folder / LOCK_NAME
    while True:
        try:
            fd = os.open(lock, os.O_RDWR | os.O_CREAT | os.O_CLOEXEC | os.O_NOFOLLOW, 0o644)
        except OSError as exc:
            raise OutputPathError(os.fspath(path), f"cannot write into {folder}: {_reason(exc)}") from None
        try:
            fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
        except BlockingIOError:
            holder = _holder(fd)
            os.close(fd)
            raise OutputPathError(os.fspath(path), f"in use by another singplan run{holder}; wait for it to "
                                                   "finish or write elsewhere") from None
        if _same_file(fd, lock):  # not a lock file its last holder removed between our open and our flock
            break
        os.close(fd)
    os.ftruncate(fd, 0)
    os.write(fd, f"{os.getpid()}\n".encode())
    _HELD[key] = _Hold(fd)
    return key


def _holder(fd: int) -> str:
    """`` (process N)`` from a held lock file, or nothing."""
    try:
        text = os.pread(fd, 32, 0).decode("ascii", "replace").strip()
    except OSError:
        return ""
    return f" (process {text})" if text.isdigit() else ""


def _same_file(fd: int, path: Path) -> bool:
    try:
        mine, named = os.fstat(fd), os.stat(path, follow_symlinks=False)
    except OSError:
        return False
    return (mine.st_dev, mine.st_ino) == (named.st_dev, named.st_ino)


def _unlock(folder: Path, key: str) -> None:
    """Release one hold; the last one removes the lock file (while still holding it) and lets go."""
    held = _HELD[key]
    held.count -= 1
    if held.count:
        return
    del _HELD[key]
    if held.fd < 0:
        return
    with contextlib.suppress(OSError):
        (folder / LOCK_NAME).unlink()
    os.close(held.fd)


def check_output_dir(path: str | os.PathLike[str], names: Iterable[str] = ()) -> Path:
    """Refuse (OutputPathError) a folder that cannot receive the files ``names``; leave it as it was."""
    folder = _usable_dir(path)
    _check_not_folders(path, folder, names)
    created = _make_dirs(folder)
    try:
        _probe(folder)
    finally:
        _remove_dirs(created)
    return folder


def check_output_file(path: str | os.PathLike[str]) -> Path:
    """Refuse a file path that cannot be written; return the file to write (a symlink's target)."""
    target = _usable_file(path)
    try:
        check_output_dir(target.parent)
    except OutputPathError as exc:
        raise OutputPathError(os.fspath(path), exc.reason) from None
    return target


def write_files(path: str | os.PathLike[str], writers: Mapping[str, Writer]) -> list[Path]:
    """Write each ``name -> writer(stream)`` into folder ``path``, all or nothing; return the files.

    The folder is held (:func:`hold_output_folder`) while it is written: a folder some other run
    holds is refused before anything is written.
    """
    # the names are checked before writing: a rename would fail half way through
    with hold_output_folder(path, writers) as folder:
        temps: dict[str, Path] = {}
        written: list[Path] = []
        try:
            for name, write in writers.items():
                _write_temp(folder, name, write, temps)
            with _interrupts_held():  # Ctrl-C between two renames would leave a mixed set of files
                for name in list(temps):
                    os.replace(temps[name], folder / name)  # each rename is atomic; no reader sees a partial file
                    del temps[name]
                    written.append(folder / name)
        except BaseException as exc:
            for temp in temps.values():
                temp.unlink(missing_ok=True)
            if isinstance(exc, OSError):
                raise OutputPathError(os.fspath(path), f"cannot write into {folder}: {_reason(exc)}") from exc
            raise
    return written


@contextlib.contextmanager
def _interrupts_held() -> Iterator[None]:
    """SIGINT and SIGTERM wait until the block ends (POSIX; elsewhere nothing is held)."""
    if not hasattr(signal, "pthread_sigmask"):
        yield
        return
    previous = signal.pthread_sigmask(signal.SIG_BLOCK, {signal.SIGINT, signal.SIGTERM})
    try:
        yield
    finally:
        signal.pthread_sigmask(signal.SIG_SETMASK, previous)


def _check_not_folders(path: str | os.PathLike[str], folder: Path, names: Iterable[str]) -> None:
    for name in names:
        if (folder / name).is_dir():
            raise OutputPathError(os.fspath(path), f"{folder / name} is a folder; singplan cannot replace it")


def write_file(path: str | os.PathLike[str], write: Writer) -> Path:
    """Write one file the same way: a temporary name in its folder, renamed when complete."""
    target = _usable_file(path)
    return write_files(target.parent, {target.name: write})[0]


def text_writer(text: str) -> Writer:
    """A writer of a ready string."""
    def write(stream: TextIO) -> None:
        stream.write(text)
    return write


def _usable_dir(path: str | os.PathLike[str]) -> Path:
    text = os.fspath(path)
    if text == "":
        raise OutputPathError(text, "empty path; give a folder, e.g. -o out")
    if "\0" in text:
        raise OutputPathError(text, "contains a NUL character")
    folder = Path(text)
    try:
        for p in (folder, *folder.parents):
            if p.is_symlink() and not p.exists():
                raise OutputPathError(text, f"{p} is a broken symbolic link")
            if p.exists():
                if not p.is_dir():
                    raise OutputPathError(text, f"{p} is not a folder" if p == folder
                                          else f"lies under {p}, which is not a folder")
                break
    except OSError as exc:
        raise OutputPathError(text, _reason(exc)) from None
    return folder


def _usable_file(path: str | os.PathLike[str]) -> Path:
    text = os.fspath(path)
    if text == "" or text.endswith(os.sep):
        raise OutputPathError(text, "give a file name, e.g. replay.html")
    if "\0" in text:
        raise OutputPathError(text, "contains a NUL character")
    target = Path(text)
    try:
        if target.is_symlink():
            target = Path(os.path.realpath(target))  # write the file it points to and keep the link
        is_dir = target.is_dir()
    except OSError as exc:  # e.g. a name too long for the file system
        raise OutputPathError(text, _reason(exc)) from None
    if is_dir:
        raise OutputPathError(text, "is a folder; give a file name")
    return target


def _make_dirs(folder: Path) -> list[Path]:
    """Create ``folder`` and its missing parents; return those created, outermost first."""
    missing = []
    p = folder
    while not p.exists():
        missing.append(p)
        p = p.parent
    created: list[Path] = []
    try:
        for d in reversed(missing):
            d.mkdir()
            created.append(d)
    except OSError as exc:
        _remove_dirs(created)
        raise OutputPathError(str(folder), f"cannot create the folder {d}: {_reason(exc)}") from None
    except BaseException:
        _remove_dirs(created)
        raise
    return created


def _remove_dirs(created: list[Path]) -> None:
    for d in reversed(created):
        try:
            d.rmdir()
        except OSError:  # something else appeared in it meanwhile: not ours to remove
            return


def _probe(folder: Path) -> None:
    try:
        fd, name = tempfile.mkstemp(prefix=_PROBE_PREFIX, suffix=_TEMP_SUFFIX, dir=folder)
        os.close(fd)
        os.unlink(name)
    except OSError as exc:
        raise OutputPathError(str(folder), f"cannot write into it: {_reason(exc)}") from None


def _write_temp(folder: Path, name: str, write: Writer, temps: dict[str, Path]) -> None:
    """Write one file under a hidden temporary name, registered in ``temps`` before any byte."""
    fd, temp = tempfile.mkstemp(prefix=_temp_prefix(name), suffix=_TEMP_SUFFIX, dir=folder)
    temps[name] = Path(temp)
    with os.fdopen(fd, "w", encoding="utf-8") as stream:
        os.fchmod(fd, 0o666 & ~_umask())  # mkstemp makes it private; the result is an ordinary file
        write(stream)
        stream.flush()
        os.fsync(fd)


def _temp_prefix(name: str) -> str:
    return f".{name[:64]}."  # short: any name fits


def remove_temporary_files(folder: Path, names: Iterable[str]) -> None:
    """Remove the temporary files of ``names`` (and the lock file) left in ``folder`` by a writer
    killed before it could (SIGKILL, the OOM killer), if no run holds the folder now; OSError when
    the folder cannot be read."""
    try:
        key = _lock(folder, folder)
    except OutputPathError:  # another run holds it: its files are not leftovers
        return
    try:
        _remove_temporaries(folder, names)
    finally:
        _unlock(folder, key)


def _remove_temporaries(folder: Path, names: Iterable[str]) -> None:
    """Remove singplan's temporary files of ``names`` (and its probes) in a folder this process holds."""
    prefixes = (*(_temp_prefix(name) for name in names), _PROBE_PREFIX)
    for p in folder.glob(f".*{_TEMP_SUFFIX}"):
        if p.name.startswith(prefixes):
            p.unlink(missing_ok=True)


def _umask() -> int:
    mask = os.umask(0o022)
    os.umask(mask)
    return mask


def _reason(exc: OSError) -> str:
    return exc.strerror or str(exc)
