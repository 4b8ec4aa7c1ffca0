"""The regression gate: a baseline of a results table, and the rows of a new table that got worse than it allows.

A row is identified by (case, engine, formulation, integrator, precision, dt). It fails the gate when
- it is in the baseline and missing now;
- its status got worse (ok < diverged < failed, skipped: a run that no longer completes);
- one of its drifts or errors (every *_drift, *_err, *_err_end column), on a row that was ok and still is, exceeds
  factor * baseline + floor, or became NaN where the baseline had a number;
- with a time factor only: us_per_step exceeds time_factor * baseline (timings differ between machines and runs), on
  a row timed with repeats now (results.csv `timing` not "single": a run whose time decides nothing keeps one timed
  run, harness.analysis.decisive; each engine's fastest runs of a case are always timed with repeats).
A convergence row (convergence.csv: case, engine, formulation, integrator, precision) fails when its order fell more than
ORDER_DROP below the baseline's, or became NaN where the baseline had a number.

The tolerance model, per metric: factor * baseline + floor. The default factor 2 passes round-off, which moves the
drifts of these deterministic integrators by far less than 1 % on a machine of the same kind, and fails any real loss
of accuracy (a drift ten times worse). The floor absorbs the metrics that sit at round-off level (the truth's drifts,
Casimir drifts of 1e-16 .. 1e-15), whose relative change across machines can exceed any factor: 1e-12 is a thousand
times the round-off of a double yet well below every drift an integrator of the suite shows at its largest step.

Two modes (MODES), recorded in the baseline by `stereodyn baseline --mode` and applied by `check`:
- same-machine (the default): the check runs where the baseline was made, with the same library versions. Reruns are
  then bit-identical, so factor 1.05 over the floor fails a 1.49x error increase that factor 2 let through.
- cross-machine: another CPU or other library versions. Factor 2, for round-off that a different CPU (FMA, libm,
  vector width) amplifies along a trajectory: docs/DESIGN.md §4, Baselines, gives the spread measured across CPUs.
A baseline without a mode (stereodyn 0.2 and before) was checked with factor 2: cross-machine.
"""
from __future__ import annotations

import json
import math
from dataclasses import dataclass, replace
from pathlib import Path

import pandas as pd

from ...reference.plugins import markup_problem
from ..environment import OWN_SOURCE, differences
from ..integrators.base import MAX_ORDER
from ..precision import FLOAT64
from ..readers import MAX_BASELINE_BYTES, ReadError, read_json, read_toml
from ..tables import read_optional
from ..run.results import (KEY, METRIC_SUFFIXES, NAMED, SINGLE, STATUSES, TableError, describe_key, dt_key, duplicate,
                           metric_names, read_results, value_rule, with_precision, write_atomic)

# KEY: (case, engine, formulation, integrator, precision, dt); precision: a baseline or table of stereodyn 0.2.0 has
# none, and its runs were float64.
STATUS_RANK = {"ok": 0, "diverged": 1, "failed": 2, "skipped": 2}
BASELINE_FORMAT = "stereodyn-baseline/1"  # "orders" (the fitted convergence orders) is optional: older files lack it
CONVERGENCE_FILE = "convergence.csv"  # written by harness.analysis.workprecision
ORDER_KEY = ("case", "engine", "formulation", "integrator", "precision")
# The keys write_baseline writes, at the top and in an order entry: any other is refused (a typed "order" for
# "orders" would be a baseline without orders, a "fited" an order never checked).
BASELINE_KEYS = ("format", "mode", "environment", "rows", "orders")
ORDER_ENTRY_KEYS = (*ORDER_KEY, "fitted", "declared")
# A fitted order may fall this much below the baseline's. The fits are deterministic: on one machine kind round-off
# moves them by < 0.01; a method that lost an order (MuJoCo 3.17's ball-joint RK4: 2.00 against 4.07) moves >= 1.
ORDER_DROP = 0.5
SAME_MACHINE, CROSS_MACHINE = "same-machine", "cross-machine"
DEFAULT_MODE = SAME_MACHINE
LEGACY_MODE = CROSS_MACHINE  # a baseline that records no mode was made for factor 2, 0.2.0's only default


class GateError(ValueError):
    """A missing or malformed baseline, results table or tolerance file: bad input, exit 2."""


@dataclass(frozen=True)
class Tolerance:
    """A metric may grow to factor * baseline + floor."""

    factor: float = 2.0
    floor: float = 1e-12

    def allowed(self, baseline: float) -> float:
        return self.factor * baseline + self.floor


# The default tolerance of each mode: factor (dimensionless) * baseline + floor (the metric's unit: rad, or relative).
MODES = {SAME_MACHINE: Tolerance(1.05, 1e-12), CROSS_MACHINE: Tolerance(2.0, 1e-12)}


@dataclass(frozen=True)
class Tolerances:
    default: Tolerance = Tolerance()
    per_metric: tuple[tuple[str, Tolerance], ...] = ()
    time_factor: float | None = None

    def of(self, metric: str) -> Tolerance:
        return dict(self.per_metric).get(metric, self.default)


@dataclass(frozen=True)
class Finding:
    """One reason a row fails the gate. ratio: current / baseline of a metric (nan otherwise); message: the run's
    message, for a status change."""

    key: tuple
    what: str
    baseline: str
    current: str
    allowed: str
    ratio: float = math.nan
    message: str = ""


@dataclass(frozen=True)
class Baseline:
    """A baseline file: its rows, the environment it was made in, the fitted orders (may be empty) and the mode it was
    written for (None: a file of stereodyn 0.2 or before, which records none)."""

    rows: list
    environment: dict
    orders: list
    mode: str | None = None

    @property
    def applied_mode(self) -> str:
        return self.mode or LEGACY_MODE


def metric_columns(columns) -> list[str]:
    return [c for c in columns if c.endswith(METRIC_SUFFIXES)]


_dt_key = dt_key


def _key(row: dict) -> tuple:
    return (str(row["case"]), str(row["engine"]), str(row.get("formulation") or ""), str(row["integrator"]),
            str(row.get("precision") or FLOAT64), _dt_key(row.get("dt")))


def _order_key(row: dict) -> tuple:
    return (str(row["case"]), str(row["engine"]), str(row.get("formulation") or ""), str(row["integrator"]),
            str(row.get("precision") or FLOAT64))


def _number(value) -> float:
    try:
        return float(value)
    except (TypeError, ValueError):
        return math.nan


def _fmt(value: float) -> str:
    return "NaN" if math.isnan(value) else f"{value:.3e}"


# ------------------------------------------------------------------------------------------------------- files

def read_table(results_dir: Path, required: tuple = (*KEY, "status")) -> pd.DataFrame:
    """DIR/results.csv; GateError (one line naming the file) when it is absent, empty, undecodable, has no rows or
    lacks one of the required columns."""
    path = Path(results_dir) / "results.csv"
    if not path.exists():  # a FIFO or a device exists: read_results refuses it, naming what it is
        raise GateError(f"{path}: file not found")
    try:
        df = read_results(path)
    except pd.errors.EmptyDataError:
        raise GateError(f"{path}: empty file (not a results table)") from None
    except UnicodeDecodeError as exc:
        raise GateError(f"{path}: not UTF-8 text ({exc.reason} at byte {exc.start})") from None
    except TableError as exc:  # read_results names the file and the problem already
        raise GateError(str(exc)) from None
    except (OSError, ValueError, pd.errors.ParserError) as exc:
        raise GateError(f"{path}: not a results table ({' '.join(str(exc).split())})") from None
    missing = [column for column in required if column not in df.columns]
    if missing:
        raise GateError(f"{path}: missing columns {', '.join(missing)} (not a stereodyn results table)")
    if df.empty:
        raise GateError(f"{path}: no rows (a header only)")
    return df


def read_orders(results_dir: Path) -> pd.DataFrame | None:
    """DIR/convergence.csv (the fitted orders), or None when the run wrote none."""
    path = Path(results_dir) / CONVERGENCE_FILE
    if not path.exists():
        return None
    try:  # a file cut mid-row, a FIFO, garbage, a family twice, an order out of bounds (tables.read_optional: the
        # report's reading too; issue 46: 1e308 was written into a baseline that check then refused)
        df = read_optional(path, ("formulation", "integrator"))
    except TableError as exc:
        raise GateError(str(exc)) from None
    missing = [column for column in (*ORDER_KEY, "order") if column not in df.columns and column != "precision"]
    if missing:
        raise GateError(f"{path}: missing columns {', '.join(missing)} (not a stereodyn convergence table)")
    df = with_precision(df).fillna({"formulation": ""})
    keys = [_order_key(row) for row in df.to_dict("records")]
    twice = duplicate(keys)
    if twice:  # the last one won in silence (issue 46's eleventh attack, F5), where results.csv refuses it
        raise GateError(f"{path}: row {twice[1] + 1}: duplicate key {describe_key(keys[twice[1]])} (also row "
                        f"{twice[0] + 1}): one fitted order per run family")
    return df


def _order_rows(convergence: pd.DataFrame | None) -> list[dict]:
    if convergence is None:
        return []
    rows = []
    for row in convergence.to_dict("records"):
        entry = dict(zip(ORDER_KEY, _order_key(row)))
        for column, name in (("order", "fitted"), ("declared_order", "declared")):
            value = _number(row.get(column))
            entry[name] = None if math.isnan(value) else value
        rows.append(entry)
    return rows


def write_baseline(df: pd.DataFrame, path: Path, environment: dict | None = None,
                   convergence: pd.DataFrame | None = None, mode: str = DEFAULT_MODE) -> int:
    """Write the baseline of a results table and its fitted orders (JSON, one row per line) for a gate mode (MODES);
    return the number of rows."""
    if mode not in MODES:
        raise GateError(f"mode: {mode!r} is not a gate mode ({', '.join(MODES)})")
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
    head = {"format": BASELINE_FORMAT, "mode": mode, "environment": environment or {}}
    text = json.dumps(head, indent=1)[:-2] + ',\n "rows": [\n'
    text += ",\n".join("  " + json.dumps(row, separators=(",", ":")) for row in rows) + "\n ]"
    orders = _order_rows(convergence)
    for number, row in enumerate(orders, 1):  # what check would refuse is never written (a fit of -50: convergence.csv
        for key in ("fitted", "declared"):  # reads it, and a check flags it as a drop; no baseline can hold it)
            rule = None if row[key] is None else order_rule(key, row[key])
            if rule:
                raise GateError(f"{CONVERGENCE_FILE}: row {number}: order {row[key]!r} ({key}) {rule} to be a "
                                "baseline's order")
    if orders:
        text += ',\n "orders": [\n'
        text += ",\n".join("  " + json.dumps(row, separators=(",", ":")) for row in orders) + "\n ]"
    text += "\n}\n"
    try:
        Path(path).parent.mkdir(parents=True, exist_ok=True)
        write_atomic(Path(path), text)
    except OSError as exc:
        raise GateError(f"{path}: cannot write ({exc.strerror or exc})") from None
    return len(rows)


def _is_number(value) -> bool:
    return value is None or (isinstance(value, (int, float)) and not isinstance(value, bool))


def _finite(value) -> bool:
    try:
        return math.isfinite(value)
    except OverflowError:  # an integer of hundreds of digits: no double holds it
        return False


def _validate_rows(path: Path, name: str, rows, required: tuple, text: tuple, numbers) -> None:
    """Every entry of the list `name` is an object with the required keys; text keys hold strings (or null where
    allowed below), number keys (numbers(key)) hold numbers or null."""
    for index, row in enumerate(rows):
        where = f"{path}: {name}[{index}]"
        if not isinstance(row, dict):
            raise GateError(f"{where}: must be an object, got {json.dumps(row)[:40]}")
        for key in required:
            if key not in row:
                raise GateError(f"{where}: missing key {key!r}")
        for key in text:
            if key in row and not isinstance(row[key], str) and not (row[key] is None and key == "formulation"):
                raise GateError(f"{where}.{key}: must be a string, got {json.dumps(row[key])[:40]}")
            # names as results.csv holds them (results.read_results): "mu|joco" was read by check, compare and
            # history where a results.csv row of that name is refused (issue 46's thirteenth attack)
            why = _name_problem(row[key]) if key in NAMES and isinstance(row.get(key), str) else None
            if why:
                raise GateError(f"{where}.{key}: {json.dumps(row[key])[:40]}: {why}")
        for key, value in row.items():
            if numbers(key) and not _is_number(value):
                raise GateError(f"{where}.{key}: must be a number or null, got {json.dumps(value)[:40]}")
            if numbers(key) and value is not None and not _finite(value):
                raise GateError(f"{where}.{key}: must be finite, got {str(value)[:40]}")


NAMES = ("case", "engine", "formulation", "integrator")  # a row's names: shown as themselves in every output


def _name_problem(name: str) -> str | None:
    if not name.isprintable():
        return "must be one line of printable characters"
    return markup_problem(name)


def order_rule(key: str, value: float) -> str | None:
    """Why value cannot be a baseline's fitted or declared order, or None: a fitted order in [0, MAX_ORDER] (one
    below 0 would be a method whose error grows as its step shrinks), a declared one in (0, MAX_ORDER] (as an
    integrator declares it, integrators.base.metadata_problem)."""
    if value < 0 or (key == "declared" and value == 0):
        return "must be >= 0" if key == "fitted" else "must be > 0"
    if value > MAX_ORDER:
        return f"must be <= {MAX_ORDER}"
    return None


def _known_keys(where: str, entry: dict, allowed: tuple) -> None:
    """GateError naming the first key of entry that is not in allowed (where: the file and the entry, up to the key)."""
    for key in entry:
        if key not in allowed:
            raise GateError(f"{where}{str(key)[:80]}: unknown key (allowed: {', '.join(allowed)})")


def _check_rows(path: Path, rows: list[dict]) -> None:
    """What read_results asks of a results table, asked of a baseline's rows: a case and an engine named, a status of
    STATUSES exactly, no metric (nor timing) negative and a dt > 0, only the keys write_baseline writes (a metric the
    table has), one row per KEY."""
    metrics = metric_names()
    allowed = (*KEY, "status", "us_per_step")
    for index, row in enumerate(rows):
        where = f"{path}: rows[{index}]"
        for key, value in row.items():
            if key.endswith(METRIC_SUFFIXES) and key not in metrics:
                raise GateError(f"{where}.{key}: not a metric of the results table (valid: {', '.join(metrics)})")
            if not key.endswith(METRIC_SUFFIXES) and key not in allowed:
                raise GateError(f"{where}.{key}: unknown key (allowed: {', '.join(allowed)} and the metrics)")
            rule = None if value is None or isinstance(value, str) else value_rule(key, value)
            if rule:
                raise GateError(f"{where}.{key}: {rule}, got {value}")
        for key in NAMED:
            if not row[key].strip():
                raise GateError(f"{where}.{key}: empty")
        if row["status"] not in STATUSES:
            raise GateError(f"{where}.status: {row['status'][:40]!r} is not a status ({', '.join(STATUSES)})")
    twice = duplicate([_key(row) for row in rows])
    if twice:
        raise GateError(f"{path}: rows[{twice[1]}]: duplicate key {describe_key(_key(rows[twice[1]]))} (also "
                        f"rows[{twice[0]}]): one row per key")


def read_baseline_file(path: Path) -> Baseline:
    """A baseline file, validated as strictly as read_results reads a results table: GateError (one line naming the
    file, the entry and the rule) on anything else."""
    try:
        data = read_json(path, MAX_BASELINE_BYTES)
    except FileNotFoundError:
        raise GateError(f"{path}: file not found") from None
    except OSError as exc:
        raise GateError(f"{path}: cannot read ({exc.strerror or exc})") from None
    except ReadError as exc:  # too large, not UTF-8, not JSON, nested too deep, an integer of too many digits
        raise GateError(f"{path}: not a baseline file ({exc})") from None
    if not isinstance(data, dict) or data.get("format") != BASELINE_FORMAT or not isinstance(data.get("rows"), list):
        raise GateError(f"{path}: not a baseline file (format must be {BASELINE_FORMAT!r} with a list of rows)")
    _known_keys(f"{path}: ", data, BASELINE_KEYS)
    rows, orders, environment = data["rows"], data.get("orders", []), data.get("environment", {})
    if not rows:
        raise GateError(f"{path}: rows: empty (a baseline must hold at least one row)")
    _validate_rows(path, "rows", rows, ("case", "engine", "integrator", "status"),
                   ("case", "engine", "formulation", "integrator", "precision", "status"),
                   lambda key: key.endswith(METRIC_SUFFIXES) or key in ("dt", "us_per_step"))
    _check_rows(path, rows)
    if not isinstance(orders, list):
        raise GateError(f"{path}: orders: must be a list")
    _validate_rows(path, "orders", orders, (*ORDER_KEY[:4], "fitted"), ORDER_KEY,
                   lambda key: key in ("fitted", "declared"))
    for index, row in enumerate(orders):
        _known_keys(f"{path}: orders[{index}].", row, ORDER_ENTRY_KEYS)
        for key in ("fitted", "declared"):
            rule = None if row.get(key) is None else order_rule(key, row[key])
            if rule:
                raise GateError(f"{path}: orders[{index}].{key}: {rule} (a convergence order), got {row[key]}")
    twice = duplicate([_order_key(row) for row in orders])
    if twice:
        raise GateError(f"{path}: orders[{twice[1]}]: duplicate key {describe_key(_order_key(orders[twice[1]]))} "
                        f"(also orders[{twice[0]}]): one fitted order per run family")
    if not isinstance(environment, dict):
        raise GateError(f"{path}: environment: must be an object")
    for name, value in environment.items():  # what runs.json records: versions and names, all text
        if not isinstance(value, str):
            raise GateError(f"{path}: environment.{name[:80]}: must be a string, got {json.dumps(value)[:40]}")
    mode = data.get("mode")
    if mode is not None and mode not in MODES:
        raise GateError(f"{path}: mode: must be one of {', '.join(MODES)}, got {json.dumps(mode)[:40]}")
    return Baseline(rows, environment, orders, mode)


def read_baseline(path: Path) -> list[dict]:
    """The rows of a baseline file (validated as read_baseline_file does)."""
    return read_baseline_file(path).rows


def read_tolerances(path: Path, base: Tolerances = Tolerances()) -> Tolerances:
    """A TOML tolerance file: [default] factor/floor, [metric.NAME] factor/floor, [time] factor."""
    try:
        data = read_toml(path)
    except FileNotFoundError:
        raise GateError(f"{path}: file not found") from None
    except OSError as exc:
        raise GateError(f"{path}: -: cannot read ({exc.strerror or exc})") from None
    except ReadError as exc:  # too large, not UTF-8 TOML, nested too deep, an integer of 5000 digits
        raise GateError(f"{path}: -: {exc}") from None

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
        if name not in metric_names():  # a table for no metric would be applied to nothing
            raise GateError(f"{path}: metric.{name}: not a metric of the results table (valid: "
                            f"{', '.join(metric_names())})")
        per_metric[name] = tolerance(table, f"metric.{name}", default)
    time_factor = base.time_factor
    if "time" in data:
        time = data["time"]
        if not isinstance(time, dict) or set(time) != {"factor"} or not isinstance(time["factor"], (int, float)) \
                or isinstance(time["factor"], bool) or not math.isfinite(time["factor"]) or not time["factor"] >= 1.0:
            raise GateError(f"{path}: time: must be a table with only factor (a finite number >= 1)")
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
            findings.append(Finding(key, "missing", str(old.get("status")), "-", "present"))
            continue
        old_status, new_status = str(old.get("status")), str(new.get("status"))
        old_rank, new_rank = STATUS_RANK.get(old_status, 3), STATUS_RANK.get(new_status, 3)
        if new_rank > old_rank:
            message = new.get("message")
            message = "" if not isinstance(message, str) else " ".join(message.split())
            findings.append(Finding(key, "status", old_status, new_status, old_status, message=message))
            continue
        if old_status != "ok" or new_status != "ok":
            continue  # the metrics of runs that did not complete are not comparable
        for metric in metric_columns(old):
            before, after = _number(old.get(metric)), _number(new.get(metric))
            if math.isnan(before):
                continue
            limit = tolerances.of(metric).allowed(before)
            if math.isnan(after) or after > limit:
                ratio = after / before if before > 0 else math.inf if after > 0 else math.nan
                findings.append(Finding(key, metric, _fmt(before), _fmt(after), f"<= {_fmt(limit)}", ratio))
        if tolerances.time_factor is not None and new.get("timing") != SINGLE:
            before, after = _number(old.get("us_per_step")), _number(new.get("us_per_step"))
            if not math.isnan(before) and not math.isnan(after) and after > tolerances.time_factor * before:
                findings.append(Finding(key, "us_per_step", f"{before:.3g}", f"{after:.3g}",
                                        f"<= {tolerances.time_factor * before:.3g}",
                                        after / before if before > 0 else math.inf))
    return findings


def compare_orders(current: pd.DataFrame | None, orders: list[dict]) -> list[Finding]:
    """Fitted orders that fell more than ORDER_DROP below the baseline's (or became NaN), or whose convergence row
    is gone. Keys are (case, engine, formulation, integrator, precision, "order")."""
    if not orders:
        return []
    now = {_order_key(row): row for row in _order_rows(current)}
    findings = []
    for old in orders:
        key = _order_key(old)
        before = _number(old.get("fitted"))
        if math.isnan(before):
            continue
        declared = _number(old.get("declared"))
        declared_text = "-" if math.isnan(declared) else f"{declared:g}"
        new = now.get(key)
        if new is None:
            findings.append(Finding((*key, "order"), "missing order", f"{before:.2f}", "-", "present",
                                    message=f"declared {declared_text}"))
            continue
        after = _number(new.get("fitted"))
        if math.isnan(after) or after < before - ORDER_DROP:
            findings.append(Finding((*key, "order"), "order", f"{before:.2f}", "NaN" if math.isnan(after)
                                    else f"{after:.2f}", f">= {before - ORDER_DROP:.2f}",
                                    message=f"declared {declared_text}"))
    return findings


def code_environment(manifest: dict | None) -> dict:
    """runs.json's "code" as environment entries: 'plug-in engine NAME' and 'plug-in integrator NAME' ->
    'DIST VERSION, source HASH' for every class a plug-in provides (a plug-in's changed source shows even when its
    version did not change), and 'stereodyn source' (its fingerprint: it changes with every commit; the gate
    lists it, as the code under test, never as another machine: mode_line). Entries of an unexpected shape are left
    out (runs.json's code is informative)."""
    code = (manifest or {}).get("code")
    if not isinstance(code, dict):
        return {}
    entries = {}
    if isinstance(code.get(OWN_SOURCE), str):
        entries[OWN_SOURCE] = code[OWN_SOURCE]
    for kind, table in (("engine", code.get("engines")), ("integrator", code.get("integrators"))):
        for name, origins in (table.items() if isinstance(table, dict) else ()):
            for origin in (origins if isinstance(origins, list) else [origins]):
                if isinstance(origin, dict) and origin.get("distribution") not in (None, "stereodyn"):
                    entries[f"plug-in {kind} {name}"] = (f"{origin.get('distribution')} {origin.get('version', '')}, "
                                                         f"source {origin.get('source', '?')}")
    return entries


def recorded_environment(manifest: dict | None) -> dict:
    """The environment a baseline keeps and check, compare and history compare: runs.json's environment and the code
    (stereodyn's source, its plug-ins'), one rule for all of them (a baseline without stereodyn's source said "same
    environment" where the folder it came from said "1 key differs": issue 46's eleventh attack, F2)."""
    environment = (manifest or {}).get("environment")
    return {**(environment if isinstance(environment, dict) else {}), **code_environment(manifest)}


def environment_changes(baseline: dict, current: dict | None, why: str | None = None) -> list[str]:
    """'name old -> new' for every environment entry (library versions, CPU, platform, plug-ins' code) that differs
    between the baseline and the run, by environment.differences: the measurement context (the date, the commit, the
    load at timing) is no change. why: why the run's runs.json could not be read, where it is there
    (store.manifest_problem; a garbled one was said to be missing)."""
    if not current:
        return [f"run environment unknown ({why or 'no runs.json beside results.csv'})"] if baseline else []
    return [f"{name} {baseline.get(name, '-')} -> {current.get(name, '-')}" for name in differences(baseline, current)]


def new_rows(current: pd.DataFrame, baseline: list[dict]) -> int:
    """Rows of the current table that the baseline does not have (reported, never a failure)."""
    known = {_key(row) for row in baseline}
    return sum(_key(row) not in known for row in current.to_dict("records"))


@dataclass(frozen=True)
class Verdict:
    """What `check` found against a baseline of `rows` rows and `orders` fitted orders: the findings of the rows
    (compare) and of the orders (compare_orders), and the count of rows the baseline lacks (never a failure)."""

    rows: int
    orders: int
    findings: tuple[Finding, ...]
    order_findings: tuple[Finding, ...]
    new: int = 0

    @property
    def worse(self) -> int:  # rows, not findings: a row with three metrics over its bound is one row
        return len({f.key for f in self.findings if f.what != "missing"})

    @property
    def missing(self) -> int:
        return sum(f.what == "missing" for f in self.findings)

    @property
    def fell(self) -> int:
        return sum(f.what == "order" for f in self.order_findings)

    @property
    def orders_missing(self) -> int:
        return sum(f.what == "missing order" for f in self.order_findings)

    @property
    def passed(self) -> bool:
        return not self.findings and not self.order_findings

    def headline(self, baseline: str) -> str:
        """check's last line: 'check passed: ...' or 'check failed: ...', each count named for what it counts."""
        note = f"; {self.new} rows not in the baseline (not checked)" if self.new else ""
        if self.passed:
            orders = f", {self.orders} fitted orders" if self.orders else ""
            return f"check passed: {self.rows} baseline rows{orders}, none worse{note}"
        parts = []
        if self.worse:
            parts.append(f"{self.worse} of {self.rows} baseline rows got worse than {baseline} allows")
        if self.missing:
            parts.append(f"{self.missing} of {self.rows} baseline rows missing")
        if self.fell:
            parts.append(f"{self.fell} of {self.orders} fitted orders fell")
        if self.orders_missing:  # the run wrote no order for the family: not a lower order, an absent one
            parts.append(f"{self.orders_missing} of {self.orders} fitted orders missing")
        return f"check failed: {'; '.join(parts)}{note}"


def mode_line(mode: str, source: str, tolerances: Tolerances, changes: list[str]) -> str:
    """Which gate mode check applied, from where, and the tolerance it gives (after --factor, --floor, a file)."""
    tolerance = tolerances.default
    line = (f"gate: {mode} mode ({source}): a drift or error may grow to {tolerance.factor:g} x baseline + "
            f"{tolerance.floor:g}")
    if tolerances.per_metric:
        line += f", other bounds for {', '.join(name for name, _ in tolerances.per_metric)}"
    if tolerances.time_factor is not None:
        line += f"; us_per_step to {tolerances.time_factor:g} x baseline"
    if mode == SAME_MACHINE and any(not c.startswith(("run environment unknown", "platform ", "plug-in ", OWN_SOURCE))
                                    for c in changes):  # the code under test changes by design: no other machine
        line += f" (the environment differs: on another machine or versions, --mode {CROSS_MACHINE})"
    return line


def _ratio(value: float) -> str:
    return "-" if math.isnan(value) else "inf" if math.isinf(value) else f"{value:.3g}x"


def summary(findings: list[Finding]) -> list[str]:
    """One line per group of findings (engine, integrator, kind): '8 rows: mujoco rk4, attitude_err up to 1.4e6x'."""
    groups: dict[tuple, list[Finding]] = {}
    for f in findings:
        kind = f.what if f.what in ("missing", "status", "order", "missing order", "us_per_step") else "metric"
        precision = "" if f.key[4] == FLOAT64 else f" {f.key[4]}"
        groups.setdefault((f.key[1], f.key[3] + precision, kind), []).append(f)
    lines = []
    for (engine, integrator, kind), group in groups.items():
        rows = len({f.key for f in group})
        head = f"{rows} row{'s' if rows != 1 else ''}: {engine} {integrator}".rstrip()
        if kind == "metric":
            parts = []
            for metric in dict.fromkeys(f.what for f in group):
                mine = [f for f in group if f.what == metric]
                if any(f.current == "NaN" for f in mine):
                    parts.append(f"{metric} NaN")
                else:
                    parts.append(f"{metric} up to {_ratio(max(f.ratio for f in mine))}")
            lines.append(f"{head}, {', '.join(parts)}")
        elif kind == "status":
            changes = sorted({f"{f.baseline} -> {f.current}" for f in group})
            lines.append(f"{head}, status {', '.join(changes)}")
        elif kind in ("order", "missing order"):
            # an order belongs to a run family (case, engine, formulation, integrator, precision): several per case
            cases = len({f.key[0] for f in group})
            families = (f"{rows} famil{'ies' if rows != 1 else 'y'} over {cases} case{'s' if cases != 1 else ''}"
                        if rows != cases else f"{rows} famil{'ies' if rows != 1 else 'y'}")
            f = min(group, key=lambda x: _number(x.current))
            lines.append(f"{engine} {integrator}: fitted {f.current}, baseline {f.baseline}, {f.message} ({families})"
                         if kind == "order" else f"{engine} {integrator}: fitted order missing ({families})")
        elif kind == "missing":
            lines.append(f"{head}, missing")
        else:
            lines.append(f"{head}, us_per_step up to {_ratio(max(f.ratio for f in group))}")
    return lines


def findings_table(findings: list[Finding]) -> str:
    """A fixed-width table of the findings, for the terminal and CI logs: each row's ratio, and for a status change
    or an order the run's message."""
    header = [*KEY, "what", "baseline", "current", "allowed", "ratio", "message"]
    cells = [header] + [[*(f.key[:6] if f.key[-1] != "order" else (*f.key[:5], "")), f.what, f.baseline, f.current,
                         f.allowed, _ratio(f.ratio), f.message] for f in findings]
    widths = [max(len(row[i]) for row in cells) for i in range(len(header))]
    return "\n".join("  ".join(cell.ljust(w) for cell, w in zip(row, widths)).rstrip() for row in cells)
