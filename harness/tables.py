"""Reading a table stereodyn wrote (results.csv and the tables derived from it: pareto.csv, advice.csv,
convergence.csv, ...) with every way the file can be malformed one TableError naming it, never a table silently short
of rows: results.csv's validation of its cells is harness/run/results.py's read_results."""
from __future__ import annotations

import csv
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


def read_optional(path: Path, text_columns: tuple[str, ...] = ("formulation",)) -> pd.DataFrame | None:
    """A derived table (convergence.csv, ladder.csv, ...), or None where the run wrote none; text columns read as text
    with "" for empty cells; TableError for one that is malformed, never a table silently short of rows."""
    if not Path(path).exists():
        return None
    df = read_csv_table(path, dtype={c: str for c in text_columns}, keep_default_na=True)
    return df.fillna({c: "" for c in text_columns if c in df})


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
