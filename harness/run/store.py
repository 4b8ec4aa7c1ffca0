"""The result store: one JSON file per run, DIR/store/<key>.json, written atomically.

A run's key hashes everything its row depends on: the case's content, engine, formulation, integrator, dt, whether
the truth is certified, the library versions, and the code: a fingerprint of stereodyn's installed source files and,
for the run's engine and integrator classes, their distribution, version and source hash (harness.environment), so a
changed line of code, even without a new version, is never served from the store. A record is written (temporary
file, fsync, rename) the moment its run finishes, so an interrupted sweep loses nothing already computed and never
leaves a partial record; `--resume` reuses the records whose key matches and whose shape is right (anything else
counts as absent and is redone). results.csv and DIR/runs.json (the sweep's keys, environment and code fingerprints)
are assembled from the records.

A command holds an exclusive lock on DIR/store while it writes the folder (folder_lock: `stereodyn run` for the
sweep, work–precision and the report; `report` for the report), so two commands never write one folder, and any
temporary file found there (TEMPORARY_FOLDERS) is the leftover of a killed process: it is removed when the next
command takes the lock.
"""
from __future__ import annotations

import dataclasses
import hashlib
import io
import json
import math
import os
from collections.abc import Iterator
from contextlib import contextmanager
from pathlib import Path
from typing import Any

import numpy as np
import pandas as pd

from ..scenes.cases import Case
from ..precision import FLOAT64
from ..environment import code_origin, library_versions, source_fingerprint
from ..scenes.checks import ROW_KEY
from ..readers import ReadError, read_json
from ..words import one_line
from .results import COLUMNS, value_rule, write_atomic
from ..trajectory import Status

STORE_DIR = "store"
TRAJECTORIES_DIR = "trajectories"  # stereodyn run --save-trajectories: DIR/trajectories/<key>.npz
TRAJECTORY_INDEX = "index.csv"     # DIR/trajectories/index.csv: each saved run's key columns -> its file
TRAJECTORY_INDEX_COLUMNS = ("case", "engine", "formulation", "integrator", "dt", "status", "file")
STATE_ARRAYS = ("times", "quat", "omega", "truth_quat", "truth_omega")
MANIFEST = "runs.json"
FORMAT = 1
COMPLETE = "complete"  # runs.json: false while a sweep writes the folder, true once its command ended (mark_complete)
# The completion mark's second witness: DIR/store/unfinished exists from the moment a sweep opens the store until
# mark_complete, so a killed sweep's folder stays unfinished when its runs.json is then lost, cut or garbled
# (completeness). A folder of 0.2.0, or of a finished sweep, has none.
UNFINISHED = "unfinished"

try:
    import fcntl
except ImportError:  # not POSIX: no lock; the store still never holds a partial record
    fcntl = None


class StoreBusy(RuntimeError):
    """Another sweep holds the folder's lock."""


# The folders under DIR that stereodyn writes with write_atomic (DIR itself, the store, the figures): where a killed
# process may have left a .NAME.*.tmp. Not the whole tree under DIR: `--out .` must never delete a user's files.
TEMPORARY_FOLDERS = (".", STORE_DIR, "figures", TRAJECTORIES_DIR)
# Locks held by this process: resolved DIR/store -> [descriptor, open Stores]. flock conflicts between two descriptors
# even in one process, so the command's lock and the sweep's Store share one descriptor and nest.
_HELD: dict[str, list[int]] = {}


@contextmanager
def folder_lock(out_dir: Path, store: bool = False) -> Iterator[None]:
    """Hold DIR's exclusive lock (on DIR/store) for the block; StoreBusy when another process holds it. `stereodyn
    run` takes it for the whole command (sweep, work–precision, report) and the sweep's Store (store=True) inside
    it; in one process a second Store of the folder is still refused."""
    out_dir = Path(out_dir)
    root = out_dir / STORE_DIR
    root.mkdir(parents=True, exist_ok=True)
    name = os.path.realpath(root)
    busy = StoreBusy(f"{out_dir}: another stereodyn command is writing to this folder (try again when it has "
                     f"written its report)")
    if name in _HELD:
        held = _HELD[name]
        if store and held[1]:
            raise busy
        held[1] += store
        try:
            yield
        finally:
            held[1] -= store
        return
    fd = None
    if fcntl is not None:
        fd = os.open(root, os.O_RDONLY)
        try:
            fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
        except BlockingIOError:
            os.close(fd)
            raise busy from None
    _HELD[name] = [-1 if fd is None else fd, int(store)]
    try:
        remove_partial_files(out_dir)
        yield
    finally:
        del _HELD[name]
        if fd is not None:
            os.close(fd)  # closing the descriptor releases the lock


def remove_partial_files(out_dir: Path) -> list[Path]:
    """Delete the temporary files of interrupted atomic writes (harness.atomic.write_atomic's .NAME.*.tmp) in the
    folders stereodyn writes under DIR (TEMPORARY_FOLDERS)."""
    leftovers = [path for folder in TEMPORARY_FOLDERS for path in (Path(out_dir) / folder).glob(".*.tmp")]
    for path in leftovers:
        path.unlink(missing_ok=True)
    return leftovers


def _plain(value: Any) -> Any:
    """JSON-ready: numpy scalars and arrays as Python numbers and lists, NaN as null."""
    if isinstance(value, np.ndarray):
        value = value.tolist()
    if isinstance(value, (list, tuple)):
        if all(type(v) is float for v in value) and all(map(math.isfinite, value)):
            return list(value)  # a series of finite numbers as it is: element by element was 5 s of a default run
        return [_plain(v) for v in value]
    if isinstance(value, dict):
        return {str(k): _plain(v) for k, v in value.items()}
    if isinstance(value, np.generic):
        value = value.item()
    if isinstance(value, float) and not math.isfinite(value):
        return None if math.isnan(value) else repr(value)
    return value


# Case fields that do not change a run's row: words, where the file was, and the other steps of the sweep.
NOT_CONTENT = ("description", "tags", "path", "dt")


def case_content(case: Case) -> dict:
    """What a case's runs depend on: every field but NOT_CONTENT (a field added to Case is part of it at once)."""
    content = {}
    for field in dataclasses.fields(case):
        if field.name not in NOT_CONTENT:
            value = getattr(case, field.name)
            if field.name == "torques":  # the terms (reference.torque_models), by their case table
                value = {term.key: dataclasses.asdict(term) for term in value}
            content[field.name] = dataclasses.asdict(value) if dataclasses.is_dataclass(value) else value
    return _plain(content)


def run_identity(case: Case, engine: str, formulation: str, integrator: str, dt: float | None, certify: bool,
                 versions: dict[str, str], code: dict | None = None, precision: str = FLOAT64) -> dict:
    """Everything a run's row depends on. code: the fingerprints of the code that runs it (Store.code)."""
    return {"case": case_content(case), "engine": engine, "formulation": formulation, "integrator": integrator,
            "precision": precision, "dt": None if dt is None else float(dt), "certify": bool(certify),
            "versions": versions, "code": code}


def integrator_classes(name: str) -> list[type]:
    """Every registered class called `name`, one per state space (an engine picks the one of its space)."""
    from .. import integrators

    return [integrators.get(name, space) for space in integrators.state_spaces() if name in integrators.names(space)]


def engine_class(name: str) -> type:
    from ..engines import get_engine

    return type(get_engine(name))


def run_key(identity: dict) -> str:
    """sha256 of the identity's canonical JSON (floats by repr, so bit-exact), first 24 hex digits."""
    text = json.dumps(identity, sort_keys=True, separators=(",", ":"))
    return hashlib.sha256(text.encode()).hexdigest()[:24]


SEALED = ("format", "key", "identity", "row", "budget")  # a record's parts the seal covers
_RECORD_KEYS = frozenset({*SEALED, "series", "seal"})  # every key put() writes


def seal(record: dict) -> str:
    """The digest Store.put writes into a record: sha256 of the canonical JSON of what the results are made of (its
    key, identity, row and budget; not the series, which only the figures read), first 24 hex digits. A record whose
    seal does not match is not exactly what put() wrote (a metric deleted, a key added, its identity's dt edited:
    each was reused by --resume, issue 46's ninth attack) and counts as absent."""
    sealed = {name: record.get(name) for name in SEALED}
    return hashlib.sha256(json.dumps(sealed, sort_keys=True, separators=(",", ":")).encode()).hexdigest()[:24]


_TEXT_COLUMNS = ("case", "engine", "formulation", "integrator", "precision", "status", "message", "timing")
_IDENTITY_COLUMNS = ("engine", "formulation", "integrator", "precision")  # in both the identity and the row
_STATUSES = frozenset(s.value for s in Status)


def _is_number(column: str, value: Any) -> bool:
    """A number column's JSON value as _plain writes it: null (NaN), "inf"/"-inf" (what the run computed, kept as it
    was), or a finite number within the column's rule (results.value_rule, the rule of every reader of rows: no
    negative metric or count, no dt <= 0, nothing above MAX_VALUE), never a NaN literal (_plain writes null). A
    hand-edited record outside it is redone, not copied into a results.csv that check would refuse."""
    if value is None or value in ("inf", "-inf"):
        return True
    if isinstance(value, bool) or not isinstance(value, (int, float)):
        return False
    try:
        number = float(value)
    except OverflowError:  # an integer of hundreds of digits
        return False
    return math.isfinite(number) and value_rule(column, number) is None


def well_formed(record: Any, key: str) -> bool:
    """Whether a stored record has the shape Store.put writes: the format, its own key, its seal (seal), an identity,
    a row whose status is a Status, whose text columns are text and whose other columns are numbers, and
    series/checks of the right container type. A record failing this is treated as absent (redone, never copied into results.csv)."""
    if not (isinstance(record, dict) and record.get("format") == FORMAT and record.get("key") == key
            and isinstance(record.get("identity"), dict) and isinstance(record.get("row"), dict)
            and isinstance(record.get("series"), (dict, type(None))) and record.keys() <= _RECORD_KEYS
            and record.get("seal") == seal(record)):
        return False
    row = record["row"]
    if row.get("status") not in _STATUSES or not all(isinstance(row.get(c), str) for c in ("case", "engine")):
        return False
    identity = record["identity"]
    if any(c in identity and c in row and row[c] != identity[c] for c in _IDENTITY_COLUMNS):
        return False
    for column in COLUMNS:
        value = row.get(column)
        if column in _TEXT_COLUMNS or column == "torque_mode":
            if not isinstance(value, (str, type(None))):
                return False
        elif not _is_number(column, value):
            return False
    return isinstance(row.get(ROW_KEY), (list, type(None)))


def _row_from_json(row: dict) -> dict:
    """The inverse of _plain on a row: null back to NaN ("" in text columns), "inf" back to a float."""
    out = {}
    for column, value in row.items():
        if column in _TEXT_COLUMNS:
            out[column] = "" if value is None else value
        elif value is None:
            out[column] = math.nan
        elif value in ("inf", "-inf"):
            out[column] = float(value)
        else:
            out[column] = value
    return out


_STATUSES = frozenset(status.value for status in Status)
_NUMERIC_COLUMNS = frozenset(COLUMNS) - {*_TEXT_COLUMNS, "torque_mode"}


def _valid_row(row: Any) -> bool:
    """A stored row as put() writes it: a status of Status, text in the text columns, numbers (or null, or "inf" /
    "-inf") in results.csv's numeric columns. Other columns (the checks, columns added later) are not judged here."""
    if not isinstance(row, dict) or row.get("status") not in _STATUSES:
        return False
    for column, value in row.items():
        if column in _TEXT_COLUMNS:
            if not isinstance(value, (str, type(None))):
                return False
        elif column in _NUMERIC_COLUMNS and not (value is None or value in ("inf", "-inf") or (
                isinstance(value, (int, float)) and not isinstance(value, bool))):
            return False
    return True


class Store:
    """The records under DIR/store. Use as a context manager: it takes the folder's lock and clears leftovers."""

    def __init__(self, out_dir: Path):
        self.out_dir = Path(out_dir)
        self.root = self.out_dir / STORE_DIR
        self.versions = library_versions()
        self.source = source_fingerprint()
        self._origins: dict[tuple[str, str], Any] = {}  # ("engine"|"integrator", name) -> code_origin(s)

    def __enter__(self) -> "Store":
        self._lock = folder_lock(self.out_dir, store=True)
        self._lock.__enter__()
        try:  # before any table is rewritten: the folder is unfinished until its command's mark_complete
            write_atomic(self.root / UNFINISHED, "a sweep writes this folder, or was stopped before its end: finish it "
                                                 "with stereodyn run ... --resume (runs.json: complete)\n")
        except BaseException:
            self._lock.__exit__(None, None, None)
            raise
        return self

    def __exit__(self, *exc) -> None:
        try:
            if exc[0] is not None:  # interrupted: an atomic write cut short between mkstemp and its try may leave one
                self.remove_partial_files()
        finally:
            self._lock.__exit__(*exc)

    def remove_partial_files(self) -> list[Path]:
        """Delete the temporary files of interrupted atomic writes under DIR (remove_partial_files)."""
        return remove_partial_files(self.out_dir)

    def code(self, engine: str, integrator: str) -> dict:
        """The code fingerprints of a run: stereodyn's source, its engine's class and every class registered under its
        integrator's name (an engine's own integrator, e.g. MuJoCo's implicit, has none: the engine's version holds)."""
        if ("engine", engine) not in self._origins:
            self._origins["engine", engine] = code_origin(engine_class(engine))
        if ("integrator", integrator) not in self._origins:
            self._origins["integrator", integrator] = [code_origin(c) for c in integrator_classes(integrator)]
        return {"stereodyn": self.source, "engine": self._origins["engine", engine],
                "integrator": self._origins["integrator", integrator]}

    def identity(self, case: Case, engine: str, formulation: str, integrator: str, dt: float | None,
                 certify: bool, precision: str = FLOAT64) -> dict:
        return run_identity(case, engine, formulation, integrator, dt, certify, self.versions,
                            self.code(engine, integrator), precision)

    def code_manifest(self) -> dict:
        """runs.json's "code": stereodyn's source fingerprint and the origin of each engine and integrator used."""
        listed: dict[str, Any] = {"stereodyn source": self.source, "engines": {}, "integrators": {}}
        for (kind, name), origin in sorted(self._origins.items()):
            listed[f"{kind}s"][name] = origin
        return listed

    def path(self, key: str) -> Path:
        return self.root / f"{key}.json"

    def get(self, key: str) -> dict | None:
        """The record {"identity", "row", "series"} of a finished run, or None. An unreadable record, or one of the
        wrong shape (well_formed), counts as absent (it is rewritten when the run is redone)."""
        try:
            record = read_json(self.path(key))
        except (OSError, ReadError):  # absent, too large, not JSON, nested too deep: recompute the run
            return None
        if not well_formed(record, key):
            return None  # not a record this version wrote: recompute the run
        record["row"] = _row_from_json(record["row"])
        return record

    def put(self, key: str, identity: dict, row: dict, series: dict | None, budget: dict | None = None) -> None:
        """Write one run's record atomically. row: the public columns (keys starting with "_" are dropped); budget:
        for a run its wall-time budget stopped, which budget ({"what", "seconds"}, harness.budget.failed_row), so
        that --resume redoes it only when that budget was raised (harness.budget.still_holds)."""
        public = {k: v for k, v in row.items() if not k.startswith("_")}
        record = {"format": FORMAT, "key": key, "identity": identity, "row": _plain(public),
                  "series": _plain(series)}
        if budget is not None:
            record["budget"] = _plain(budget)
        record["seal"] = seal(record)
        write_atomic(self.path(key), json.dumps(record, separators=(",", ":")) + "\n")

    def states_path(self, key: str) -> Path:
        return self.out_dir / TRAJECTORIES_DIR / f"{key}.npz"

    def put_states(self, key: str, row: dict, states: dict) -> None:
        """Write a run's recorded states atomically to DIR/trajectories/<key>.npz: arrays times (n,) s, quat (n, 4)
        wxyz body -> world, omega (n, 3) rad/s body frame (NaN after a divergence), truth_quat (n, 4) and truth_omega
        (n, 3): the case's truth at the same times, and the row's case, engine, formulation, integrator (0-d strings)
        and dt (0-d float, NaN for an adaptive integrator)."""
        buffer = io.BytesIO()
        arrays = {name: np.asarray(states[name], dtype=float) for name in STATE_ARRAYS if name in states}
        np.savez(buffer, **arrays,
                 **{c: np.str_(row.get(c) or "") for c in ("case", "engine", "formulation", "integrator")},
                 dt=np.float64(row.get("dt", math.nan)))
        path = self.states_path(key)
        path.parent.mkdir(exist_ok=True)
        write_atomic(path, buffer.getvalue())

    def write_trajectory_index(self, rows: list[tuple[dict, str]]) -> None:
        """DIR/trajectories/index.csv: one line per saved run (rows: (its results row, its key)), its key columns
        (case, engine, formulation, integrator, dt), status and file (relative to DIR), in results.csv's order."""
        lines = [{**{c: row.get(c) for c in TRAJECTORY_INDEX_COLUMNS[:6]},
                  "file": f"{TRAJECTORIES_DIR}/{key}.npz"} for row, key in rows
                 if self.states_path(key).is_file()]
        path = self.out_dir / TRAJECTORIES_DIR / TRAJECTORY_INDEX
        path.parent.mkdir(exist_ok=True)
        write_atomic(path, pd.DataFrame(lines, columns=list(TRAJECTORY_INDEX_COLUMNS)).to_csv(index=False))

    def write_manifest(self, keys: list[str], environment: dict, complete: bool = False) -> None:
        """DIR/runs.json: the store keys behind results.csv, the environment of the sweep, the code fingerprints in
        its keys ("code": code_manifest()), and whether the folder is complete (COMPLETE; mark_complete)."""
        write_atomic(self.out_dir / MANIFEST, json.dumps({"format": FORMAT, "environment": environment,
                                                          "code": self.code_manifest(), "runs": keys,
                                                          COMPLETE: complete}, indent=1) + "\n")


def read_manifest(out_dir: Path) -> dict | None:
    """DIR/runs.json, or None when the folder has none (results.csv from elsewhere) or one this version cannot read
    (manifest_problem says why)."""
    return _manifest(out_dir)[0]


def manifest_problem(out_dir: Path) -> str | None:
    """Why DIR/runs.json, which is there, is no runs.json this version reads (not a regular file, larger than the
    readers' limit, not JSON, another shape), in one line naming it; None when it reads, or is absent."""
    return _manifest(out_dir)[1]


def _manifest(out_dir: Path) -> tuple[dict | None, str | None]:
    path = Path(out_dir) / MANIFEST
    try:
        manifest = read_json(path)
    except FileNotFoundError:
        return None, None
    except (OSError, ReadError) as exc:
        reason = exc.strerror if isinstance(exc, OSError) and exc.strerror else str(exc)
        return None, f"{path}: not a runs.json stereodyn can read ({reason})"
    if not isinstance(manifest, dict) or manifest.get("format") != FORMAT:
        return None, f"{path}: not a runs.json stereodyn can read (no \"format\": {FORMAT})"
    runs, environment = manifest.get("runs", []), manifest.get("environment")
    if not (isinstance(runs, list) and all(isinstance(key, str) for key in runs)
            and isinstance(environment, (dict, type(None))) and isinstance(manifest.get(COMPLETE, False), bool)):
        # not a manifest this version wrote: as if the folder had none
        return None, f"{path}: not a runs.json stereodyn can read (runs, environment or {COMPLETE} of another shape)"
    if environment:  # a hand-edited value's ESC or newline reached check's terminal, the step summary, the report
        manifest = {**manifest, "environment": {one_line(k): one_line(v) if isinstance(v, str) else v
                                                for k, v in environment.items()}}
    return manifest, None


def mark_complete(out_dir: Path) -> None:
    """Mark DIR complete: the command that wrote it (a whole sweep; `stereodyn run`: its sweep, work–precision
    tables and report) ended. Called with the folder's lock held, as the command's last write."""
    manifest = read_manifest(out_dir)
    if manifest is not None:
        write_atomic(Path(out_dir) / MANIFEST, json.dumps({**manifest, COMPLETE: True}, indent=1) + "\n")
        # after the mark: killed between the two, the folder reads as unfinished, and --resume ends it
        (Path(out_dir) / STORE_DIR / UNFINISHED).unlink(missing_ok=True)


class FolderNotReady(ValueError):
    """A result folder a command may not read (yet): a sweep left it unfinished. Bad input, exit 2, one line."""


def sweep_ended(out_dir: Path) -> bool:
    """Whether DIR holds a sweep that ended: runs.json complete and no unfinished witness (completeness's mark)."""
    manifest = read_manifest(out_dir)
    return bool(manifest) and manifest.get(COMPLETE) is True and not (Path(out_dir) / STORE_DIR / UNFINISHED).exists()


def completeness(out_dir: Path, allow_partial: bool = False) -> list[str]:
    """Whether a command may read DIR, by its completion mark (runs.json "complete") and its witness (DIR/store/
    unfinished, UNFINISHED): FolderNotReady for an unfinished one, by either (unless allow_partial); the warnings to
    print (one line each) for a partial or an unmarked one (a folder of stereodyn 0.2.0, which wrote no mark, or
    tables from elsewhere)."""
    manifest = read_manifest(out_dir)
    mark = None if manifest is None else manifest.get(COMPLETE)
    if (Path(out_dir) / STORE_DIR / UNFINISHED).exists():  # runs.json lost, cut or garbled after a kill
        mark = False
    if mark is True:
        return []
    if mark is False:
        if not allow_partial:
            raise FolderNotReady(f"{out_dir}: an unfinished sweep (interrupted, killed or still running): finish it "
                                 f"with stereodyn run ... --resume --out {out_dir}, or read it as it is with "
                                 "--allow-partial")
        return [f"{out_dir}: an unfinished sweep, read as it is (--allow-partial)"]
    if not (Path(out_dir) / "results.csv").is_file():
        return []  # nothing to read: the reader says so
    problem = manifest_problem(out_dir)
    if problem:  # garbled, cut or huge: named, and read as a folder without one
        return [f"{problem}: read as it is, as a folder without one (no completion mark, no environment)"]
    return [f"{out_dir}: no completion mark (written by stereodyn 0.2.0 or elsewhere): read as it is"]


@contextmanager
def reading(out_dir: Path, allow_partial: bool = False) -> Iterator[list[str]]:
    """Hold DIR's lock shared while a command reads the folder (check, baseline, compare): StoreBusy when a command
    is writing it (a sweep holds the lock exclusively from its start to its report), FolderNotReady when a sweep left
    it unfinished (completeness). Yields completeness's warnings. A folder without DIR/store has no writer to wait
    for (tables copied from elsewhere)."""
    out_dir = Path(out_dir)
    root = out_dir / STORE_DIR
    busy = StoreBusy(f"{out_dir}: a stereodyn command is writing this folder (try again when it has finished)")
    if os.path.realpath(root) in _HELD:
        raise busy
    fd = None
    if fcntl is not None and root.is_dir():
        fd = os.open(root, os.O_RDONLY)
        try:
            fcntl.flock(fd, fcntl.LOCK_SH | fcntl.LOCK_NB)
        except BlockingIOError:
            os.close(fd)
            raise busy from None
    try:
        yield completeness(out_dir, allow_partial)
    finally:
        if fd is not None:
            os.close(fd)


def read_records(out_dir: Path) -> list[dict]:
    """The records listed in DIR/runs.json (those still present), or [] without a manifest."""
    manifest = read_manifest(out_dir)
    if manifest is None:
        return []
    store = Store(out_dir)
    return [record for key in manifest.get("runs", []) if (record := store.get(key)) is not None]
