"""`stereodyn compare A B`'s pages: OUT/compare.md and OUT/compare.html (OUT: B or --out) — the environments with
the differences first, then the rows whose status or metrics changed, grouped by how much and sorted within a group,
each metric as the ratio B / A, and a figure of the largest changes — and compare.csv (harness.analysis.compare's
table)."""
from __future__ import annotations

import math
from pathlib import Path

import pandas as pd

from ..analysis import gate
from ..analysis.compare import (BECAME_NAN, DIFFERS, FIGURE_ROWS, FLOOR, GROUPS, LISTED, ORDER_CHANGE, PR_RATIO, TIMING,
                                CompareError, environment_rows, group, identical, label, load, load_orders,
                                metric_signs, order_changes, row_changes, verdict_changes)
from ..precision import FLOAT64
from ..words import plural
from .markdown import markdown_table, md_text


def _ratio(value: float) -> str:
    return "NaN in B" if value == BECAME_NAN else "-" if not math.isfinite(value) else f"{value:.3g}"


def compare_lines(path_a: Path, path_b: Path, env_a: dict, env_b: dict, changes: pd.DataFrame,
                  figure: str | None) -> list[str]:
    """The lines of the output folder's compare.md."""
    # every value escaped (md_text), as compare-pr.md's: a folder's or a hand-edited table's names are the user's
    lines = ["# stereodyn compare", "", f"A: {md_text(path_a)}", "", f"B: {md_text(path_b)}", "", "## Environment", ""]
    env = environment_rows(env_a, env_b)
    differing = [r[0] for r in env if r[3] == DIFFERS]
    lines += [("Differs: " + ", ".join(map(md_text, differing)) + ".") if differing
              else "Same environment (the date aside).", ""]
    lines += markdown_table(["key", "A", "B", ""], [[md_text(cell) for cell in row] for row in env]) + [""]
    groups = changes.apply(group, axis=1) if len(changes) else pd.Series([], dtype=str)
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
        rows = [[md_text(label(r)), md_text(r["status_a"]), md_text(r["status_b"]), md_text(r["metric"] or "-"),
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


PR_LINES = 60  # a pull request's comment or step summary: the whole diff on one screen or two
# Rows per table, at most: with their headings the sections fill PR_LINES exactly (2 + 12 + 14 + 10 + 12 + 9 + 1).
PR_LISTED = {"environment": 6, "metrics": 8, "status": 4, "orders": 6, "verdicts": 3}


def _short(value: str) -> str:
    """A cell of the environment table: a source hash of 24 hex digits cut to 12, still unambiguous for a reader."""
    return " ".join(word[:12] + "…" if len(word) == 24 and all(c in "0123456789abcdef" for c in word) else word
                    for word in str(value).split(" "))


# Characters that markdown would read as markup in a value (a case name, an environment value, a path): escaped with a
# backslash, which GitHub's markdown renders as the character itself. "_" only at a word's edge (inside a word, as in
# attitude_err, it is never emphasis).


def _capped(header: list[str], rows: list[list], cap: int, rest: str) -> list[str]:
    """A table of at most `cap` rows, every cell escaped (md_text): one line a row whatever the values hold."""
    lines = ["| " + " | ".join(header) + " |", "|" + "---|" * len(header)]
    lines += ["| " + " | ".join(md_text(cell) for cell in row) + " |" for row in rows[:cap]]
    return lines + ([f"... and {len(rows) - cap} more {rest}"] if len(rows) > cap else [])


def _times(ratio: float) -> str:
    return "NaN in B" if ratio == BECAME_NAN else f"{ratio:.3g}x"


def _order(value: float) -> str:
    return "-" if math.isnan(value) else f"{value:.2f}"


def pr_lines(path_a: Path, path_b: Path, env_a: dict, env_b: dict, changes: pd.DataFrame, orders: list[dict],
             verdicts: list[dict], same_rows: bool, answers: list[dict] = ()) -> list[str]:
    """`compare --format pr`: at most PR_LINES lines of markdown, no image: the environment keys that differ, each
    accuracy metric's rows worse and better (lower is better), status changes, fitted orders that moved (nearer the
    declared order is better), verdicts that changed and the answers (answers.changed) that changed; one line, that
    B is identical to A, when nothing differs at all.

    An answer that moved only within the timing noise (its `noise`: the two answers' costs tie by the Pareto rule,
    pareto.tied) is no change: a rerun on one machine names another of the runs that tie, as its timings vary. It is
    said as such (in the identical line too) and counted nowhere as a change; any other changed answer is a change:
    the headline counts it, its line names it, and B is then not identical."""
    env = [r for r in environment_rows(env_a, env_b) if r[3] == DIFFERS]
    real = [c for c in answers if not c["noise"]]
    noise = len(answers) - len(real)
    if same_rows and not env and not orders and not verdicts and not real:
        moved = f" ({noise} moved only within the timing noise)" if noise else ""
        return [f"**stereodyn compare**: {md_text(path_b)} is identical to {md_text(path_a)} ({len(changes)} rows, the same "
                f"statuses, metrics, fitted orders, verdicts, answers{moved} and environment, the date aside)."]
    statuses = changes[changes["status_a"] != changes["status_b"]] if len(changes) else changes
    rank = {"ok": 0, "diverged": 1, "failed": 2, "skipped": 2, "-": 3}  # a row gone ("-") is the worst
    status_rows = [[label(r), r["status_a"], r["status_b"],
                    "worse" if rank.get(r["status_b"], 3) > rank.get(r["status_a"], 3) else "better"]
                   for _, r in statuses.iterrows()]
    status_rows.sort(key=lambda r: r[3] != "worse")
    metrics = metric_signs(changes)
    worse = sum(m["worse"] for m in metrics) + sum(r[3] == "worse" for r in status_rows) \
        + sum(o["sign"] == "worse" for o in orders) + sum(v["sign"] == "worse" for v in verdicts)
    lines = [f"**stereodyn compare**: B {md_text(path_b)} against A {md_text(path_a)}: {len(changes)} rows; "
             f"{'**' + plural(worse, 'change') + ' for the worse**' if worse else 'no change for the worse'} "
             f"(a metric beyond {PR_RATIO:g}x either way, an order moved by more than {ORDER_CHANGE:g})"
             + (f"; {_answers(len(real))} changed (What to use)" if real else "") + ".", ""]
    if env:
        lines += [f"Environment: {len(env)} key{'s differ' if len(env) != 1 else ' differs'}", "",
                  *_capped(["key", "A", "B"], [[r[0], _short(r[1]), _short(r[2])] for r in env],
                           PR_LISTED["environment"], "keys in compare.md"), ""]
    else:
        lines += ["Same environment (the date aside).", ""]
    if metrics:
        rows = [[m["metric"], f"{m['worse']} worse" if m["worse"] else "-", f"{m['better']} better" if m["better"]
                 else "-", f"{_times(m['worst'][1])} {m['worst'][0]}" if m["worst"] else "-",
                 f"{_times(m['best'][1])} {m['best'][0]}" if m["best"] else "-"] for m in metrics]
        lines += ["Accuracy, rows ok in both (B / A; lower error is better):", "",
                  *_capped(["metric", "worse", "better", "worst (B / A)", "best (B / A)"], rows, PR_LISTED["metrics"],
                           "metrics in compare.md"), ""]
    else:
        lines += [f"Accuracy: no metric of a row ok in both changed by more than {PR_RATIO:g}x.", ""]
    if status_rows:
        lines += [f"Status changes: {len(status_rows)}", "",
                  *_capped(["row", "A", "B", ""], status_rows, PR_LISTED["status"], "in compare.md"), ""]
    if orders:
        fell = sum(o["sign"] == "worse" for o in orders)
        rows = [[" ".join(x for x in (*o["key"][:4], "" if o["key"][4] == FLOAT64 else o["key"][4]) if x),
                 "-" if math.isnan(o["declared"]) else f"{o['declared']:g}", _order(o["a"]), _order(o["b"]),
                 o["sign"]] for o in orders]
        lines += [f"Fitted orders: {len(orders)} moved, {fell} worse (farther from the declared order, or gone)", "",
                  *_capped(["family", "declared", "A", "B", ""], rows, PR_LISTED["orders"],
                           "(compare both convergence.csv)"), ""]
    if verdicts:
        rows = [[v["name"], v["a"], v["b"], v["sign"]] for v in verdicts]
        lines += [f"Verdicts: {len(verdicts)} changed", "",
                  *_capped(["verdict", "A", "B", ""], rows, PR_LISTED["verdicts"], "(verdicts.csv)"), ""]
    last = "Every row: compare.md and compare.csv beside this summary."
    if answers:  # one line, in place of the last one where the sections fill PR_LINES
        line = answer_line(real, noise)
        lines += [line, "", last] if len(lines) + 3 <= PR_LINES else [line]
    else:
        lines.append(last)
    assert "\n".join(lines).count("\n") < PR_LINES, len(lines)  # PR_LISTED bounds it; md_text keeps a value one line
    return lines


def _answers(count: int) -> str:
    return f"{count} answer{'s' if count != 1 else ''}"


def answer_line(real: list[dict], noise: int, listed: int = 4) -> str:
    """The PR summary's line of the answers (answers.csv, What to use) that changed (`real`: answers.changed's
    entries that are no timing noise), and how many more moved only within the timing noise (no change)."""
    moved = f"{noise} more moved only within the timing noise (no change)" if noise else ""
    if not real:
        return (f"What to use (answers.csv): no answer changed beyond the timing noise ({noise} moved between runs "
                "whose costs tie).")
    said = "; ".join(f"{md_text(c['case'])} {md_text(c['scope'])} {c['target']:.0e}: {md_text(c['a'])} -> {md_text(c['b'])}"
                     for c in real[:listed])  # each name one line, shown as itself (md_text)
    return (f"What to use (answers.csv): {_answers(len(real))} changed: {said}"
            + (f"; {len(real) - listed} more" if len(real) > listed else "") + (f"; {moved}" if moved else "") + ".")


def figure(changes: pd.DataFrame) -> bytes | None:
    """A bar per row of the largest accuracy changes (log10 of the ratio B / A of its most-changed metric)."""
    drawn = changes[(changes["change"] >= GROUPS[-1][0]) & (changes["change"] < math.inf)]  # NaN in B has no bar
    top = drawn.sort_values("change", ascending=False).head(FIGURE_ROWS)
    if top.empty:
        return None
    from matplotlib.figure import Figure

    from . import figures

    values = [math.log10(r[r["metric"]]) for _, r in top.iterrows()]
    labels = [f"{label(r)}: {r['metric']}" for _, r in top.iterrows()]
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


PR_FILE = "compare-pr.md"


def compare(path_a: Path, path_b: Path, out: Path | None = None,
            pr: bool = False) -> tuple[Path, Path, list[str]]:
    """Write compare.md, compare.html, compare.csv (and the figure) to `out` (default: B, which must then be a
    directory), with pr also compare-pr.md (pr_lines); return the two pages and the headline lines for the terminal
    (with pr: the lines of compare-pr.md)."""
    from . import html, index
    from ..analysis import answers
    from ..run.results import write_atomic

    if out is None:
        if Path(path_b).is_file():
            raise CompareError(f"{path_b}: a baseline file, not a directory: give --out DIR for compare.md")
        out = Path(path_b)
    table_a, env_a = load(path_a)
    table_b, env_b = load(path_b)
    # read in every format, as check and history read them: what one refuses compare refuses (a fitted order of inf
    # in B was refused by check and taken by compare; issue 46's thirteenth attack)
    orders_a, orders_b = load_orders(path_a), load_orders(path_b)
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
    if pr:
        summary = pr_lines(path_a, path_b, env_a, env_b, changes, order_changes(orders_a, orders_b),
                           verdict_changes(path_a, path_b), identical(table_a, table_b),
                           answers.folder_changes(path_a, path_b))
        write_atomic(out / PR_FILE, "\n".join(summary) + "\n")
    if (out / index.INDEX_FILE).is_file():  # a result folder with its index (DIR/README.md) now holds these too
        index.write(out)
    if pr:
        return out / "compare.md", out / "compare.html", summary
    differing = [f"{r[0]} {r[1]} -> {r[2]}" for r in environment_rows(env_a, env_b) if r[3] == DIFFERS]
    head = ["environment differs: " + ", ".join(differing) if differing else "environment: the same (the date aside)"]
    groups = changes.apply(group, axis=1) if len(changes) else pd.Series([], dtype=str)
    for name in ["status changed", *(n for _, n in GROUPS), "only in A", "only in B"]:
        members = changes[groups == name].sort_values("change", ascending=False)
        if len(members):
            r = members.iloc[0]
            ratio = r[r["metric"]] if r["metric"] else math.nan
            worst = (f"{r['metric']} " + ("NaN in B" if ratio == BECAME_NAN else f"x{_ratio(ratio)}")
                     if r["metric"] and name in dict(map(reversed, GROUPS))
                     else f"{r['status_a']} -> {r['status_b']}")
            head.append(f"{len(members)} rows {name}; first: {label(r)} ({worst})")
    return out / "compare.md", out / "compare.html", head
