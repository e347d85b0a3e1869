"""Reading a file singplan was pointed at: a regular file of bounded size, or a named refusal.

Every file a user can name (task, URDF, mesh, controller sidecar, trajectory.json, cell mesh)
is read through :func:`read_bounded`. A FIFO, a device such as ``/dev/zero``, a folder or a
file over its cap is refused before it is read, so no input can hang a run or fill its memory:
the file is opened without blocking (a FIFO with no writer would wait forever in ``open``),
checked with ``fstat`` on the open descriptor (no race between the check and the read), and
read up to one byte past the cap (a file that grows meanwhile is still refused).

What is read is then parsed with bounded work (:func:`read_json`; YAML in
:mod:`singplan.kinematics.yamldoc`) and every value is checked before use; a value that is not
what it must be is a :class:`FileFieldError` naming the file and the field.
"""

from __future__ import annotations

import json
import os
import stat
from pathlib import Path
from typing import Any

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


class FileFieldError(InputError):
    """A value in a file singplan read is not what it must be.

    Attributes:
        path: the file as named.
        field: where in it, as a key path (``segments[3].kind``; empty for the whole document).
        reason: what is wrong, with the value found and what was expected.
    """

    def __init__(self, path: str, field: str, reason: str) -> None:
        self.path = path
        self.field = field
        self.reason = reason
        super().__init__(f"{path}: {field}: {reason}" if field else f"{path}: {reason}")


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
        raise FileRefusedError(name, what, f"is a directory, not a {what}") from None
    except PermissionError:
        raise FileRefusedError(name, what, "cannot be read (permission denied)") from None
    except ValueError:  # a NUL byte in the path: no file has that name
        raise FileRefusedError(name, what, f"no such {what} (the name holds a NUL character)") from None
    except OSError as exc:
        raise FileRefusedError(name, what, f"cannot be read ({exc.strerror or exc})") from None
    info = os.fstat(fd)
    if not stat.S_ISREG(info.st_mode):
        os.close(fd)
        if stat.S_ISDIR(info.st_mode):
            raise FileRefusedError(name, what, f"is a directory, not a {what}")
        raise FileRefusedError(name, what, f"not a regular file (a {_kind(info.st_mode)}); a {what} must be one")
    with os.fdopen(fd, "rb") as f:
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


def read_json(path: str | os.PathLike[str], max_bytes: int, what: str) -> Any:
    """The JSON document of the file ``path`` (:func:`read_bounded_text`), parsed with bounded work.

    Python's parser refuses nesting past the interpreter's recursion limit (a few thousand
    levels at most, each a character of the bounded file) with RecursionError; that, a
    syntax error and a number Python will not convert (an integer of over 4300 digits) are
    each a :class:`FileFieldError` naming the file (and the line and column of a syntax error).
    The values are not checked here: the caller checks each before use.
    """
    text = read_bounded_text(path, max_bytes, what)
    name = display_path(path)
    try:
        return json.loads(text)
    except json.JSONDecodeError as exc:
        raise FileFieldError(name, "", f"not valid JSON (line {exc.lineno}, column {exc.colno}): {exc.msg}") from None
    except RecursionError:
        raise FileFieldError(name, "", "nested too deeply to be a " + what) from None
    except ValueError as exc:  # e.g. an integer too long to convert
        raise FileFieldError(name, "", f"a value cannot be read: {str(exc)[:120]}") from None


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
