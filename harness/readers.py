"""Bounded readers of the files stereodyn reads back: case and tolerance files (TOML), store records, runs.json and
baselines (JSON). Whatever a file holds, reading it ends in its value or in a ReadError (one line, the rule): a file
larger than its limit (/dev/zero as a case file read without end), nesting deeper than the parser's stack (a
runs.json of 100,000 brackets: RecursionError), an integer longer than Python converts (5,000 digits: ValueError)
are all ReadErrors, never a traceback. Only a regular file is read: a FIFO would block its reader until a writer
came, a device read without end. Callers name the file (docs/limits.md, "Files stereodyn reads back").
"""
from __future__ import annotations

import json
import os
import stat
import sys
import tomllib
from pathlib import Path
from typing import Any

MAX_TOML_BYTES = 1 << 20   # case and tolerance files; the suite's largest case file is ~2 kB
# Store records hold a run's invariant series (<= MAX_SAMPLES = 100,000 samples, a few series, ~20 bytes a number:
# ~30 MB at most); runs.json a key per run; a baseline ~400 bytes a row (64 MB: 160,000 rows).
MAX_JSON_BYTES = 1 << 28
MAX_BASELINE_BYTES = 1 << 26
MAX_TABLE_BYTES = 1 << 30  # results.csv: ~500 bytes a row (the default suite's 1361 rows: 0.6 MB)


class ReadError(ValueError):
    """A file that cannot be read as what it should be; str() is the rule, without the file's name."""


def kind(mode: int) -> str:
    """What a file of this st_mode is, in words ("a regular file", "a FIFO", ...)."""
    for test, name in ((stat.S_ISREG, "a regular file"), (stat.S_ISDIR, "a folder"), (stat.S_ISFIFO, "a FIFO"),
                       (stat.S_ISCHR, "a character device"), (stat.S_ISBLK, "a block device"),
                       (stat.S_ISSOCK, "a socket"), (stat.S_ISLNK, "a symbolic link")):
        if test(mode):
            return name
    return "a special file"


def must_be_regular(path: str | Path) -> None:
    """ReadError unless path is a regular file (or a link to one): checked before opening, since opening a FIFO
    blocks until a writer opens it. OSError (FileNotFoundError, ...) when it cannot be looked up."""
    mode = os.stat(path).st_mode
    if not stat.S_ISREG(mode):
        raise ReadError(f"not a regular file ({kind(mode)})")


def read_bytes(path: str | Path, limit: int) -> bytes:
    """The bytes of a regular file (ReadError for a FIFO, a device, a folder), reading at most limit + 1 of them (a
    growing file never reads without end)."""
    must_be_regular(path)
    # Non-blocking: a path swapped for a FIFO after the check still opens at once, and fstat refuses it.
    fd = os.open(path, os.O_RDONLY | getattr(os, "O_NONBLOCK", 0))
    with open(fd, "rb") as handle:
        info = os.fstat(fd)
        if not stat.S_ISREG(info.st_mode):
            raise ReadError(f"not a regular file ({kind(info.st_mode)})")
        if info.st_size > limit:  # said before a byte is read (a 300 MB file is not read to be refused)
            raise ReadError(f"larger than {limit} bytes (docs/limits.md)")
        raw = handle.read(limit + 1)
    if len(raw) > limit:
        raise ReadError(f"larger than {limit} bytes (docs/limits.md)")
    return raw


def parse_toml(raw: bytes) -> dict[str, Any]:
    """TOML from bytes (a UTF-8 byte-order mark is dropped)."""
    try:
        return tomllib.loads(raw.decode("utf-8-sig"))
    except UnicodeDecodeError:
        raise ReadError("invalid TOML: not UTF-8 text") from None
    except tomllib.TOMLDecodeError as exc:
        raise ReadError("invalid TOML: " + " ".join(str(exc).split())[:300]) from None
    except RecursionError:  # tomllib recurses once per nesting level: thousands of [[[...]]] exhaust the stack
        raise ReadError("invalid TOML: arrays or tables nested too deep") from None
    except ValueError as exc:  # an integer of more than sys.get_int_max_str_digits() digits
        raise ReadError(f"invalid TOML: {_rule(exc)}") from None


def parse_json(raw: bytes | str) -> Any:
    try:
        return json.loads(raw)
    except UnicodeDecodeError:
        raise ReadError("invalid JSON: not UTF-8 text") from None
    except RecursionError:
        raise ReadError("invalid JSON: nested too deep") from None
    except ValueError as exc:  # json.JSONDecodeError, or an integer of too many digits
        raise ReadError(f"invalid JSON: {_rule(exc)}") from None


def _rule(exc: ValueError) -> str:
    if "integer string conversion" in str(exc):
        return f"an integer of more than {sys.get_int_max_str_digits()} digits"
    return " ".join(str(exc).split())[:200]


def read_toml(path: str | Path, limit: int = MAX_TOML_BYTES) -> dict[str, Any]:
    """A TOML file; OSError when it cannot be opened, ReadError otherwise."""
    return parse_toml(read_bytes(path, limit))


def read_json(path: str | Path, limit: int = MAX_JSON_BYTES) -> Any:
    """A JSON file; OSError when it cannot be opened, ReadError otherwise."""
    return parse_json(read_bytes(path, limit))
