"""Plain text shared by the analysis tables' notes, the terminal and the report: a number in a cell, a message with
its numbers elided, runs grouped by the reason they did not complete. No markup."""
from __future__ import annotations

import math
import re

import numpy as np
import pandas as pd


def number(value, spec: str = ".2e") -> str:
    """A table cell for a number: '-' for NaN, the text itself for a non-number."""
    try:
        value = float(value)
    except (TypeError, ValueError):
        return str(value)
    return "-" if math.isnan(value) else format(value, spec)


_NUMBER = re.compile(r"[-+]?(?:\d+\.?\d*|\.\d+)(?:[eE][-+]?\d+)?")


def reason(message) -> str:
    """A message with its numbers replaced by '…', so runs that stopped for the same reason share it."""
    text = message if isinstance(message, str) else ""
    return _NUMBER.sub("…", text).strip() or "(no message)"


def _subject(row) -> str:
    formulation = row.get("formulation", "")
    formulation = f" {formulation}" if isinstance(formulation, str) and formulation else ""
    dt = row.get("dt")
    dt = f" dt={dt:g}" if isinstance(dt, float) and np.isfinite(dt) else ""
    integrator = row.get("integrator", "")
    integrator = f" {integrator}" if isinstance(integrator, str) and integrator else ""
    return f"{row['case']} {row['engine']}{formulation}{integrator}{dt}"


def grouped_reasons(df: pd.DataFrame, statuses=("failed", "diverged", "skipped")) -> list[dict]:
    """Runs that did not complete, one entry per (status, reason): count, the runs, and the first run's own message
    (`example`, its numbers kept), most frequent first (failures before divergences before skips on a tie)."""
    rank = {s: i for i, s in enumerate(statuses)}
    rows = df[df["status"].isin(statuses)]
    groups: dict[tuple[str, str], list[str]] = {}
    examples: dict[tuple[str, str], str] = {}
    for _, row in rows.iterrows():
        message = row.get("message")
        key = (row["status"], reason(message))
        groups.setdefault(key, []).append(_subject(row))
        examples.setdefault(key, message.strip() if isinstance(message, str) and message.strip() else key[1])
    entries = [{"status": s, "reason": r, "count": len(runs), "runs": runs, "example": examples[(s, r)]}
               for (s, r), runs in groups.items()]
    return sorted(entries, key=lambda e: (rank[e["status"]], -e["count"], e["reason"]))
