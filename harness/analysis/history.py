"""History: any number of runs (result folders or baselines) lined up in a sequence, each gated row's metrics, status
and each fitted order followed over it, and the steps in each series flagged, as asv flags them (tables in, tables
out; harness.report.history renders, harness.cli.history reads the files).

A step is found as asv's step detection finds it: the series is fitted by a piecewise-constant function minimising
the sum of absolute deviations plus a penalty per segment (asv.step_detect), here by exact dynamic programming (a
history is tens of points, not thousands). Metrics are fitted in log10 of max(value, FLOOR) (compare's ratio floor:
round-off has no ratio), fitted orders as they are. A boundary between two segments whose levels differ by at least
the threshold is a step: a factor STEP_FACTOR for a metric, ORDER_STEP for an order. A status that changes is a step
too.
"""
from __future__ import annotations

import datetime
import itertools
import math
from dataclasses import dataclass
from statistics import median

import pandas as pd

from . import gate
from .compare import FLOOR, GROUPS
from ..environment import differences
from ..run.results import KEY
from ..words import clipped, one_line

# The smallest change of a metric flagged: compare's smallest change group (1.1x). Reruns on one machine are
# bit-identical and round-off across machines moves these deterministic metrics by far less than 10 %
# (harness.analysis.gate), so a level that moves by 10 % moved for a reason.
STEP_FACTOR = 10 ** GROUPS[-1][0]
# The smallest change of a fitted order flagged: the gate's ORDER_DROP (round-off moves a fit by < 0.01; a method
# that lost an order moves by >= 1).
ORDER_STEP = gate.ORDER_DROP
ORDER_KEY = gate.ORDER_KEY
STATUS = "status"
ORDER = "order"
ABSENT = "-"
COLUMNS = (*KEY, "quantity", "point", "label", "value", "status", "step", "change")
STEP_COLUMNS = (*KEY, "quantity", "point", "label", "before", "after", "change", "direction")


@dataclass(frozen=True)
class Point:
    """One run in the sequence. label: its name in the tables (unique); path: where it was read; table: its rows
    (results.csv or a baseline's rows); orders: its fitted orders (convergence.csv or a baseline's "orders"; may be
    empty: columns of gate.ORDER_KEY, fitted, declared); environment: runs.json's (versions, date, git commit)."""

    label: str
    path: str
    table: pd.DataFrame
    orders: pd.DataFrame
    environment: dict


def segments(values: list[float], threshold: float) -> list[int]:
    """The start indices (after 0) of the segments of the L1 piecewise-constant fit of `values` (finite), each new
    segment costing `threshold` (a level off by the threshold costs as much as a segment), kept only where the fitted
    levels of two neighbouring segments differ by at least `threshold`."""
    n = len(values)
    # a series whose values all lie within the threshold has no step (every fitted level is a median of its values):
    # most series of deterministic runs, and the fit is O(n^3)
    if n < 2 or max(values) - min(values) < threshold * (1 - 1e-9):
        return []

    def cost(i: int, j: int) -> float:  # values[i:j] fitted by their median
        level = median(values[i:j])
        return sum(abs(v - level) for v in values[i:j])

    best = [0.0] + [math.inf] * n  # best[j]: the cheapest fit of values[:j]
    start = [0] * (n + 1)
    for j in range(1, n + 1):
        for i in range(j):
            total = best[i] + cost(i, j) + threshold
            if total < best[j] - 1e-15:
                best[j], start[j] = total, i
    bounds, j = [], n
    while j > 0:
        bounds.append(start[j])
        j = start[j]
    bounds = sorted(bounds)  # [0, s1, s2, ...]
    levels = [median(values[a:b]) for a, b in zip(bounds, bounds[1:] + [n])]
    # a tolerance of one part in 1e9 of the threshold: a step of exactly the threshold (the factor 1.1 in log10 after
    # rounding) is a step
    return [s for s, before, after in zip(bounds[1:], levels, levels[1:])
            if abs(after - before) >= threshold * (1 - 1e-9)]


def _order_key(row: dict) -> tuple:
    return gate._order_key(row) + ("",)


def _value(row: dict | None, column: str) -> float:
    return math.nan if row is None else gate._number(row.get(column))


def series(points: list[Point]) -> pd.DataFrame:
    """history.csv without the steps: one row per key (KEY), quantity (each metric, `status`, `order` with dt "")
    and point, in the points' order: value (the metric or fitted order; empty for status), status (the row's; "-"
    where the point has no such row)."""
    indexed = [{gate._key(r): r for r in p.table.to_dict("records")} for p in points]
    keys = list(dict.fromkeys(k for rows in indexed for k in rows))
    metrics = list(dict.fromkeys(m for p in points for m in gate.metric_columns(p.table.columns)))
    out = []
    for key in keys:
        for quantity in [STATUS, *metrics]:
            for index, (point, rows) in enumerate(zip(points, indexed)):
                row = rows.get(key)
                status = ABSENT if row is None else str(row.get("status"))
                out.append((*key, quantity, index + 1, point.label,
                            math.nan if quantity == STATUS else _value(row, quantity), status))
    orders = [{_order_key(r): r for r in p.orders.to_dict("records")} if len(p.orders) else {} for p in points]
    for key in dict.fromkeys(k for rows in orders for k in rows):
        for index, (point, rows) in enumerate(zip(points, orders)):
            row = rows.get(key)
            out.append((*key, ORDER, index + 1, point.label, _value(row, "fitted"), ABSENT if row is None else "fit"))
    return pd.DataFrame(out, columns=[*KEY, "quantity", "point", "label", "value", "status"])


def _declared(points: list[Point]) -> dict:
    declared = {}
    for point in points:
        for row in point.orders.to_dict("records") if len(point.orders) else []:
            value = gate._number(row.get("declared"))
            if math.isfinite(value):
                declared[_order_key(row)] = value
    return declared


def flag(table: pd.DataFrame, points: list[Point], factor: float = STEP_FACTOR,
         order_step: float = ORDER_STEP) -> tuple[pd.DataFrame, pd.DataFrame]:
    """(history, steps): `series`'s table with `step` (worse, better, changed or "") and `change` (B/A of a metric's
    fitted levels, the difference of an order's, "A -> B" of a status) at each point where a series steps, and the
    steps alone (STEP_COLUMNS: before and after the fitted levels, or the statuses). Lower is better for a metric; for
    an order, a fall the gate fails (gate.ORDER_DROP) is worse, else nearer the declared order (a higher one where none
    is declared) better, else a change; a worse status ranks as the gate
    ranks it (ok < diverged < failed, skipped), a row gone missing is worse, a row that appears a change."""
    declared = _declared(points)
    records = table.to_dict("records")
    found = []
    for (key, quantity), rows in _groups(records):
        if quantity == STATUS:
            statuses = [records[r]["status"] for r in rows]
            for i in range(1, len(statuses)):
                before, after = statuses[i - 1], statuses[i]
                if after != before:
                    found.append((rows[i], before, after, f"{before} -> {after}", _status_direction(before, after)))
            continue
        found += _became_nan(records, rows, quantity)
        finite = [(r, records[r]["value"]) for r in rows if math.isfinite(records[r]["value"])]
        if quantity == ORDER:
            levels, threshold = [v for _, v in finite], order_step
        else:
            levels, threshold = [math.log10(max(v, FLOOR)) for _, v in finite], math.log10(factor)
        if not levels:  # no number at any run (a metric this row never has)
            continue
        starts = segments(levels, threshold)
        bounds = [0, *starts, len(levels)]
        fitted = [median(levels[a:b]) for a, b in zip(bounds, bounds[1:])]
        for s, before, after in zip(starts, fitted, fitted[1:]):
            if quantity == ORDER:
                target = declared.get(key)
                better = (abs(after - target) < abs(before - target)) if target is not None else after > before
                # worse exactly where the gate fails it (fell by more than its ORDER_DROP), so history agrees with check
                direction = "worse" if after < before - gate.ORDER_DROP else "better" if better else "changed"
                found.append((finite[s][0], before, after, f"{after - before:+.2f}", direction))
            else:
                ratio = 10 ** (after - before)
                found.append((finite[s][0], 10 ** before, 10 ** after, f"{ratio:.3g}x",
                              "worse" if ratio > 1 else "better"))
    step, change = [""] * len(records), [""] * len(records)
    steps = []
    for row, before, after, text, direction in found:
        step[row], change[row] = direction, text
        entry = records[row]
        steps.append((*[entry[k] for k in KEY], entry["quantity"], entry["point"], entry["label"], before, after,
                      text, direction))
    steps_table = pd.DataFrame(steps, columns=list(STEP_COLUMNS))
    if len(steps_table):  # worse first, then by where in the sequence
        rank = steps_table["direction"].map({"worse": 0, "changed": 1, "better": 2})
        steps_table = steps_table.assign(_rank=rank).sort_values(["_rank", "point"], kind="stable") \
            .drop(columns="_rank").reset_index(drop=True)
    return table.assign(step=step, change=change)[list(COLUMNS)], steps_table


def _became_nan(records: list[dict], rows: list[int], quantity: str) -> list[tuple]:
    """The points where a metric that had a number on an ok row became NaN on a row still ok (worse: the gate fails
    it), or a fitted order that had a number became NaN or went (worse: the gate fails it, "fell" or "missing"), and
    where such a value got a number again (better). The finite values' levels are fitted apart (flag)."""
    found, had, last = [], False, math.nan
    for r in rows:
        value, ok = records[r]["value"], quantity == ORDER or records[r]["status"] == "ok"
        if ok and not math.isfinite(value) and had and math.isfinite(last):
            found.append((r, last, math.nan, "NaN", "worse"))
        elif ok and math.isfinite(value) and had and not math.isfinite(last):
            found.append((r, math.nan, value, "a number again", "better"))
        if ok and math.isfinite(value):
            had = True
        if ok:
            last = value
    return found


def _status_direction(before: str, after: str) -> str:
    """A status change signed as the gate ranks statuses; a row gone missing is worse (the gate fails it), one that
    appears is a change (the gate does not check it)."""
    if after == ABSENT:
        return "worse"
    if before == ABSENT:
        return "changed"
    rank = gate.STATUS_RANK
    return "worse" if rank[after] > rank[before] else "better" if rank[after] < rank[before] else "changed"


def _groups(records: list[dict]):
    """((key, quantity), row indices) per series of `series`'s table, in its order (keys may hold "" and NaN: grouped
    by hand, not by pandas, which drops NaN keys)."""
    seen: dict = {}
    for index, row in enumerate(records):
        seen.setdefault((tuple(row[k] for k in KEY), row["quantity"]), []).append(index)
    return seen.items()


def history(points: list[Point], factor: float = STEP_FACTOR,
            order_step: float = ORDER_STEP) -> tuple[pd.DataFrame, pd.DataFrame]:
    """(history.csv, history_steps.csv) of a sequence of points."""
    return flag(series(points), points, factor, order_step)


def points_table(points: list[Point], steps: pd.DataFrame) -> pd.DataFrame:
    """history_points.csv: per point its label, path, date, commit, rows, fitted orders, steps flagged there (worse),
    and every environment entry that differs between two of the points (environment.differences: the measurement
    context aside)."""
    keys = list(dict.fromkeys(k for p in points for k in p.environment))
    differ = {k for a, b in itertools.combinations(points, 2) for k in differences(a.environment, b.environment)}
    varying = [k for k in keys if k in differ]
    rows = []
    for index, point in enumerate(points, 1):
        here = steps[steps["point"] == index] if len(steps) else steps
        rows.append({"point": index, "label": point.label, "path": one_line(point.path),  # a CR in it: no CSV
                     "date": clipped(point.environment.get("date", "")),
                     "commit": str(point.environment.get("git commit", ""))[:12],
                     "rows": len(point.table), "orders": len(point.orders),
                     "steps": len(here), "worse": int((here["direction"] == "worse").sum()) if len(here) else 0,
                     **{clipped(k): clipped(point.environment.get(k, ABSENT)) for k in varying}})
    return pd.DataFrame(rows)


# -------------------------------------------------------------------------------------------------- ordering

def version_key(text: str) -> tuple:
    """A sort key of a version string (PEP 440 where it parses; "absent" and unparsable ones last, by text)."""
    from packaging.version import InvalidVersion, Version

    try:
        return (0, Version(str(text)), "")
    except InvalidVersion:
        return (1, Version("0"), str(text))


def order(points: list[Point], by: str, commits: list[str] | None = None) -> list[Point]:
    """The points in the order `by` names: "given" (as listed), "date" (runs.json's date, ISO 8601), "commit" (by
    position in `commits`, oldest first: the repository's history), or an environment key (a package: "mujoco"),
    by its version. ValueError (one line naming the point and the rule) when a point lacks what orders it. Ties keep
    the given order."""
    if by == "given":
        return list(points)
    if by == "commit":
        position = {c: i for i, c in enumerate(commits or [])}
        missing = [p for p in points if p.environment.get("git commit") not in position]
        if missing:
            p = missing[0]
            raise ValueError(f"{p.path}: git commit {p.environment.get('git commit', 'unrecorded')!r} is not in the "
                             "repository's history (--repo)")
        return sorted(points, key=lambda p: position[p.environment["git commit"]])
    key = "date" if by == "date" else by
    missing = [p for p in points if key not in p.environment]
    if missing:
        raise ValueError(f"{missing[0].path}: no {key!r} recorded in its environment (runs.json), so --by {by} cannot "
                         "place it")
    if by == "date":
        moments = {id(p): recorded_moment(p.environment["date"]) for p in points}
        bad = next((p for p in points if moments[id(p)] is None), None)
        if bad is not None:  # "not a date", 12 or {"a": 1} were sorted as text (issue 46's thirteenth attack)
            raise ValueError(f"{bad.path}: date {clipped(bad.environment['date'])!r} recorded in its environment "
                             "(runs.json) is no ISO 8601 date and time, so --by date cannot place it")
        return sorted(points, key=lambda p: moments[id(p)])
    return sorted(points, key=lambda p: version_key(p.environment[key]))


def recorded_moment(value) -> float | None:
    """A runs.json date (ISO 8601, as stereodyn writes it: with its UTC offset; one without is taken as UTC) as a
    POSIX time, s; None for what is no such date."""
    if not isinstance(value, str):
        return None
    try:
        moment = datetime.datetime.fromisoformat(value)
        if moment.tzinfo is None:
            moment = moment.replace(tzinfo=datetime.timezone.utc)
        return moment.timestamp()
    except (ValueError, OverflowError, OSError):  # no date, or one outside what a timestamp holds (year 1, -14:00)
        return None


def orders_side_by_side(points: list[Point]) -> pd.DataFrame:
    """Every fitted order of every run family (gate.ORDER_KEY), the declared order and one column per point (its
    label; empty where that run fitted none), families in first-seen order."""
    rows: dict = {}
    for point in points:
        for row in point.orders.to_dict("records") if len(point.orders) else []:
            entry = rows.setdefault(gate._order_key(row), {"declared": math.nan})
            entry[point.label] = gate._number(row.get("fitted"))
            declared = gate._number(row.get("declared"))
            if math.isfinite(declared):
                entry["declared"] = declared
    return pd.DataFrame([{**dict(zip(ORDER_KEY, k)), "declared": v["declared"],
                          **{p.label: v.get(p.label, math.nan) for p in points}} for k, v in rows.items()],
                        columns=[*ORDER_KEY, "declared", *(p.label for p in points)])
