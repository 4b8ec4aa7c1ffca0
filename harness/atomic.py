"""Atomic file writes: every table, record and report stereodyn writes goes through a temporary file and a rename, so
that an interrupted run or a reader racing it never sees a partial file."""
from __future__ import annotations

import os
import tempfile
from pathlib import Path


def write_atomic(path: Path, text: str | bytes) -> None:
    """Write text (or bytes) to path through a temporary file in the same folder and a rename: readers never see a
    partial file."""
    path = Path(path)
    fd, tmp = tempfile.mkstemp(dir=path.parent, prefix=f".{path.name}.", suffix=".tmp")
    try:
        os.fchmod(fd, 0o644)  # mkstemp makes the file private (0600); the result is an ordinary file
        options = {"mode": "wb"} if isinstance(text, bytes) else {"mode": "w", "encoding": "utf-8", "newline": ""}
        with os.fdopen(fd, **options) as handle:
            handle.write(text)
            handle.flush()
            os.fsync(handle.fileno())
        os.replace(tmp, path)
    except BaseException as exc:
        Path(tmp).unlink(missing_ok=True)
        # a full disk: write() and fsync() name no file; a folder at path: the rename names our temporary file
        if isinstance(exc, OSError) and exc.filename in (None, tmp):
            raise OSError(exc.errno, exc.strerror, str(path)) from exc
        raise


def append_regular(path: Path, text: str) -> None:
    """Append text to path, a regular file or a new path (created), without ever blocking: anything else (a FIFO,
    whose open waits for a reader forever; a device) is an OSError saying what it is, before a byte is written.
    Checked before the open and again on the open file (opened non-blocking: a path swapped for a FIFO in between
    still opens at once, or fails, and fstat refuses it)."""
    import errno
    import stat

    from .readers import kind

    def refuse(mode: int) -> None:
        if not stat.S_ISREG(mode):
            raise OSError(errno.EINVAL, f"not a regular file ({kind(mode)})", str(path))

    try:
        refuse(os.stat(path).st_mode)
    except FileNotFoundError:
        pass  # a new path
    fd = os.open(path, os.O_WRONLY | os.O_APPEND | os.O_CREAT | getattr(os, "O_NONBLOCK", 0), 0o644)
    try:
        refuse(os.fstat(fd).st_mode)
        data = text.encode("utf-8")
        while data:
            data = data[os.write(fd, data):]
    finally:
        os.close(fd)
