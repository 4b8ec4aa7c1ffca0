"""The report's work–precision sections: "What to use" (pareto.csv, harness.report.what_to_use), "Step-size advice"
(advice.csv, harness.report.advice), "Convergence, round-off floors and stability" (convergence.csv) and "Tolerance
ladders" (tolerance_fit.csv), from the tables that harness.analysis.workprecision writes."""
from __future__ import annotations

from pathlib import Path

import numpy as np

from ..analysis.fitting import ASYMPTOTIC_MAX, FIRST_PART, ROUNDOFF_MARGIN, SUPERCONVERGENT, _name, note_group
from ..analysis import answers, ladders as dt_ladders
from ..analysis.workprecision import (ADVICE_FILE, CONVERGENCE_FILE, SHORT_MAX_EVALS, SHORT_MAX_STEPS,
                                      TOLERANCE_FIT_FILE, read_optional)
from ..analysis.ladders import SHORT_LADDER, STABLE_ENERGY_DRIFT
from . import sections
from .advice import advice_lines
from .markdown import markdown_table as _md, number as _num
from .what_to_use import what_to_use_lines


def report_lines(out_dir: Path, tolerance_figures: dict[str, str] | None = None) -> list[str]:
    """The report's "What to use", "Step-size advice", "Convergence" and "Tolerance ladders" sections, from pareto.csv, convergence.csv
    and tolerance_fit.csv (each left out without its file). tolerance_figures: case -> the path of its
    tolerance-against-error figure (harness.report.build draws them)."""
    lines: list[str] = []
    answer_table = answers.read(out_dir)  # the one answer per case, engine and target that both sections show
    if answer_table is not None and len(answer_table):
        lines += what_to_use_lines(answer_table)
    lines += advice_lines(read_optional(Path(out_dir) / ADVICE_FILE, ("formulation", "engine", "integrator", "note")),
                          answer_table)
    convergence = read_optional(Path(out_dir) / CONVERGENCE_FILE, ("formulation", "note", "source"))
    if convergence is not None and len(convergence):
        ladders = convergence[convergence["source"] == "ladder"]
        fitted = convergence[np.isfinite(convergence["order"])]
        short = convergence[convergence["source"] == SHORT_LADDER]
        lines += ["## Convergence, round-off floors and stability", "",
                  f"convergence.csv: {len(fitted)} of {len(convergence)} run families have a fitted order (slope of "
                  "log state error, max(attitude_err, omega_err, casimir_drift), against log dt over the asymptotic "
                  f"range: {ROUNDOFF_MARGIN:g} x the rounding level (eps steps, or the round-off floor where the "
                  f"points show one) <= error <= {ASYMPTOTIC_MAX:g}); the others say why in `note`. Families with a "
                  "dt ladder (ladder.csv: about ten dt from the stability limit down to the round-off regime) also "
                  "have the round-off floor and the largest stable dt over t_end (bisection; stable: finished ok with "
                  f"energy drift <= {STABLE_ENERGY_DRIFT:g}); the others are fitted on the sweep's own dt list, and "
                  f"the {len(short)} whose list gave no order on a short ladder (`source` {SHORT_LADDER}: dt doubled "
                  f"from the list up to t_end / {dt_ladders.MIN_STEPS}, or halved, at most "
                  f"{dt_ladders.SHORT_POINTS} points, until three points are asymptotic; untimed points of at most "
                  f"{SHORT_MAX_STEPS} steps, or {SHORT_MAX_EVALS} right-hand-side evaluations where that is more; "
                  "a long horizon whose error stays above the range down to that cap is fitted over the case's first "
                  f"part, its `note` says over what span; {int(np.isfinite(short['order']).sum())} of them "
                  "fitted).", ""]
        if len(ladders):
            rows = [[r["case"], _name(r), _num(r["declared_order"], ".0f"), _num(r["order"], ".2f"),
                     _num(r["floor_dt"], ".3g"), _num(r["floor_err"]), _num(r["stable_dt_max"], ".4g"),
                     r["note"]] for _, r in ladders.iterrows()]
            lines += _md(["case", "run", "declared", "fitted order", "floor dt", "floor err", "stable dt max",
                          "note"], rows) + [""]
        others = fitted[fitted["source"] != "ladder"]
        if len(others):
            summary = []
            for (engine, formulation, integrator), group in others.groupby(["engine", "formulation", "integrator"],
                                                                           sort=False):
                summary.append([_name({"engine": engine, "formulation": formulation, "integrator": integrator}),
                                _num(group["declared_order"].iloc[0], ".0f"), str(len(group)),
                                _num(group["order"].min(), ".2f"), _num(group["order"].max(), ".2f")])
            lines += ["Fitted on the sweep's dt lists and the short ladders:", "",
                      *_md(["run", "declared", "cases", "smallest order", "largest order"], summary), ""]
        reasons = convergence[~np.isfinite(convergence["order"]) | convergence["note"].str.contains(
            SUPERCONVERGENT, regex=False) | convergence["note"].str.contains(FIRST_PART, regex=False)]
        if len(reasons):
            counts = reasons["note"].map(note_group).value_counts()
            lines += ["Families without a fitted order, fitted steeper than declared, or fitted over the case's first "
                      "part only, by reason (convergence.csv `note`):", "",
                      *_md(["reason", "families"], [[k, str(v)] for k, v in counts.items()]), ""]
    return lines + tolerance_report_lines(out_dir, tolerance_figures or {})


def tolerance_report_lines(out_dir: Path, figures: dict[str, str]) -> list[str]:
    """The report's "Tolerance ladders" section from tolerance_fit.csv (nothing without it or with no ladder)."""
    fits = read_optional(Path(out_dir) / TOLERANCE_FIT_FILE, ("formulation", "engine", "integrator", "note"))
    if fits is None or fits.empty:
        return []
    lines = ["## Tolerance ladders", "",
             "Every adaptive method run at requested tolerances from 1e-3 to 1e-13 (tolerance.csv: relative and "
             "absolute tolerance alike; per point the error achieved and the cost). 'slope': the fitted tolerance "
             "proportionality, the slope of log state error (max of attitude_err, omega_err, casimir_drift) against "
             f"log tolerance over the points above round-off ({ROUNDOFF_MARGIN:g} eps steps <= error <= "
             f"{ASYMPTOTIC_MAX:g}); 1 is an error proportional to the tolerance. 'error <= tol': at how many of "
             "those points the error stayed below the tolerance requested; 'max error/tol': the worst ratio (the "
             "tolerance bounds each step's local error, the error here is global over the whole run). "
             "tolerance_fit.csv holds the same rows.", ""]
    rows = [[r["case"], _name(r), _num(r["slope"], ".2f"), str(int(r["points"])),
             "-" if not r["points"] else f"{r['tol_max']:.0e} … {r['tol_min']:.0e}",
             f"{int(r['below_tol'])} of {int(r['points'])}", _num(r["max_err_over_tol"], ".3g"), r["note"]]
            for _, r in fits.iterrows()]
    lines += _md(["case", "method", "slope", "points", "tolerances fitted", "error <= tol", "max error/tol", "note"],
                 rows) + [""]
    for case, path in figures.items():
        lines += [f"![{case}: error reached against tolerance requested]({path})", ""]
    return lines


@sections.register("work-precision", 30)
def _work_precision(context: sections.Context) -> list[str]:
    return report_lines(context.out_dir, context.tolerance_figures)
