"""The results table (DESIGN §4): its columns, and atomic writes so an interrupted run loses nothing written."""
from __future__ import annotations

import os
import tempfile
from pathlib import Path

import pandas as pd

from ..scenes.metrics import DRIFT_COLUMNS, ERROR_COLUMNS

COLUMNS = ("case", "engine", "formulation", "integrator", "dt", "t_end", "steps", "status", "message", "diverged_at",
           "wall_s", "us_per_step", "us_per_step_spread", "rhs_per_sim_s", *DRIFT_COLUMNS, *ERROR_COLUMNS, "oracle_err",
           "truth_err", "truth_omega_err", "chart_changes", "torque_mode", "precession_axis_drift")

# Row order in the table and the report: the truth first, then engines as listed, integrators as each engine lists
# them, formulations as the engine lists them, dt descending.
SORT_KEYS = ("case", "_engine_rank", "_integrator_rank", "_formulation_rank", "_dt_rank")


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
    except BaseException:
        Path(tmp).unlink(missing_ok=True)
        raise


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


def read_results(path: Path) -> pd.DataFrame:
    text = ("integrator", "formulation", "message")  # empty means "none" here, not a missing number
    df = read_csv_table(path, REQUIRED_COLUMNS, keep_default_na=True, dtype=dict.fromkeys(text, str))
    for column in ("formulation", "message"):  # optional text columns a results.csv of an older version may lack
        if column not in df:
            df[column] = ""
    return df.fillna(dict.fromkeys(text, ""))
