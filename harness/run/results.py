"""The results table (DESIGN §4): its columns and row order, written atomically (harness/atomic.py) so an
interrupted run loses nothing written."""
from __future__ import annotations

import csv
import math
from pathlib import Path

import pandas as pd

from ..atomic import write_atomic  # noqa: F401 (imported from here too)
from ..precision import FLOAT64
from ..readers import MAX_TABLE_BYTES
from ..scenes.metrics import DRIFT_COLUMNS, ERROR_COLUMNS, TORQUE_COLUMNS

COLUMNS = ("case", "engine", "formulation", "integrator", "precision", "dt", "t_end", "steps", "status", "message",
           "diverged_at", "wall_s", "us_per_step", "us_per_step_spread", "rhs_per_sim_s", *DRIFT_COLUMNS, *ERROR_COLUMNS, "oracle_err",
           "truth_err", "truth_omega_err", "chart_changes", "torque_mode", *TORQUE_COLUMNS)

# Row order in the table and the report: the truth first, then engines as listed, integrators as each engine lists
# them, formulations as the engine lists them, dt descending, precisions as the engine lists them.
SORT_KEYS = ("case", "_engine_rank", "_integrator_rank", "_formulation_rank", "_dt_rank", "_precision_rank")


def row_order(row: dict) -> tuple:
    """A row's place in that order (its SORT_KEYS; 0 for a key it lacks)."""
    return tuple(row.get(key, 0) for key in SORT_KEYS)


def frame(rows: list[dict]) -> pd.DataFrame:
    """A DataFrame with exactly COLUMNS (missing values NaN), in the canonical row order."""
    df = pd.DataFrame(rows)
    for column in COLUMNS:
        if column not in df:
            df[column] = float("nan")
    if df.empty:
        return df[list(COLUMNS)]
    df = df.sort_values([k for k in SORT_KEYS if k in df], kind="stable")
    return df[list(COLUMNS)].reset_index(drop=True)


def write_results(df: pd.DataFrame, path: Path) -> None:
    write_atomic(path, df.to_csv(index=False, float_format="%.10g"))


class TableError(ValueError):
    """A table file that is not what stereodyn writes (empty, not CSV, columns missing): one line, exit 2."""


REQUIRED_COLUMNS = ("case", "engine", "integrator", "status")


def read_csv_table(path: Path, required: tuple[str, ...] = (), **options) -> pd.DataFrame:
    """pd.read_csv, with every way a file can be malformed (empty, garbage, a required column missing) a TableError
    naming the file."""
    try:
        df = pd.read_csv(path, **options)
    except pd.errors.EmptyDataError:
        raise TableError(f"{path}: empty file (not a table)") from None
    except UnicodeDecodeError as exc:
        raise TableError(f"{path}: not UTF-8 text ({exc.reason} at byte {exc.start})") from None
    except (pd.errors.ParserError, ValueError) as exc:
        raise TableError(f"{path}: malformed table: {' '.join(str(exc).split())[:200]}") from None
    missing = [c for c in required if c not in df.columns]
    if missing:
        raise TableError(f"{path}: missing columns {', '.join(missing)} (not a stereodyn table)")
    return df


def with_precision(df: pd.DataFrame) -> pd.DataFrame:
    """The table with a `precision` column: a table of stereodyn 0.2.0 has none, and its runs were all float64."""
    if "precision" not in df:
        df = df.assign(precision=FLOAT64)
    return df.fillna({"precision": FLOAT64}).replace({"precision": {"": FLOAT64}}).astype({"precision": str})


TEXT_COLUMNS = ("case", "engine", "formulation", "integrator", "precision", "status", "message", "torque_mode")
NAMED = ("case", "engine")  # never empty (the integrator is, on a skipped row of an engine that cannot run a case)
# The accuracy metrics the gate, baselines and compare read (every column with one of these suffixes), the timing,
# and the step of a row's key: finite or empty. Elsewhere a number may be inf (as the store writes it).
METRIC_SUFFIXES = ("_drift", "_err", "_err_end")
FINITE = ("dt", "us_per_step")
STATUSES = ("ok", "diverged", "failed", "skipped")  # trajectory.Status


def read_results(path: Path) -> pd.DataFrame:
    """A results.csv, validated: the one reading of the table that `check`, `baseline`, `compare` and `report` share,
    so what one of them refuses the others refuse too. TableError (one line naming the file, and the row and column
    where there is one: row N counts data rows from 1, the header not counted) when the file is too large, empty, not
    CSV, has a row of another length than the header (ragged or truncated), lacks case, engine, integrator or status,
    has no rows, an empty case or engine, a status that is not one of STATUSES, text in a number column, or a
    non-finite metric, timing or dt. Text columns read as text ("" where empty), the others as numbers (NaN where
    empty)."""
    path = Path(path)
    try:
        size = path.stat().st_size
    except OSError as exc:
        raise TableError(f"{path}: cannot read ({exc.strerror or exc})") from None
    if size > MAX_TABLE_BYTES:
        raise TableError(f"{path}: larger than {MAX_TABLE_BYTES} bytes (docs/limits.md)")
    _same_length_rows(path)
    df = read_csv_table(path, REQUIRED_COLUMNS, dtype=str, keep_default_na=False, skip_blank_lines=True)
    if df.empty:
        raise TableError(f"{path}: no rows (a header only)")
    for column in ("formulation", "message"):  # optional text columns a results.csv of an older version may lack
        if column not in df:
            df[column] = ""
    for column in NAMED:
        empty = df.index[df[column].str.strip() == ""]
        if len(empty):
            raise TableError(f"{path}: row {empty[0] + 1}, column {column}: empty")
    bad = df.index[~df["status"].isin(STATUSES)]
    if len(bad):
        raise TableError(f"{path}: row {bad[0] + 1}, column status: {df['status'][bad[0]][:40]!r} is not a status "
                         f"({', '.join(STATUSES)})")
    for column in [c for c in df.columns if c not in TEXT_COLUMNS]:
        text = df[column].str.strip()
        values = pd.to_numeric(text.replace("", "nan"), errors="coerce")
        bad = df.index[values.isna() & (text != "") & (text.str.lower() != "nan")]
        if len(bad):
            raise TableError(f"{path}: row {bad[0] + 1}, column {column}: {text[bad[0]][:40]!r} is not a number")
        if column in FINITE or column.endswith(METRIC_SUFFIXES):
            bad = df.index[values.isin((math.inf, -math.inf))]
            if len(bad):
                raise TableError(f"{path}: row {bad[0] + 1}, column {column}: {text[bad[0]]!r}: must be finite "
                                 "or empty")
        df[column] = values
    return with_precision(df)  # a results.csv of 0.2.0 has none: float64


def _same_length_rows(path: Path) -> None:
    """Every record has the header's number of fields: pandas fills a short (truncated) row with NaN silently, and
    names a long one by its line, not its row."""
    try:
        with open(path, newline="", encoding="utf-8") as handle:
            records = (record for record in csv.reader(handle) if record)
            header = next(records, None)
            for number, record in enumerate(records, 1):
                if len(record) != len(header):
                    raise TableError(f"{path}: row {number}: {len(record)} fields, the header has {len(header)} (a "
                                     "ragged or truncated row)")
    except UnicodeDecodeError as exc:
        raise TableError(f"{path}: not UTF-8 text ({exc.reason} at byte {exc.start})") from None
    except csv.Error as exc:  # a NUL byte, a field larger than csv's limit
        raise TableError(f"{path}: malformed table: {' '.join(str(exc).split())[:200]}") from None
