"""The report's "What to use" section, from pareto.csv: one small table per engine (case × target: that engine's
cheapest run reaching it), then the table of every run (`any`, the reference formulations and heyoka included)."""
from __future__ import annotations

import pandas as pd

from ..analysis.pareto import ANY, TIE_MAX_RATIO, TIE_RTOL, run_name, scope_rows, scopes, setting
from .markdown import markdown_table, number


def what_to_use_lines(table: pd.DataFrame) -> list[str]:
    """The section's markdown lines (table: pareto.csv, text columns read as strings)."""
    lines = ["## What to use", "",
             "Per case and accuracy target (max attitude error, rad, up to the case's horizon): the cheapest run that "
             "reaches it (pareto.csv), fixed-step (dt=) or adaptive: the sweep's runs (an adaptive one at its "
             "engine's default tolerance, 'default tol'), the dt ladders' points and the tolerance ladders' (tol=, "
             "the requested tolerance; pareto.csv `source` says which). First per engine (pareto.csv `scope`: only "
             "that engine's runs, what its user can switch to), then over every run (`any`). The truth is no "
             "contender: it is what the errors are measured against. Cost in µs of stepping per simulated second. "
             "Timings are comparable within one report only; each run is timed alone (best of up to 3). "
             "'**tie** with N': N other runs cost the same within the timing noise (pareto.csv `ties`, the sum of "
             f"their spreads, at least {TIE_RTOL:.0%}, and never more than {TIE_MAX_RATIO:g} x the fastest); the one "
             "shown is the fastest's engine's run with the fewest right-hand-side evaluations per simulated second "
             "(evaluations are compared within one engine only; the cheapest where a tied run does not count them: "
             "heyoka's taylor; runs with the same evaluations and the same error in name order). A run whose timing "
             "spread exceeded its time even when re-timed ('timing disturbed' in its message) and a run whose "
             "integrator failed a verdict are never shown; a cheaper one of the latter is named as not "
             "recommended.", ""]
    targets = sorted(table["target"].unique(), reverse=True)
    for scope in [*scopes(table), ANY]:
        rows = scope_rows(table, scope)
        if rows.empty:
            continue
        own = scope != ANY
        title = f"### {scope}" if own else "### any engine"
        lines += [title, "", *markdown_table(["case"] + [f"≤ {t:.0e}" for t in targets],
                                             [[case] + [_cell(group, t, own) for t in targets]
                                              for case, group in rows.groupby("case", sort=False)]), ""]
    return lines


def _cell(group: pd.DataFrame, target: float, own: bool) -> str:
    hit = group[group["target"] == target]
    row = hit.iloc[0] if len(hit) else None
    if row is None or not row["engine"]:
        cell = "-"
    else:
        name = " ".join(x for x in (row["formulation"], row["integrator"]) if x) if own else run_name(row)
        cell = f"{name} {setting(row)} ({number(row['us_per_sim_s'], '.3g')} µs/s)"
        ties = row.get("ties", "")
        if isinstance(ties, str) and ties:
            cell += f" **tie** with {ties.count(';') + 1}"
    failed_runs = row.get("not_recommended", "") if row is not None else ""
    if isinstance(failed_runs, str) and failed_runs:
        cell += f" (cheaper, not recommended: {failed_runs.split(';')[0]}, failed a verdict)"
    return cell
