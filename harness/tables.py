"""Reading a table stereodyn wrote (results.csv and the tables derived from it: pareto.csv, advice.csv,
convergence.csv, ...) with every way the file can be malformed one TableError naming it, never a table silently short
of rows: results.csv's validation of its cells is harness/run/results.py's read_results."""
from __future__ import annotations

import csv
import math
from pathlib import Path

import numpy as np
import pandas as pd

from .precision import FLOAT64
from .readers import MAX_TABLE_BYTES, ReadError, must_be_regular


class TableError(ValueError):
    """A table file that is not what stereodyn writes (empty, not CSV, columns missing): one line, exit 2."""


def read_csv_table(path: Path, required: tuple[str, ...] = (), **options) -> pd.DataFrame:
    """pd.read_csv of a table stereodyn wrote (results.csv, pareto.csv, advice.csv, convergence.csv, ...), with every
    way a file can be malformed a TableError naming the file: not a regular file (a FIFO would block the reader),
    larger than MAX_TABLE_BYTES, a row of another length than the header (a file cut mid-row: pandas would fill it
    with NaN silently), empty, garbage, a required column missing."""
    path = Path(path)
    try:
        must_be_regular(path)
        size = path.stat().st_size
    except ReadError as exc:
        raise TableError(f"{path}: {exc}") from None
    except OSError as exc:
        raise TableError(f"{path}: cannot read ({exc.strerror or exc})") from None
    if size > MAX_TABLE_BYTES:
        raise TableError(f"{path}: larger than {MAX_TABLE_BYTES} bytes (docs/limits.md)")
    _same_length_rows(path)
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


# The derived tables of one row per key: a row twice (by hand) was read as a second fit ("1.03 / 2.50") by the report
# while check refused it (issue 46's twelfth attack). A key column a table of an older version lacks is left out.
ONE_ROW_PER = {"convergence.csv": ("case", "engine", "formulation", "integrator", "precision")}


# The derived tables' columns of convergence orders: a number (or empty) in [-MAX_ORDER, MAX_ORDER], a declared one
# in (0, MAX_ORDER] (integrators.base.order_problem's rule). Every reader (check, history, baseline, compare, the
# report) reads them here: 1e308, inf and "four" were refused by some and shown or taken as "none" by others (issue
# 46's thirteenth attack).
ORDER_COLUMNS = {"convergence.csv": ("order", "declared_order")}


def _orders_problem(df: pd.DataFrame, column: str) -> str | None:
    from .integrators.base import MAX_ORDER

    for row, cell in enumerate(df[column], 1):
        if not isinstance(cell, str) and pd.isna(cell):  # empty: no fit
            continue
        cell = str(cell).strip()  # "four" is text where a number was written
        try:
            value = float(cell)
        except ValueError:
            value = math.nan
        if math.isnan(value) and cell.lower() == "nan":
            continue
        if not math.isfinite(value) or abs(value) > MAX_ORDER or (column == "declared_order" and value <= 0):
            rule = f"in (0, {MAX_ORDER}]" if column == "declared_order" else f"within -{MAX_ORDER} .. {MAX_ORDER}"
            return f"row {row}: {column} = {cell[:40]!r}: must be a finite number {rule} (a convergence order)"
    return None


def read_optional(path: Path, text_columns: tuple[str, ...] = ("formulation",)) -> pd.DataFrame | None:
    """A derived table (convergence.csv, ladder.csv, ...), or None where the run wrote none; text columns read as text
    with "" for empty cells; TableError for one that is malformed, never a table silently short of rows, nor one
    holding a key of ONE_ROW_PER twice, nor an order of ORDER_COLUMNS out of its bounds."""
    if not Path(path).exists():
        return None
    df = read_csv_table(path, dtype={c: str for c in text_columns}, keep_default_na=True)
    df = df.fillna({c: "" for c in text_columns if c in df})
    for column in ORDER_COLUMNS.get(Path(path).name, ()):
        why = _orders_problem(df, column) if column in df else None
        if why:
            raise TableError(f"{path}: {why}")
    key = [c for c in ONE_ROW_PER.get(Path(path).name, ()) if c in df]
    twice = df.index[df.duplicated(key, keep="first")] if key else []
    if len(twice):
        first = df.index[(df[key] == df.loc[twice[0], key]).all(axis=1)][0]
        raise TableError(f"{path}: row {twice[0] + 1}: duplicate key "
                         f"{' '.join(f'{c}={df.loc[twice[0], c]}' for c in key)} (also row {first + 1}): one row per "
                         "run family")
    return df


def _same_length_rows(path: Path) -> None:
    """Every record has the header's number of fields, and the last ends its line: pandas fills a short (truncated)
    row with NaN silently, and names a long one by its line, not its row; a file cut inside its last field has every
    field, but no newline after it (stereodyn ends every table with one)."""
    try:
        with open(path, newline="", encoding="utf-8") as handle:
            records = (record for record in csv.reader(handle) if record)
            header = next(records, None)
            number = 0
            for number, record in enumerate(records, 1):
                if len(record) != len(header):
                    raise TableError(f"{path}: row {number}: {len(record)} fields, the header has {len(header)} (a "
                                     "ragged or truncated row)")
        if number and not _ends_its_line(path):
            raise TableError(f"{path}: row {number}: no newline at its end (a truncated row)")
    except UnicodeDecodeError as exc:
        raise TableError(f"{path}: not UTF-8 text ({exc.reason} at byte {exc.start})") from None
    except csv.Error as exc:  # a NUL byte, a field larger than csv's limit
        raise TableError(f"{path}: malformed table: {' '.join(str(exc).split())[:200]}") from None


def _ends_its_line(path: Path) -> bool:
    with open(path, "rb") as handle:
        handle.seek(0, 2)
        if handle.tell() == 0:
            return True
        handle.seek(-1, 2)
        return handle.read(1) in (b"\n", b"\r")


def with_precision(df: pd.DataFrame) -> pd.DataFrame:
    """The table with a `precision` column: a table of stereodyn 0.2.0 has none, and its runs were all float64."""
    if "precision" not in df:
        df = df.assign(precision=FLOAT64)
    return df.fillna({"precision": FLOAT64}).replace({"precision": {"": FLOAT64}}).astype({"precision": str})


# The `timing` column's value for a run timed once (its worker's time): a run whose time decides nothing
# (harness.analysis.decisive); else "best of N" (N 2 or 3), or empty for a run not timed (and in an older table). Here,
# beside `disturbed` and for the same reason, so that run.timing writes it without the results table's columns.
SINGLE = "single"


def disturbed(best, spread):
    """Whether a timing is disturbed: its spread is larger than its best time (element-wise for arrays; a NaN spread is
    not). Here, not in run.timing or run.results (both re-export it), so that the Pareto table (analysis) reads it
    without the timing machinery or the results table's columns."""
    return np.asarray(spread, dtype=float) > np.asarray(best, dtype=float)


# ------------------------------------------------ what a number of a results row may be (every reader's rule)
# The accuracy metrics the gate, baselines and compare read (every column with one of these suffixes), the timing,
# and the step of a row's key: finite or empty. Elsewhere a number may be inf (as the store writes it).
METRIC_SUFFIXES = ("_drift", "_err", "_err_end")
# Numbers that are sizes, counts or durations (every metric is a max of norms or absolute values): never negative, a
# step never 0 either. A negative one is a hand-edited or foreign table (wall_s -1 drew matplotlib warnings).
NON_NEGATIVE = ("t_end", "steps", "diverged_at", "wall_s", "us_per_step", "us_per_step_spread", "rhs_per_sim_s",
                "chart_changes")
POSITIVE = ("dt",)
COUNTS = ("steps", "chart_changes")  # whole numbers (steps = 2.5 passed every reader: issue 46's ninth attack)
# The largest number a reader accepts in a metric, timing or count column (read_results, a baseline's rows, a stored
# record on --resume): one bound, so that whatever a reader accepts every command can compute with (the ratios to the
# 1e-12 floor, the powers of ten of their logs in history, factor x baseline in check: 1e100 / 1e-12 = 1e112, far from
# a double's 1.8e308). What a run can report stays far below it: an attitude error is an angle (<= pi); an ok run's
# angular speed stays below 1e6 (1 + |omega0|) (the divergence rule, harness/trajectory.py) and a case's numbers within
# 1e6 (docs/limits.md), so its energy stays below ~1e31 J and a relative drift or error above 1e100 would need an
# initial scale below 1e-69 (the largest metric of the committed default report's 1337 ok rows: an energy drift of
# 8.1e4). A value above it is a hand-edited or foreign table.
MAX_VALUE = 1e100
# The columns that are angles (rad): a geodesic angle between two attitudes lies in [0, pi]
# (reference.rotations.attitude_angle; the sliding ladder's |theta - theta_equation| taken modulo 2 pi, the same angle
# on the circle), truth_err such an angle plus an allowance of 4e-15 (reference/truth.py). MAX_ANGLE admits pi as the
# table writes it, to 10 significant digits (3.141592654 > math.pi): the largest attitude_err of the committed default
# report is 3.14150, a run that lost its attitude altogether.
ANGLES = ("attitude_err", "attitude_err_end", "oracle_err", "truth_err")
MAX_ANGLE = math.pi * (1 + 1e-9)


def value_rule(column: str, value: float) -> str | None:
    """Why value cannot be in column (negative, a step of 0, an angle above pi, or above MAX_VALUE), or None. The one
    rule of every reader of results rows (read_results, a baseline's rows, a stored record on --resume)."""
    if column in POSITIVE and value <= 0:
        return "must be > 0"
    checked = column in NON_NEGATIVE or column.endswith(METRIC_SUFFIXES)
    if checked and value < 0:
        return "must be >= 0"
    if column in COUNTS and math.isfinite(value) and value != math.floor(value):
        return "must be a whole number (a count)"
    if column in ANGLES and value > MAX_ANGLE:
        return "must be <= pi (an angle in rad)"
    if (checked or column in POSITIVE) and value > MAX_VALUE:
        return f"must be <= {MAX_VALUE:g} (docs/limits.md)"
    return None
