"""`stereodyn compare A B`: two runs side by side, what someone upgrading MuJoCo or Pinocchio reads.

A and B are result directories (results.csv, and runs.json for the environment) or baseline files (`stereodyn
baseline`). Written to OUT/compare.md and OUT/compare.html (OUT: B or --out): the environments with the differences
first, then the rows whose status or metrics changed, grouped by how much and sorted within a group, each metric as
the ratio B / A, and a figure of the largest changes. Rows are matched by (case, engine, formulation, integrator, dt) as in the gate.
"""
from __future__ import annotations

import json
import math
from pathlib import Path

import pandas as pd

from stereodyn.harness import gate
from stereodyn.harness.report.markdown import markdown_table

# Values below this are round-off (the gate's floor): two of them have no meaningful ratio, so a ratio is taken of
# max(value, FLOOR). The truth's drifts sit at 1e-16 .. 1e-14 and move by factors of ten between machines.
FLOOR = 1e-12
# Groups of rows by the largest accuracy change, |log10 ratio|: a tenfold change, twofold, a tenth; below the last,
# rows count as unchanged (round-off moves deterministic runs by far less than 10 %, harness.gate).
GROUPS = ((1.0, "changed 10x or more"), (math.log10(2.0), "changed 2x to 10x"),
          (math.log10(1.1), "changed 1.1x to 2x"))
# Environment keys that differ between any two runs (not a difference in what ran).
EXPECTED = ("date", "report rendered")
TIMING = "us_per_step"
DIFFERS = "DIFFERS"
LISTED = 40      # rows listed per group (the output folder's compare.csv holds every row)
FIGURE_ROWS = 20


class CompareError(ValueError):
    """A missing or malformed input of compare: one line, exit 2."""


def load(path: Path) -> tuple[pd.DataFrame, dict]:
    """(table, environment) of a result directory or a baseline file; CompareError when the table lacks the key
    columns or the status."""
    table, env = _load(Path(path))
    missing = [c for c in (*gate.KEY, "status") if c not in table.columns]
    if missing:
        name = Path(path) / "results.csv" if Path(path).is_dir() else Path(path)
        raise CompareError(f"{name}: no column {', '.join(missing)} (a row is keyed by {', '.join(gate.KEY)})")
    return table.fillna({"formulation": ""}), env


def _load(path: Path) -> tuple[pd.DataFrame, dict]:
    try:
        if path.is_dir():
            table = gate.read_table(path)
            manifest = path / "runs.json"
            env = {}
            if manifest.is_file():
                env = json.loads(manifest.read_text(encoding="utf-8")).get("environment") or {}
            return table, env
        if path.is_file():
            rows = gate.read_baseline(path)
            env = json.loads(path.read_text(encoding="utf-8")).get("environment") or {}
            return pd.DataFrame(rows), env
    except gate.GateError as exc:
        raise CompareError(str(exc)) from None
    except ValueError as exc:
        raise CompareError(f"{path}: not readable ({exc})") from None
    raise CompareError(f"{path}: no such result directory or baseline file")


def environment_rows(a: dict, b: dict) -> list[list[str]]:
    """[key, A, B, mark]: the keys that differ first (expected ones, the date, after them), then the equal ones."""
    keys = list(dict.fromkeys([*a, *b]))
    rows = [[k, str(a.get(k, "-")), str(b.get(k, "-"))] for k in keys]
    differs = lambda r: r[1] != r[2]  # noqa: E731
    rank = lambda r: (0 if differs(r) and r[0] not in EXPECTED else 1 if differs(r) else 2)  # noqa: E731
    return [r + [DIFFERS if rank(r) == 0 else "differs (expected)" if rank(r) == 1 else ""]
            for r in sorted(rows, key=rank)]


def _metrics(a: pd.DataFrame, b: pd.DataFrame) -> list[str]:
    return [c for c in gate.metric_columns(a.columns) if c in b.columns]


def row_changes(a: pd.DataFrame, b: pd.DataFrame) -> pd.DataFrame:
    """One row per key in A or B: statuses, the ratio B/A of every metric and of the timing, the largest accuracy
    change (|log10 ratio|) and its metric."""
    metrics = _metrics(a, b)
    index = lambda df: {gate._key(row): row for row in df.to_dict("records")}  # noqa: E731
    rows_a, rows_b = index(a), index(b)
    out = []
    for key in dict.fromkeys([*rows_a, *rows_b]):
        ra, rb = rows_a.get(key), rows_b.get(key)
        entry = dict(zip(gate.KEY, key))
        entry["status_a"] = "-" if ra is None else str(ra.get("status"))
        entry["status_b"] = "-" if rb is None else str(rb.get("status"))
        worst, worst_metric = 0.0, ""
        for metric in metrics + [TIMING]:
            x = gate._number(ra.get(metric)) if ra else math.nan
            y = gate._number(rb.get(metric)) if rb else math.nan
            ratio = max(y, FLOOR) / max(x, FLOOR) if math.isfinite(x) and math.isfinite(y) else math.nan
            entry[metric] = ratio
            if metric != TIMING and math.isfinite(ratio) and abs(math.log10(ratio)) > worst:
                worst, worst_metric = abs(math.log10(ratio)), metric
        entry["change"], entry["metric"] = worst, worst_metric
        out.append(entry)
    return pd.DataFrame(out)


def _group(row) -> str:
    if row["status_a"] == "-":
        return "only in B"
    if row["status_b"] == "-":
        return "only in A"
    if row["status_a"] != row["status_b"]:
        return "status changed"
    for threshold, name in GROUPS:
        if row["change"] >= threshold:
            return name
    return "unchanged"


def _label(row) -> str:
    dt = row["dt"] or "adaptive"
    return " ".join(str(x) for x in (row["case"], row["engine"], row["formulation"], row["integrator"]) if x) + \
        f" dt={dt}"


def _ratio(value: float) -> str:
    return "-" if not math.isfinite(value) else f"{value:.3g}"


def compare_lines(path_a: Path, path_b: Path, env_a: dict, env_b: dict, changes: pd.DataFrame,
                  figure: str | None) -> list[str]:
    """The lines of the output folder's compare.md."""
    lines = ["# stereodyn compare", "", f"A: `{path_a}`", "", f"B: `{path_b}`", "", "## Environment", ""]
    env = environment_rows(env_a, env_b)
    differing = [r[0] for r in env if r[3] == DIFFERS]
    lines += [("Differs: " + ", ".join(differing) + ".") if differing else "Same environment (the date aside).", ""]
    lines += markdown_table(["key", "A", "B", ""], env) + [""]
    groups = changes.apply(_group, axis=1) if len(changes) else pd.Series([], dtype=str)
    order = ["status changed", *(name for _, name in GROUPS), "only in A", "only in B"]
    counts = groups.value_counts()
    lines += ["## Rows", "",
              f"{len(changes)} rows matched by (case, engine, formulation, integrator, dt): "
              + ", ".join(f"{counts.get(g, 0)} {g}" for g in [*order, "unchanged"]) + ". Each metric as the ratio "
              f"B / A (of max(value, {FLOOR:g}): round-off has no ratio); the rows sorted by their largest accuracy "
              "change; us_per_step is timing, comparable only on one machine. compare.csv has every row.", ""]
    metrics = [c for c in changes.columns if c.endswith(gate.METRIC_SUFFIXES)] + [TIMING]
    for name in order:
        members = changes[groups == name].sort_values("change", ascending=False)
        if members.empty:
            continue
        shown = [m for m in metrics if members[m].notna().any()]
        rows = [[_label(r), r["status_a"], r["status_b"], r["metric"] or "-",
                 *[_ratio(r[m]) for m in shown]] for _, r in members.head(LISTED).iterrows()]
        lines += [f"### {name} ({len(members)} rows)", "",
                  # "B/A" in the header: a ratio, not a drift (the page colours drift columns on their scale)
                  *markdown_table(["row", "status A", "status B", "largest change", *(f"{m} B/A" for m in shown)],
                                  rows), ""]
        if len(members) > LISTED:
            lines += [f"... and {len(members) - LISTED} more in compare.csv.", ""]
    if figure:
        lines += ["## Largest changes", "", f"![largest changes]({figure})", ""]
    return lines


def figure(changes: pd.DataFrame) -> bytes | None:
    """A bar per row of the largest accuracy changes (log10 of the ratio B / A of its most-changed metric)."""
    top = changes[changes["change"] >= GROUPS[-1][0]].sort_values("change", ascending=False).head(FIGURE_ROWS)
    if top.empty:
        return None
    from matplotlib.figure import Figure

    from stereodyn.harness.report import figures

    values = [math.log10(r[r["metric"]]) for _, r in top.iterrows()]
    labels = [f"{_label(r)}: {r['metric']}" for _, r in top.iterrows()]
    fig = Figure(figsize=(10, 0.3 * len(top) + 1.2))
    fig.subplots_adjust(left=0.55, right=0.97, top=1 - 0.5 / (0.3 * len(top) + 1.2), bottom=0.6 / (0.3 * len(top)
                                                                                                     + 1.2))
    axes = fig.subplots()
    axes.barh(range(len(values)), values, color=["#d62728" if v > 0 else "#2ca02c" for v in values])
    axes.set_yticks(range(len(values)), labels, fontsize=figures.MIN_FONT_PT)
    axes.tick_params(axis="x", labelsize=figures.MIN_FONT_PT)
    axes.invert_yaxis()
    axes.axvline(0, color="black", linewidth=0.8)
    axes.set_xlabel("log10(B / A) of the row's most-changed metric (red: worse in B)", fontsize=figures.LABEL_FONT_PT)
    axes.set_title("largest changes", fontsize=figures.TITLE_FONT_PT)
    return figures.png(fig)  # the report's resolution and palette: readable at 100% (10 in = 960 px)


def compare(path_a: Path, path_b: Path, out: Path | None = None) -> tuple[Path, Path, list[str]]:
    """Write compare.md, compare.html, compare.csv (and the figure) to `out` (default: B, which must then be a
    directory); return the two pages and the headline lines for the terminal."""
    from stereodyn.harness.report import html
    from stereodyn.harness.run.results import write_atomic

    if out is None:
        if Path(path_b).is_file():
            raise CompareError(f"{path_b}: a baseline file, not a directory: give --out DIR for compare.md")
        out = Path(path_b)
    table_a, env_a = load(path_a)
    table_b, env_b = load(path_b)
    out = Path(out)
    out.mkdir(parents=True, exist_ok=True)
    changes = row_changes(table_a, table_b)
    png = figure(changes) if len(changes) else None
    figure_path = "figures/compare-largest-changes.png" if png else None
    lines = compare_lines(path_a, path_b, env_a, env_b, changes, figure_path)
    markdown = "\n".join(lines) + "\n"
    if png:
        (out / "figures").mkdir(exist_ok=True)
        write_atomic(out / figure_path, png)
    write_atomic(out / "compare.md", markdown)
    write_atomic(out / "compare.html", html.render(markdown, {figure_path: png} if png else {}, out))
    write_atomic(out / "compare.csv", changes.to_csv(index=False, float_format="%.6g"))
    differing = [f"{r[0]} {r[1]} -> {r[2]}" for r in environment_rows(env_a, env_b) if r[3] == DIFFERS]
    head = ["environment differs: " + ", ".join(differing) if differing else "environment: the same (the date aside)"]
    groups = changes.apply(_group, axis=1) if len(changes) else pd.Series([], dtype=str)
    for name in ["status changed", *(n for _, n in GROUPS), "only in A", "only in B"]:
        members = changes[groups == name].sort_values("change", ascending=False)
        if len(members):
            r = members.iloc[0]
            worst = (f"{r['metric']} x{_ratio(r[r['metric']])}" if r["metric"] and name in dict(map(reversed, GROUPS))
                     else f"{r['status_a']} -> {r['status_b']}")
            head.append(f"{len(members)} rows {name}; first: {_label(r)} ({worst})")
    return out / "compare.md", out / "compare.html", head
