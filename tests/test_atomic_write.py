"""write_atomic (harness/atomic.py): a write that fails mid-way leaves the old file intact and no temporary."""
import os

import pytest

from stereodyn.harness import atomic
from stereodyn.harness.atomic import write_atomic


class _HalfWriter:
    """A file handle that writes half of what it is given, then fails (a full disk, a killed process)."""

    def __init__(self, handle):
        self._handle = handle

    def write(self, data):
        self._handle.write(data[: len(data) // 2])
        self._handle.flush()
        raise OSError(28, "No space left on device")

    def __getattr__(self, name):
        return getattr(self._handle, name)

    def __enter__(self):
        return self

    def __exit__(self, *exc):
        self._handle.close()
        return False


@pytest.mark.parametrize("payload", ["new text, much longer than the old one\n" * 50, b"\x00\x01new bytes" * 50])
def test_a_write_failing_mid_way_leaves_the_old_file_and_no_temporary(tmp_path, monkeypatch, payload):
    target = tmp_path / "results.csv"
    target.write_text("old,contents\n1,2\n")
    real_fdopen = os.fdopen
    monkeypatch.setattr(atomic.os, "fdopen", lambda *a, **k: _HalfWriter(real_fdopen(*a, **k)))
    monkeypatch.setattr("builtins.open", lambda *a, **k: _HalfWriter(real_fdopen(os.open(a[0], os.O_WRONLY
                                                                       | os.O_CREAT | os.O_TRUNC), *a[1:], **k)))
    with pytest.raises(OSError, match="No space left"):
        write_atomic(target, payload)
    monkeypatch.undo()
    assert target.read_text() == "old,contents\n1,2\n"
    assert sorted(p.name for p in tmp_path.iterdir()) == ["results.csv"]


def test_a_failing_rename_leaves_the_old_file_and_no_temporary(tmp_path, monkeypatch):
    target = tmp_path / "runs.json"
    target.write_text("{}")

    def refuse(src, dst):
        raise PermissionError(13, "Permission denied", str(dst))

    monkeypatch.setattr(atomic.os, "replace", refuse)
    with pytest.raises(PermissionError):
        write_atomic(target, "{\"new\": 1}")
    monkeypatch.undo()
    assert target.read_text() == "{}"
    assert sorted(p.name for p in tmp_path.iterdir()) == ["runs.json"]


def test_a_write_replaces_the_file_readable_by_all(tmp_path):
    target = tmp_path / "out.txt"
    target.write_text("old")
    write_atomic(target, "new")
    assert target.read_text() == "new" and (target.stat().st_mode & 0o777) == 0o644
    assert sorted(p.name for p in tmp_path.iterdir()) == ["out.txt"]


def test_the_temporary_file_is_beside_the_target(tmp_path, monkeypatch):
    """A rename is atomic only within one file system: the temporary is written in the target's folder, never in the
    system's temporary folder (here another folder, as /tmp often is another file system), and named .NAME.*.tmp so
    that the next command into the folder removes it if a kill left it (harness.store.remove_partial_files)."""
    elsewhere = tmp_path / "system-temp"
    elsewhere.mkdir()
    monkeypatch.setenv("TMPDIR", str(elsewhere))
    monkeypatch.setattr(atomic.tempfile, "tempdir", str(elsewhere))
    target = tmp_path / "out" / "results.csv"
    target.parent.mkdir()
    renamed = []
    real_replace = os.replace

    def spy(src, dst):
        renamed.append((os.path.realpath(src), os.path.realpath(dst)))
        assert sorted(p.name for p in elsewhere.iterdir()) == []
        return real_replace(src, dst)

    monkeypatch.setattr(atomic.os, "replace", spy)
    write_atomic(target, "a,b\n1,2\n")
    [(src, dst)] = renamed
    assert os.path.dirname(src) == os.path.dirname(dst) == os.path.realpath(target.parent)
    assert os.path.basename(src).startswith(".results.csv.") and src.endswith(".tmp")
    assert target.read_text() == "a,b\n1,2\n" and sorted(p.name for p in target.parent.iterdir()) == ["results.csv"]


def test_a_folder_where_the_file_goes_is_named_not_the_temporary(tmp_path):
    """Issue 46's twelfth attack, F10: a store record's path made a folder gave "Is a directory:" and the name of
    our temporary file (.KEY.json.abc.tmp beside it), a name the user never made. The error names the path the write was for, and no
    temporary is left. Break-checked: with only a nameless error renamed, the message names the temporary."""
    target = tmp_path / "record.json"
    target.mkdir()
    with pytest.raises(IsADirectoryError) as caught:
        write_atomic(target, "{}")
    assert caught.value.filename == str(target) and ".tmp" not in str(caught.value), str(caught.value)
    assert sorted(p.name for p in tmp_path.iterdir()) == ["record.json"]
