"""The report's "Step-size advice" section, from advice.csv: per engine, the largest dt (or tolerance) of each
integrator that reaches each target, checked by runs, with its measured error and cost, or why there is none."""
from __future__ import annotations

import math

import pandas as pd

from ..analysis.answers import SEARCHED, answer_setting
from ..analysis.step_advice import CHECK_RATIO
from .markdown import markdown_table, number


def _answered(answers: pd.DataFrame | None) -> set[tuple]:
    """(case, engine, target, formulation, integrator, setting) of every searched answer of an engine."""
    if answers is None or answers.empty:
        return set()
    rows = answers[(answers["scope"] == answers["engine"]) & (answers["source"] == SEARCHED)]
    return {(r["case"], r["engine"], f"{r['target']:.0e}", r["formulation"], r["integrator"], answer_setting(r))
            for _, r in rows.iterrows()}


def advice_lines(table: pd.DataFrame, answers: pd.DataFrame | None = None) -> list[str]:
    """The section's markdown lines (table: advice.csv, text columns read as strings; answers:
    harness.analysis.answers, whose rows mark the engine's answer); none for an empty table."""
    if table is None or table.empty:
        return []
    answered = _answered(answers)
    lines = ["## Step-size advice", "",
             "Per engine, integrator and accuracy target (max attitude error over the case's horizon, rad, as in "
             "What to use): the largest step dt, or for an adaptive method the largest requested tolerance, that "
             "reaches it (advice.csv). Estimated from the fitted error model C·dt^p on the asymptotic range, then "
             f"checked by runs: the setting shown reaches the target, {CHECK_RATIO:g} times it (or less: 'fails at') "
             "does not. 'error checked' and 'µs/s' are the advised run's own, measured; a target beyond the step cap "
             "or below the method's floor says so instead. The default run checks the families with a dt or tolerance "
             "ladder at 1e-3 and 1e-6 rad; `--dt-ladder` every laddered family at every target; `stereodyn advise "
             "CASE --engine E` any case and engine. 'answer': the row What to use gives as the engine's answer (the "
             "cheapest advised integrator, unless a listed run is cheaper still).", ""]
    for engine, rows in table.groupby("engine", sort=False):
        cells = []
        for _, row in rows.iterrows():
            setting = f"tol = {row['tolerance']:.3g}" if math.isfinite(row["tolerance"]) else \
                f"dt = {row['dt']:.4g}" if math.isfinite(row["dt"]) else "-"
            formulation = row["formulation"] if isinstance(row["formulation"], str) else ""
            mark = (row["case"], engine, f"{row['target']:.0e}", formulation, row["integrator"],
                    answer_setting(row)) in answered
            cells.append([row["case"], " ".join(x for x in (formulation, row["integrator"]) if x),
                          f"{row['target']:.0e}", setting, number(row["error_checked"], ".2g"),
                          number(row["us_per_sim_s"], ".3g"), number(row["fails_at"], ".4g"),
                          "**answer**" if mark else "", row["note"]])
        # "### mujoco" is What to use's heading (and the page's anchor): this one names the section too. The error
        # column is not "error": that header is graded red to green, and an error that meets its target is no alarm.
        lines += [f"### {engine}: step sizes", "", *markdown_table(["case", "integrator", "target", "advised",
                                                                    "error checked", "µs/s", "fails at", "answer",
                                                                    "note"],
                                                                   cells), ""]
    return lines
