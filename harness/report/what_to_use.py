"""The report's "What to use" section: the answers table (harness.analysis.answers: advice.csv's searched settings,
else pareto.csv's cheapest listed run) once per engine, case × target, then over every engine (`any`)."""
from __future__ import annotations

import pandas as pd

from ..analysis.answers import LISTED, SEARCHED, answer_setting
from ..analysis.pareto import ANY, TIE_MAX_RATIO, TIE_RTOL, run_name
from ..words import plural
from .markdown import number

# The targets shown (max attitude error, rad): every other decade from 1e-2 keeps a table within a 1400 px window;
# pareto.csv and advice.csv hold every decade. 1e-3 and 1e-6 are the default run's advice targets.
SHOWN_TARGETS = (1e-2, 1e-3, 1e-4, 1e-6, 1e-8, 1e-10, 1e-12)
ANCHOR = "what-to-use"


def shown(target: float) -> bool:
    return any(abs(target - t) <= 1e-9 * t for t in SHOWN_TARGETS)


def what_to_use_lines(answers: pd.DataFrame) -> list[str]:
    """The section's markdown lines (answers: harness.analysis.answers.answers)."""
    lines = ["## What to use", "",
             "Per case and accuracy target (max attitude error, rad, up to the case's horizon): the one answer of "
             "this report, which the Summary and Step-size advice repeat. Each cell: the integrator, its dt (or "
             "requested tolerance, tol=; 'default tol': the engine's default), the error it reached, and its cost in "
             f"µs of stepping per simulated second. '{SEARCHED}': the largest setting that advice.csv checked by runs "
             "to reach the target (section Step-size advice). "
             f"'{LISTED}': the cheapest of the runs the sweep and the ladders listed (pareto.csv); a larger dt "
             "may reach the target too. Where both exist for an engine, the cheaper is the answer. First per engine "
             "(only that engine's runs: what its user can switch to; each table folds to a line of counts, open it), "
             "then over every engine (`any`: the cheapest engine's answer). The truth is no contender: it is what the "
             "errors are measured against. Timings are comparable within one report only; a run that could be "
             "an answer is timed alone, best of 3; the others, over 3x dearer, keep the one time taken in their worker "
             "(results.csv's `timing`). Runs within the timing "
             f"noise of the cheapest (the sum of their spreads, at least {TIE_RTOL:.0%}, never more than "
             f"{TIE_MAX_RATIO:g} x) are pareto.csv's `ties`; a run whose integrator failed a verdict, or whose timing "
             f"stayed disturbed, is no answer. '{SAME}': the answer of the cell to its left (it reaches this target "
             "too). Targets shown: "
             + ", ".join(f"{t:.0e}" for t in SHOWN_TARGETS) + " (pareto.csv and advice.csv hold every decade).", ""]
    targets = [t for t in sorted(answers["target"].unique(), reverse=True) if shown(t)]
    for scope in dict.fromkeys(answers["scope"]):
        rows = answers[answers["scope"] == scope]
        own = scope != ANY
        title = f"### {scope}" if own else "### any engine"
        table = _table(rows, targets, own)
        if own:  # an engine's table folds to one line of counts: the page's height is the cases' figures, not this
            at = rows[[shown(t) for t in rows["target"]]]
            counts = at["source"].value_counts()
            table = [f"<details><summary>{plural(rows['case'].nunique(), 'case')} × {plural(len(targets), 'target')}: "
                     f"{counts.get(SEARCHED, 0)} answers searched, {counts.get(LISTED, 0)} listed but not searched, "
                     f"{int((at['engine'] == '').sum())} targets no run reached</summary>", "", *table, "",
                     "</details>"]
        lines += [title, "", *table, ""]
    return lines


def _table(rows: pd.DataFrame, targets: list[float], own: bool) -> list[str]:
    from .markdown import markdown_table

    body = []
    for case, group in rows.groupby("case", sort=False):
        cells = [case]
        for target in targets:
            hit = group[(group["target"] - target).abs() <= 1e-9 * target]
            text = cell(hit.iloc[0], own) if len(hit) else "-"
            # most answers reach several targets: said once, the cells to its right point back to it
            cells.append(SAME if len(cells) > 1 and text != "-" and text == _last(cells) else text)
        body.append(cells)
    return markdown_table(["case"] + [f"≤ {t:.0e}" for t in targets], body)


SAME = "="  # a cell whose answer is the one to its left (that run reaches this target too)


def _last(cells: list[str]) -> str:
    """The answer a row's SAME cells point back to."""
    return next(c for c in reversed(cells) if c != SAME)


def cell(row, own: bool = True) -> str:
    """One answer as a cell: method, setting, error reached, cost and where it came from; '-' for none."""
    if not row["engine"]:
        return "-"
    name = " ".join(x for x in (row["formulation"], row["integrator"]) if x) if own else run_name(row)
    return (f"{name} {answer_setting(row)}: {number(row['error'], '.2g')} rad, {number(row['us_per_sim_s'], '.3g')} "
            f"µs/s ({row['source']})")
