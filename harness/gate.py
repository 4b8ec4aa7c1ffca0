"""The regression gate: a baseline of a results table, and the rows of a new table that got worse than it allows.

A row is identified by (case, engine, formulation, integrator, dt). It fails the gate when
- it is in the baseline and missing now;
- its status got worse (ok < diverged < failed, skipped: a run that no longer completes);
- one of its drifts or errors (every *_drift, *_err, *_err_end column), on a row that was ok and still is, exceeds
  factor * baseline + floor, or became NaN where the baseline had a number;
- with a time factor only: us_per_step exceeds time_factor * baseline (timings differ between machines and runs).

The tolerance model, per metric: factor * baseline + floor. The default factor 2 passes round-off, which moves the
drifts of these deterministic integrators by far less than 1 % on a machine of the same kind, and fails any real loss
of accuracy (a drift ten times worse). The floor absorbs the metrics that sit at round-off level (the truth's drifts,
Casimir drifts of 1e-16 .. 1e-15), whose relative change across machines can exceed any factor: 1e-12 is a thousand
times the round-off of a double yet well below every drift an integrator of the suite shows at its largest step.
"""
from __future__ import annotations

import json
import math
import tomllib
from dataclasses import dataclass, replace
from pathlib import Path

import pandas as pd

from stereodyn.harness.results import read_results, write_atomic

KEY = ("case", "engine", "formulation", "integrator", "dt")
STATUS_RANK = {"ok": 0, "diverged": 1, "failed": 2, "skipped": 2}
METRIC_SUFFIXES = ("_drift", "_err", "_err_end")
BASELINE_FORMAT = "stereodyn-baseline/1"


class GateError(ValueError):
    """A missing or malformed baseline, results table or tolerance file: bad input, exit 2."""


@dataclass(frozen=True)
class Tolerance:
    """A metric may grow to factor * baseline + floor."""

    factor: float = 2.0
    floor: float = 1e-12

    def allowed(self, baseline: float) -> float:
        return self.factor * baseline + self.floor


@dataclass(frozen=True)
class Tolerances:
    default: Tolerance = Tolerance()
    per_metric: tuple[tuple[str, Tolerance], ...] = ()
    time_factor: float | None = None

    def of(self, metric: str) -> Tolerance:
        return dict(self.per_metric).get(metric, self.default)


@dataclass(frozen=True)
class Finding:
    """One reason a row fails the gate."""

    key: tuple
    what: str
    baseline: str
    current: str
    allowed: str


def metric_columns(columns) -> list[str]:
    return [c for c in columns if c.endswith(METRIC_SUFFIXES)]


def _dt_key(value) -> str:
    try:
        value = float(value)
    except (TypeError, ValueError):
        return ""
    return "" if math.isnan(value) else f"{value:.10g}"


def _key(row: dict) -> tuple:
    return (str(row["case"]), str(row["engine"]), str(row.get("formulation") or ""), str(row["integrator"]),
            _dt_key(row.get("dt")))


def _number(value) -> float:
    try:
        return float(value)
    except (TypeError, ValueError):
        return math.nan


def _fmt(value: float) -> str:
    return "NaN" if math.isnan(value) else f"{value:.3e}"


# ------------------------------------------------------------------------------------------------------- files

def read_table(results_dir: Path) -> pd.DataFrame:
    path = Path(results_dir) / "results.csv"
    if not path.is_file():
        raise GateError(f"{path}: file not found")
    return read_results(path)


def write_baseline(df: pd.DataFrame, path: Path, environment: dict | None = None) -> int:
    """Write the baseline of a results table (JSON, one row per line); return the number of rows."""
    columns = [*KEY, "status", *metric_columns(df.columns), "us_per_step"]
    rows = []
    for _, row in df.iterrows():
        entry = {}
        for column in columns:
            value = row.get(column)
            if isinstance(value, float) and math.isnan(value):
                value = None
            entry[column] = value.item() if hasattr(value, "item") else value
        rows.append(entry)
    head = {"format": BASELINE_FORMAT, "environment": environment or {}}
    text = json.dumps(head, indent=1)[:-2] + ',\n "rows": [\n'
    text += ",\n".join("  " + json.dumps(row, separators=(",", ":")) for row in rows) + "\n ]\n}\n"
    Path(path).parent.mkdir(parents=True, exist_ok=True)
    write_atomic(Path(path), text)
    return len(rows)


def read_baseline(path: Path) -> list[dict]:
    try:
        data = json.loads(Path(path).read_text(encoding="utf-8"))
    except FileNotFoundError:
        raise GateError(f"{path}: file not found") from None
    except (OSError, ValueError) as exc:
        raise GateError(f"{path}: not a baseline file ({exc})") from None
    if not isinstance(data, dict) or data.get("format") != BASELINE_FORMAT or not isinstance(data.get("rows"), list):
        raise GateError(f"{path}: not a baseline file (format must be {BASELINE_FORMAT!r} with a list of rows)")
    return data["rows"]


def read_tolerances(path: Path, base: Tolerances = Tolerances()) -> Tolerances:
    """A TOML tolerance file: [default] factor/floor, [metric.NAME] factor/floor, [time] factor."""
    try:
        data = tomllib.loads(Path(path).read_text(encoding="utf-8"))
    except FileNotFoundError:
        raise GateError(f"{path}: file not found") from None
    except (OSError, UnicodeDecodeError, tomllib.TOMLDecodeError) as exc:
        raise GateError(f"{path}: -: invalid TOML ({' '.join(str(exc).split())})") from None

    def tolerance(table, key: str, start: Tolerance) -> Tolerance:
        if not isinstance(table, dict) or set(table) - {"factor", "floor"}:
            raise GateError(f"{path}: {key}: must be a table with only factor and floor")
        values = {}
        for name, value in table.items():
            if isinstance(value, bool) or not isinstance(value, (int, float)) or not math.isfinite(value) \
                    or value < (1.0 if name == "factor" else 0.0):
                raise GateError(f"{path}: {key}.{name}: must be a number {'>= 1' if name == 'factor' else '>= 0'}")
            values[name] = float(value)
        return replace(start, **values)

    unknown = set(data) - {"default", "metric", "time"}
    if unknown:
        raise GateError(f"{path}: {sorted(unknown)[0]}: unknown key (allowed: default, metric, time)")
    default = tolerance(data.get("default", {}), "default", base.default)
    metrics = data.get("metric", {})
    if not isinstance(metrics, dict):
        raise GateError(f"{path}: metric: must be a table of tables")
    per_metric = dict(base.per_metric)
    for name, table in metrics.items():
        if not name.endswith(METRIC_SUFFIXES):
            raise GateError(f"{path}: metric.{name}: not a drift or error column (*_drift, *_err, *_err_end)")
        per_metric[name] = tolerance(table, f"metric.{name}", default)
    time_factor = base.time_factor
    if "time" in data:
        time = data["time"]
        if not isinstance(time, dict) or set(time) != {"factor"} or not isinstance(time["factor"], (int, float)) \
                or isinstance(time["factor"], bool) or not time["factor"] >= 1.0:
            raise GateError(f"{path}: time: must be a table with only factor (a number >= 1)")
        time_factor = float(time["factor"])
    return Tolerances(default, tuple(per_metric.items()), time_factor)


# ------------------------------------------------------------------------------------------------------ the gate

def compare(current: pd.DataFrame, baseline: list[dict], tolerances: Tolerances = Tolerances()) -> list[Finding]:
    """Every way the current table is worse than the baseline, in the baseline's row order."""
    now = {_key(row): row for row in current.to_dict("records")}
    findings = []
    for old in baseline:
        key = _key(old)
        new = now.get(key)
        if new is None:
            findings.append(Finding(key, "missing row", str(old.get("status")), "-", "present"))
            continue
        old_status, new_status = str(old.get("status")), str(new.get("status"))
        old_rank, new_rank = STATUS_RANK.get(old_status, 3), STATUS_RANK.get(new_status, 3)
        if new_rank > old_rank:
            findings.append(Finding(key, "status", old_status, new_status, old_status))
            continue
        if old_status != "ok" or new_status != "ok":
            continue  # the metrics of runs that did not complete are not comparable
        for metric in metric_columns(old):
            before, after = _number(old.get(metric)), _number(new.get(metric))
            if math.isnan(before):
                continue
            limit = tolerances.of(metric).allowed(before)
            if math.isnan(after) or after > limit:
                findings.append(Finding(key, metric, _fmt(before), _fmt(after), f"<= {_fmt(limit)}"))
        if tolerances.time_factor is not None:
            before, after = _number(old.get("us_per_step")), _number(new.get("us_per_step"))
            if not math.isnan(before) and not math.isnan(after) and after > tolerances.time_factor * before:
                findings.append(Finding(key, "us_per_step", f"{before:.3g}", f"{after:.3g}",
                                        f"<= {tolerances.time_factor * before:.3g}"))
    return findings


def new_rows(current: pd.DataFrame, baseline: list[dict]) -> int:
    """Rows of the current table that the baseline does not have (reported, never a failure)."""
    known = {_key(row) for row in baseline}
    return sum(_key(row) not in known for row in current.to_dict("records"))


def findings_table(findings: list[Finding]) -> str:
    """A fixed-width table of the findings, for the terminal and CI logs."""
    header = [*KEY, "what", "baseline", "current", "allowed"]
    cells = [header] + [[*f.key, f.what, f.baseline, f.current, f.allowed] for f in findings]
    widths = [max(len(row[i]) for row in cells) for i in range(len(header))]
    return "\n".join("  ".join(cell.ljust(w) for cell, w in zip(row, widths)).rstrip() for row in cells)
