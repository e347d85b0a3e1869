"""Reading a file singplan was pointed at: a regular file of bounded size, or a named refusal.

Every file a user can name (task, URDF, mesh, controller sidecar, trajectory.json, cell mesh)
is read through :func:`read_bounded`. A FIFO, a device such as ``/dev/zero``, a folder or a
file over its cap is refused before it is read, so no input can hang a run or fill its memory:
the file is opened without blocking (a FIFO with no writer would wait forever in ``open``),
checked with ``fstat`` on the open descriptor (no race between the check and the read), and
read up to one byte past the cap (a file that grows meanwhile is still refused).
"""

from __future__ import annotations

import os
import stat
from pathlib import Path

from singplan.errors import InputError


class FileRefusedError(InputError):
    """A named file is not a readable regular file within its cap.

    Attributes:
        path: the file as named.
        what: what the file was meant to be ("task file", "URDF", "mesh", ...).
        reason: what is wrong with it.
    """

    def __init__(self, path: str, what: str, reason: str) -> None:
        self.path = path
        self.what = what
        self.reason = reason
        super().__init__(f"{path}: {reason}")


def display_path(path: str | os.PathLike[str]) -> str:
    """A path for a message: as it is when printable, else quoted; at most 200 characters."""
    text = os.fspath(path)
    text = text if text.isprintable() else repr(text)
    return text if len(text) <= 200 else text[:197] + "..."


def read_bounded(path: str | os.PathLike[str], max_bytes: int, what: str) -> bytes:
    """The bytes of the regular file ``path``, refusing anything else and anything over ``max_bytes``.

    Raises:
        FileRefusedError: missing, a folder, not a regular file (FIFO, device, socket), unreadable,
            or over ``max_bytes`` (the message names the file, what it was for and the cap).
    """
    name = display_path(path)
    flags = os.O_RDONLY | getattr(os, "O_NONBLOCK", 0) | getattr(os, "O_CLOEXEC", 0)
    try:
        fd = os.open(path, flags)
    except FileNotFoundError:
        raise FileRefusedError(name, what, f"no such {what}") from None
    except IsADirectoryError:
        raise FileRefusedError(name, what, f"is a folder, not a {what}") from None
    except PermissionError:
        raise FileRefusedError(name, what, "cannot be read (permission denied)") from None
    except (OSError, ValueError) as exc:  # ValueError: a NUL byte in the path
        raise FileRefusedError(name, what, f"cannot be read ({getattr(exc, 'strerror', None) or exc})") from None
    with os.fdopen(fd, "rb") as f:
        info = os.fstat(f.fileno())
        if stat.S_ISDIR(info.st_mode):
            raise FileRefusedError(name, what, f"is a folder, not a {what}")
        if not stat.S_ISREG(info.st_mode):
            raise FileRefusedError(name, what, f"not a regular file (a {_kind(info.st_mode)}); a {what} must be one")
        if info.st_size > max_bytes:
            raise FileRefusedError(name, what, f"{info.st_size} bytes is over the {max_bytes}-byte cap for a {what}")
        try:
            data = f.read(max_bytes + 1)
        except OSError as exc:
            raise FileRefusedError(name, what, f"cannot be read ({exc.strerror or exc})") from None
    if len(data) > max_bytes:
        raise FileRefusedError(name, what, f"over the {max_bytes}-byte cap for a {what}")
    return data


def read_bounded_text(path: str | os.PathLike[str], max_bytes: int, what: str) -> str:
    """:func:`read_bounded`, decoded as UTF-8 (a byte-order mark is dropped).

    Raises:
        FileRefusedError: as :func:`read_bounded`, or the bytes are not UTF-8 (the first bad byte named).
    """
    data = read_bounded(path, max_bytes, what)
    try:
        return data.decode("utf-8-sig")
    except UnicodeDecodeError as exc:
        raise FileRefusedError(display_path(path), what,
                               f"not a UTF-8 text file (byte {exc.start} is invalid)") from None


def _kind(mode: int) -> str:
    if stat.S_ISFIFO(mode):
        return "FIFO"
    if stat.S_ISCHR(mode) or stat.S_ISBLK(mode):
        return "device"
    if stat.S_ISSOCK(mode):
        return "socket"
    return "special file"


def is_within(path: Path, roots: tuple[Path, ...]) -> bool:
    """Whether ``path`` lies inside one of the folders ``roots`` (symbolic links resolved on both sides:
    a link inside a root that points outside it is outside)."""
    try:
        real = path.resolve()
        folders = [root.resolve() for root in roots]
    except (OSError, RuntimeError):  # a loop of links
        return False
    return any(real == folder or folder in real.parents for folder in folders)
