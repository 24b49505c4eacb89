"""Files of the course folder written whole or not at all.

The course's own records (``.cvkit/journal.json``, the hand marks, the trusted submission
times, nbgrader's configuration, the exports) are read by other processes while a grading run
writes them: a second ``cvkit`` command, nbgrader's formgrader, an instructor's script. A file
written in place can be seen half written, and one interrupted (Ctrl-C, a full disk, a lost
machine) stays half written: a truncated journal reads as "nothing graded yet", truncated
submission times as "none recorded".

:func:`whole_file` writes to a temporary file beside the target, flushes it to the disk, and
moves it over the target in one step (``os.replace``): a reader sees the old file or the new
one, never a part; a link standing at the target is replaced, never followed; on any error
the temporary file is removed, the target is as it was, and the error is raised.
"""
from __future__ import annotations

import contextlib
import os
import tempfile
from pathlib import Path
from typing import IO, Iterator

__all__ = ["whole_file", "write_whole"]


def _default_mode() -> int:
    """The permissions a plain ``open(path, "w")`` would give a new file: 0o666 less the umask."""
    try:
        with open("/proc/self/status", encoding="ascii") as status:
            for line in status:
                if line.startswith("Umask:"):
                    return 0o666 & ~int(line.split()[1], 8)
    except (OSError, ValueError, IndexError):
        pass
    umask = os.umask(0o022)  # elsewhere: read by setting it back at once
    os.umask(umask)
    return 0o666 & ~umask


@contextlib.contextmanager
def whole_file(path: str | os.PathLike[str], *, mode: int | None = None, binary: bool = False,
               encoding: str = "utf-8", errors: str = "strict", newline: str | None = None) -> Iterator[IO]:
    """Open a file that replaces ``path`` whole when the block ends without an error.

    Parameters
    ----------
    path : path-like
        The file to write; its folder is made if missing.
    mode : int, optional
        Its permissions; by default those of a new file (``0o666`` less the umask).
    binary : bool
        Yield a binary handle instead of a text one.
    encoding, errors, newline
        As for :func:`open`, for a text handle.

    Yields
    ------
    file object
        The handle of the temporary file.

    Examples
    --------
    >>> import json, tempfile, pathlib
    >>> target = pathlib.Path(tempfile.mkdtemp()) / "records.json"
    >>> with whole_file(target) as handle:
    ...     json.dump({"alice/ch01": "graded"}, handle)
    >>> json.loads(target.read_text())
    {'alice/ch01': 'graded'}
    """
    target = Path(path)
    target.parent.mkdir(parents=True, exist_ok=True)
    # a hidden name beside the target (its first 100 characters: a long name stays a valid one)
    descriptor, temporary = tempfile.mkstemp(prefix=f".{target.name[:100]}.", suffix=".part", dir=target.parent)
    try:
        os.chmod(temporary, _default_mode() if mode is None else mode)
        with (os.fdopen(descriptor, "wb") if binary else
              os.fdopen(descriptor, "w", encoding=encoding, errors=errors, newline=newline)) as handle:
            descriptor = -1  # closed with the handle from here on
            yield handle
            handle.flush()
            os.fsync(handle.fileno())
        os.replace(temporary, target)
    except BaseException:
        if descriptor >= 0:
            os.close(descriptor)
        with contextlib.suppress(OSError):
            os.unlink(temporary)
        raise
    _sync_folder(target.parent)


def write_whole(path: str | os.PathLike[str], data: str | bytes, *, mode: int | None = None,
                encoding: str = "utf-8", errors: str = "strict") -> None:
    """Replace the file ``path`` by ``data`` (``str``, encoded with ``encoding``, or ``bytes``)
    whole or not at all (see :func:`whole_file`)."""
    if not isinstance(data, (str, bytes)):
        raise TypeError(f"data must be str or bytes, got {type(data).__name__}")
    with whole_file(path, mode=mode, binary=isinstance(data, bytes), encoding=encoding, errors=errors,
                    newline="") as handle:
        handle.write(data)


def _sync_folder(folder: Path) -> None:
    """Flush the folder's entry of the new file to the disk, where the system allows it."""
    try:
        descriptor = os.open(folder, os.O_RDONLY | getattr(os, "O_DIRECTORY", 0))
    except OSError:
        return
    try:
        os.fsync(descriptor)
    except OSError:
        pass
    finally:
        os.close(descriptor)
