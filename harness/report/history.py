"""`stereodyn history`'s page: the "History" section (registered as any other, so a folder holding history tables
shows it in its report too), written with its figure as OUT/history.md and OUT/history.html beside the CSVs
(harness.analysis.history computes them)."""
from __future__ import annotations

import math
from pathlib import Path

import pandas as pd

from ..analysis.compare import label as row_label
from ..analysis.history import ORDER, STATUS, STEP_COLUMNS
from ..run.results import read_csv_table, write_atomic
from . import figures, html, sections
from .markdown import markdown_table, md_text

HISTORY_FILE, STEPS_FILE, POINTS_FILE = "history.csv", "history_steps.csv", "history_points.csv"
FIGURE = "figures/history-steps.png"
LISTED = 60        # steps listed on the page (history_steps.csv has them all)
FIGURE_SERIES = 8  # series drawn, worse steps first


def _read(out_dir: Path, name: str) -> pd.DataFrame | None:
    path = Path(out_dir) / name
    if not path.exists():
        return None
    return read_csv_table(path, keep_default_na=False,
                          dtype={"formulation": str, "integrator": str, "dt": str, "label": str, "change": str,
                                 "commit": str, "date": str})


def _row(entry) -> str:
    row = dict(entry)
    if row["quantity"] == ORDER:  # an order belongs to a run family, not to one dt
        return row_label({**row, "dt": "x"}).rsplit(" dt=", 1)[0]
    return row_label(row)


def _number(value) -> str:
    try:
        value = float(value)
    except (TypeError, ValueError):
        return str(value)
    return "-" if not math.isfinite(value) else f"{value:.3g}"


@sections.register("history", 95)
def history_lines(context: sections.Context) -> list[str]:
    """The points in their order, the steps flagged (worse first) and the figure of the series that stepped; []
    where the folder holds no history."""
    points, steps = _read(context.out_dir, POINTS_FILE), _read(context.out_dir, STEPS_FILE)
    if points is None or steps is None:
        return []
    by = points["ordered_by"].iloc[0] if "ordered_by" in points and len(points) else "given"
    shown = [c for c in points.columns if c not in ("path", "ordered_by")]
    lines = ["## History", "",
             f"{len(points)} runs in order ({by}); {len(steps)} steps flagged "
             f"({(steps['direction'] == 'worse').sum()} worse, {(steps['direction'] == 'better').sum()} better). "
             f"{HISTORY_FILE} holds every series (each metric, status and fitted order of each row at each run), "
             f"{STEPS_FILE} the steps. A step is where the piecewise-constant fit of a series (asv's step detection) "
             "changes level by at least its threshold: a metric by the factor, a fitted order by the difference, "
             "a status by any change.", "",
             *markdown_table([md_text(c) for c in shown], [[_number(r[c]) if c in ("rows", "orders", "steps", "worse") else md_text(r[c])
                                      for c in shown] for _, r in points.iterrows()]), ""]
    if steps.empty:
        return lines + ["No series stepped: every metric, status and fitted order kept its level over the sequence.",
                        ""]
    rows = [[md_text(_row(r)), r["quantity"], f"{r['point']} ({md_text(r['label'])})", _number(r["before"]),
             _number(r["after"]),
             r["change"], r["direction"]] for _, r in steps.head(LISTED).iterrows()]
    lines += ["### Steps", "", *markdown_table(["row", "quantity", "at run", "before", "after", "change", "direction"],
                                               rows), ""]
    if len(steps) > LISTED:
        lines += [f"... and {len(steps) - LISTED} more in {STEPS_FILE}.", ""]
    if (Path(context.out_dir) / FIGURE).exists():
        lines += [f"![history of the series that stepped]({FIGURE})", ""]
    return lines


def figure(table: pd.DataFrame, steps: pd.DataFrame, labels: list[str]) -> bytes | None:
    """A panel per series that stepped (at most FIGURE_SERIES, worse first; statuses have no value to draw): the value
    at each run, the run of the step marked."""
    drawn = steps[steps["quantity"] != STATUS].drop_duplicates(list(STEP_COLUMNS[:7])).head(FIGURE_SERIES)
    if drawn.empty:
        return None
    from matplotlib.figure import Figure

    columns = min(2, len(drawn))
    rows = math.ceil(len(drawn) / columns)
    width, height = 5.0 * columns, 2.9 * rows + 0.2
    figure_ = Figure(figsize=(width, height))
    # room on the left of each panel for a log axis's labels (4x10^-9), above it for its two-line title
    figure_.subplots_adjust(left=0.95 / width, right=1 - 0.15 / width, bottom=0.55 / height, top=1 - 0.6 / height,
                            wspace=1.1 / 3.9, hspace=1.1 / 1.9)
    grid = figure_.subplots(rows, columns, squeeze=False)
    for axes in grid.flat[len(drawn):]:
        axes.set_visible(False)
    for axes, (_, step) in zip(grid.flat, drawn.iterrows()):
        same = (table["quantity"] == step["quantity"])
        for column in STEP_COLUMNS[:6]:
            same &= table[column].astype(str) == str(step[column])
        values = table[same].sort_values("point")
        axes.plot(values["point"], values["value"], marker="o", color="#1f77b4")
        at = values[values["point"] == step["point"]]
        axes.plot(at["point"], at["value"], marker="o", linestyle="", markersize=10, markerfacecolor="none",
                  color="#d62728" if step["direction"] == "worse" else "#2ca02c")
        if step["quantity"] != ORDER:
            axes.set_yscale("log")
            figures.log_ticks(axes.yaxis)  # plain-text ticks: no exponent smaller than the digits
        axes.set_xticks(range(1, len(labels) + 1), [str(i) for i in range(1, len(labels) + 1)])
        axes.tick_params(labelsize=figures.MIN_FONT_PT)
        axes.set_xlabel("run (history_points.csv)", fontsize=figures.LABEL_FONT_PT)
        axes.set_title(f"{_row(step)}\n{step['quantity']}: {step['direction']} at run {step['point']}",
                       fontsize=figures.MIN_FONT_PT)
    return figures.png(figure_)


def write(out: Path, table: pd.DataFrame, steps: pd.DataFrame, points: pd.DataFrame) -> list[Path]:
    """OUT/history.csv, history_steps.csv, history_points.csv, the figure, history.md and history.html (the History
    section on a page of its own); return the pages."""
    out = Path(out)
    (out / "figures").mkdir(parents=True, exist_ok=True)
    write_atomic(out / HISTORY_FILE, table.to_csv(index=False, float_format="%.10g"))
    write_atomic(out / STEPS_FILE, steps.to_csv(index=False, float_format="%.10g"))
    write_atomic(out / POINTS_FILE, points.to_csv(index=False))
    png = figure(table, steps, list(points["label"]))
    if png is not None:
        write_atomic(out / FIGURE, png)
    elif (out / FIGURE).exists():  # a figure of an earlier history in this folder would be shown as this one's
        (out / FIGURE).unlink()
    context = sections.Context(out, pd.DataFrame(), {}, None, {}, {})
    markdown = "\n".join(["# stereodyn history", "", *history_lines(context)]) + "\n"
    write_atomic(out / "history.md", markdown)
    write_atomic(out / "history.html", html.render(markdown, {FIGURE: png} if png else {}, out, embed=False))
    return [out / "history.md", out / "history.html"]
