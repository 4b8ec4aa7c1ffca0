"""The drift table in the terminal and report.md."""
from __future__ import annotations

import re
import textwrap
from typing import Sequence

import numpy as np
import pandas as pd

from ..analysis.text import grouped_reasons, number, reason  # noqa: F401 (number, reason: part of this API)
from ..environment import environment
from ..run.results import COLUMNS as RESULTS_COLUMNS
from ..words import one_line
from . import sections

from ...reference.integrals import DRIFT_COLUMNS, INTEGRALS

# The drift tables' columns: every drift column of the registry (reference.integrals), a case's table showing those it
# has (_shown_columns).
TERMINAL_COLUMNS = ("engine", "formulation", "integrator", "dt", "status", *DRIFT_COLUMNS, "attitude_err",
                    "omega_err", "truth_err", "us_per_step")
SHORT = {**{integral.column: integral.short for integral in INTEGRALS.values()}, "attitude_err": "att_err",
         "omega_err": "omega_err", "us_per_step": "us/step", "chart_changes": "charts"}

DEFINITIONS_TEMPLATE = """\
- *_drift: max over the samples of |I(t) - I(0)| / scale, scale = the sum of the absolute values of the integral's
  terms at t = 0 (for a vector or a dot product, the norms). {integrals}. A special integral is shown only on cases
  that meet its conditions (FORMULARY G5-G8, G12), NaN elsewhere. Every integral is computed from the recorded states
  by the same code for every engine, never from an engine's own energy.
- attitude_err / attitude_err_end: max / final geodesic angle (rad) between the run's attitude and the truth's at the
  same times, up to the case's horizon; omega_err: max |omega - omega_truth| / max |omega_truth|.
- truth: engine reference, integrator taylor (heyoka, adaptive, tolerance 1e-16); truth_err (rad) and
  truth_omega_err (relative) bound its attitude and omega errors: its difference from a quadruple-precision rerun plus
  an allowance for a float64 comparison's rounding (none with --no-certify).
- adaptive runs (dt empty): an engine's error-controlled integrators at its default tolerance: heyoka's taylor
  (1e-16) and scipy's solve_ivp methods scipy_rk45, scipy_dop853, scipy_radau, scipy_bdf, scipy_lsoda (engine
  reference, rtol = atol = 1e-8, the dense output on the sample times); steps: accepted steps; rhs_per_sim_s counts
  every right-hand-side call, the implicit methods' finite-difference Jacobians included. tolerance.csv runs them at
  1e-3 ... 1e-13 (section Tolerance ladders).
- us_per_step: stepping time only, metrics off. Every run is timed once in its worker, right after its accuracy run
  (its warm-up). A run whose time can change a "What to use" answer (within 3x of its engine's fastest run at its
  accuracy) is then timed again, alone, in a phase after all the accuracy runs, so that no repeat shares the cores with
  another run: best of 3, at least 2 of them alone. results.csv's `timing` says which (`single` or `best of N`);
  ladder.csv and tolerance.csv likewise. Compare timings within one report. us_per_step_spread: the second-best timed
  run minus the best (µs per step), the noise of the figure; empty for a single time. rhs_per_sim_s: right-hand-side evaluations per simulated second, a cost noise cannot touch (steps x
  stages for an engine that does not count them; empty for an adaptive run that does not).
- formulation (engine reference): the state and equations integrated. quaternion: Euler-Poisson with a quaternion;
  gibbs: Ferrarese's Lagrangian in the Gibbs vector, with Christoffel symbols; gibbs_hamiltonian: his Hamiltonian form;
  euler_zxz: Lagrange's equations in ZXZ Euler angles. taylor integrates them by heyoka, the fixed-step integrators
  step the formulation's coordinates (a quaternion state is not renormalised). charts (chart_changes): how often the
  coordinates were re-centred on the current attitude, the Gibbs vector when |q| > 1 (a rotation of more than 90
  degrees from its frame), the angles when |sin theta| < 0.5.
- External torques (issue 5, reference.torques). energy_drift then means a balance: with a body torque
  M = (a + b|omega|^2) u or Grioli's torque (41), the work-energy balance |E(t) - E(0) - W(t)|, W = integral of M.omega
  dt from the recorded samples (antiderivative of a degree-7 interpolating spline), relative to the terms of E at
  t = 0 plus max |W|; with a central field in a fixed direction, the energy with MacCullagh's potential
  (3 mu / 2 r^3) H.sigma H; with the field's direction turning at orbit_rate Omega about world z, the Jacobi integral
  J = 1/2 sigma omega.omega + (3 mu / 2 r^3) H.sigma H - Omega K_z (K_z the world z component of R sigma omega),
  conserved because the scene is stationary in the frame turning with the orbit (its Lagrangian in the relative
  angular velocity omega - Omega R^T z does not depend on time, and J is its Jacobi function); a body torque on top
  adds the work of M along omega - Omega R^T z. momentum: K.D along a fixed field's direction D (NaN otherwise).
  precession_axis_drift: max |e(t) - e(0)| of the
  world precession axis (40) e = sin(theta)(omega - (omega.u)u)/|omega x u| + cos(theta) u under torque (41);
  NaN when a sample comes within 0.05 rad of omega || u, where (41) is singular. torque_mode: how the torque entered
  the engine: rhs (the reference's equations), qfrc_applied (MuJoCo, a constant torque set once), passive_callback
  (MuJoCo's mjcb_passive, seen at every RK4 stage), stage (Pinocchio, tau at every stage), none.
- Sliding ladder (kind sliding_ladder, harness.scenes.sliding_ladder): rows are the equation
  theta'' = 3g/(4l) sin theta (engine reference, formulation theta) and MuJoCo's bilateral and unilateral models
  (formulation column). energy_drift: the rod's energy 1/2 m|v_G|^2 + 1/2 (m l^2/3) theta'^2 + m g y_G;
  attitude_err: |theta - theta_equation| (rad), omega_err likewise for theta', up to the equation's detachment for the unilateral model. checks.csv: the
  detachment angle against arccos((2/3) cos theta0 + 4 l theta0'^2 / (9 g)), energy drift, constraint violation (m)."""
# The registry's definitions (reference.integrals), one per drift column, in table order.
def _definitions() -> str:
    drifts, rest = DEFINITIONS_TEMPLATE.split("\n- ", 1)
    drifts = drifts.replace("{integrals}", "; ".join(f"{i.name}: {i.definition}" for i in INTEGRALS.values()))
    return textwrap.fill(" ".join(drifts.split()), width=118, subsequent_indent="  ") + "\n- " + rest


DEFINITIONS = _definitions()


def _fmt(value, column: str) -> str:
    if isinstance(value, str):
        return value
    if value is None or (isinstance(value, float) and np.isnan(value)):
        return "" if column in ("dt",) else "-"
    if column == "dt":
        return f"{value:g}"
    if column == "us_per_step":
        return f"{value:.3g}"
    if column == "chart_changes":
        return f"{value:.0f}"
    return f"{value:.2e}"


def _shown_columns(df: pd.DataFrame, columns: tuple[str, ...]) -> list[str]:
    """Drop numeric columns that are NaN on every row (integrals the case does not have), and the formulation when
    no engine shown has one."""
    if "formulation" in columns and not (df["formulation"].fillna("") != "").any():
        columns = tuple(c for c in columns if c != "formulation")
    return [c for c in columns if c in ("engine", "formulation", "integrator", "dt", "status")
            or df[c].notna().any()]


def _table(df: pd.DataFrame, columns: list[str]) -> list[list[str]]:
    return [[SHORT.get(c, c) for c in columns]] + [[_fmt(row[c], c) for c in columns] for _, row in df.iterrows()]


def drift_table_text(df: pd.DataFrame) -> str:
    """Fixed-width drift tables, one per case, for the terminal."""
    out = []
    for case, group in df.groupby("case", sort=False):
        cells = _table(group, _shown_columns(group, TERMINAL_COLUMNS))
        widths = [max(len(row[i]) for row in cells) for i in range(len(cells[0]))]
        out.append(f"== {case}")
        out += ["  ".join(cell.rjust(w) for cell, w in zip(row, widths)) for row in cells]
        out.append("")
    return "\n".join(out)


_MARKUP = re.compile(r"[\\`*\[\]<>|~&#!]|(?<![A-Za-z0-9])_|_(?![A-Za-z0-9])")


_BAR = re.compile(r"(?<!\\)\|")  # a bar not escaped yet


def md_text(value) -> str:
    """A value as markdown text that shows as itself, on one line: control characters (a newline in a case name or an
    environment value) written as escapes, markup escaped (a name the user chose: a folder's, a case's)."""
    return _MARKUP.sub(lambda m: "\\" + m.group(0), one_line(value))


def markdown_table(header: list[str], rows: list[list]) -> list[str]:
    """The lines of a Markdown table, each cell on its line (words.one_line: a newline in a cell ended the table)."""
    # A bar inside a cell (a message about |omega|, say) would end the cell: escape it (once: md_text's is escaped)
    escape = lambda cell: _BAR.sub(r"\\|", one_line(cell))  # noqa: E731
    return (["| " + " | ".join(header) + " |", "|" + "---|" * len(header)]
            + ["| " + " | ".join(escape(c) for c in row) + " |" for row in rows])


def _markdown_table(cells: list[list[str]]) -> str:
    return "\n".join(markdown_table(cells[0], cells[1:]))


PROBLEMS = "Runs that did not complete"
# Runs named per reason in "Runs that did not complete" (the CSV files hold every row).
REASON_EXAMPLES = 3


def problem_lines(df: pd.DataFrame) -> list[str]:
    """ "Runs that did not complete": one row per status and reason (numbers elided), with its count."""
    entries = grouped_reasons(df)
    if not entries:
        return []
    # a reason is a run's message, a plug-in's text: markup escaped (`*x*` or `<img>` rendered, issue 46's 13th attack)
    rows = [[e["status"], str(e["count"]), md_text(e["reason"]),
             "; ".join(e["runs"][:REASON_EXAMPLES]) + (f"; and {e['count'] - REASON_EXAMPLES} more"
                                                       if e["count"] > REASON_EXAMPLES else "")]
            for e in entries]
    total = sum(e["count"] for e in entries)
    return [f"## {PROBLEMS}", "",
            f"{total} runs, grouped by status and reason (numbers in the message elided); results.csv has each "
            "run's message.", "", *markdown_table(["status", "runs", "reason", "for example"], rows), ""]


def case_lines(case: str, group: pd.DataFrame, extras: Sequence[str] = ()) -> list[str]:
    """A case's section: its drift table, its divergences, then `extras` (its figures)."""
    columns = TERMINAL_COLUMNS[:-2] + ("attitude_err_end", "truth_err", "chart_changes", "wall_s", "us_per_step")
    # a scene's own columns (Scene.columns beyond results.COLUMNS), which results.csv carries after the others
    columns += tuple(c for c in group.columns if c not in RESULTS_COLUMNS and not c.startswith("_"))
    counts = group["status"].value_counts()
    # Skipped runs have no numbers: counted here, their reasons grouped in "Runs that did not complete" (results.csv
    # has each row).
    ran = group[group["status"] != "skipped"]
    skipped = f"; the skipped ones are in {PROBLEMS} (grouped by reason)" if counts.get("skipped", 0) else ""
    lines = [f"### {case}", "", f"{len(group)} runs: " + ", ".join(
        f"{counts.get(s, 0)} {s}" for s in ("ok", "diverged", "failed", "skipped") if counts.get(s, 0)) + skipped,
             ""]
    if len(ran):
        lines += [_markdown_table(_table(ran, _shown_columns(ran, columns))), ""]
    diverged = group[group["status"] == "diverged"]
    for _, row in diverged.iterrows():
        formulation = row.get("formulation", "")
        formulation = f" {formulation}" if isinstance(formulation, str) and formulation else ""
        lines.append(f"- {row['engine']}{formulation} {row['integrator']} dt={row['dt']:g} diverged at t = "
                     f"{row['diverged_at']:.4g} s")
    if len(diverged):
        lines.append("")
    return lines + list(extras)


@sections.register("title", 0)
def _title(context: sections.Context) -> list[str]:
    return ["# stereodyn report", ""]


@sections.register("runs-that-did-not-complete", 50)
def _problems(context: sections.Context) -> list[str]:
    return problem_lines(context.results)


@sections.register("formulations-side-by-side", 60)
def _formulations(context: sections.Context) -> list[str]:
    return formulation_lines(context.results)


@sections.register("cases", 70)
def cases_lines(context: sections.Context) -> list[str]:
    """A section per case: its drift table, its divergences and its figures."""
    lines = ["## Cases", "",
             "Per case: the drift table (DESIGN §4; every column in results.csv), the work–precision figure (max "
             "attitude error against µs of stepping per simulated second, a panel per engine and formulation, "
             "each integrator's points joined along dt, the dt ladder's included) and the invariants against time "
             "(energy, momentum and the case's special integral, relative to their scale, and the attitude error: "
             "the maximum over buckets of samples).", ""]
    for case, group in context.results.groupby("case", sort=False):
        lines += case_lines(case, group, context.case_figures.get(case, ()))
    return lines


@sections.register("definitions", 90)
def _definitions_section(context: sections.Context) -> list[str]:
    return ["## Definitions", "", DEFINITIONS, ""]


@sections.register("environment", 100)
def _environment(context: sections.Context) -> list[str]:
    env = context.env or environment()
    return ["## Environment", "", *_engines_judged(context.results, env),
            *(f"- {key}: {value}" for key, value in env.items())]


def _engines_judged(results: pd.DataFrame, env: dict) -> list[str]:
    """The line naming each engine of the results with the versions of its packages the sweep ran (runs.json's
    environment), so that a report of MuJoCo 4.0.0 cannot be read as one of 3.3.7."""
    from ..engines import EngineError, get_engine

    judged = []
    for name in dict.fromkeys(results["engine"].dropna()) if "engine" in results else ():
        try:
            packages = get_engine(str(name)).about.packages
        except (EngineError, KeyError):
            packages = ()
        versions = ", ".join(f"{p} {env.get(p, 'absent')}" for p in packages)
        judged.append(f"{name} ({versions})" if versions else str(name))
    return [f"- engines judged: {'; '.join(judged)}"] if judged else []


FORMULATION_COLUMNS = ("formulation", "integrator", "dt", "status", "chart_changes", "energy_drift", "attitude_err",
                       "us_per_step")


def _side_by_side(df: pd.DataFrame):
    """(case, engine, dt, rows) of the case with several formulations whose rows at the middle common dt changed
    charts most often (first in table order on a tie), or None."""
    formulations = df["formulation"].fillna("") if "formulation" in df else pd.Series("", index=df.index)
    best = None
    for (case, engine), group in df[formulations != ""].groupby(["case", "engine"], sort=False):
        fixed = group[group["dt"].notna()]
        if fixed["formulation"].nunique() < 2:
            continue
        common = sorted(set.intersection(*(set(g["dt"]) for _, g in fixed.groupby("formulation"))), reverse=True)
        if not common:
            continue
        dt = common[len(common) // 2]
        at_dt = fixed[fixed["dt"] == dt]
        changes = at_dt["chart_changes"].fillna(0).sum() if "chart_changes" in at_dt else 0
        if best is None or changes > best[0]:
            best = (changes, case, engine, dt, pd.concat([group[group["dt"].isna()], at_dt]))
    return None if best is None else best[1:]


def formulation_lines(df: pd.DataFrame) -> list[str]:
    """The section "Formulations side by side": for one case and one engine with several formulations, every
    formulation at one dt (the middle of the dt values they all ran) with each fixed-step integrator, and integrated
    by the adaptive integrators (dt empty). The case: the one whose rows at that dt changed charts most often (the one
    where the coordinates differ most), first in table order on a tie; one such case without external torques (the
    Lagrange top, in the default suite) and one with them (torque_mode other than none), each where the sweep has one.
    Empty when no engine ran two formulations."""
    # (no fillna("none"): a column read back all empty is float64, and pandas deprecates filling it with a string)
    torqued = (df["torque_mode"].notna() & (df["torque_mode"] != "none")) if "torque_mode" in df \
        else pd.Series(False, index=df.index)
    tables = []
    for picked in (_side_by_side(df[~torqued]), _side_by_side(df[torqued])):
        if picked is None:
            continue
        case, engine, dt, rows = picked
        cells = _table(rows, list(FORMULATION_COLUMNS))
        cells[1:] = [[cell if cell or column != "dt" else "adaptive" for cell, column in zip(row, FORMULATION_COLUMNS)]
                     for row in cells[1:]]
        modes = sorted(set(rows["torque_mode"].dropna()) - {"none"}) if "torque_mode" in rows else []
        torque = f" (external torques, entered as: {', '.join(modes)})" if modes else ""
        tables += [f"### {case}", "", f"Case {case}, engine {engine}{torque}: each formulation at dt = {dt:g} with "
                   "every fixed-step integrator, and integrated by the adaptive ones.", "", _markdown_table(cells), ""]
    if not tables:
        return []
    return ["## Formulations side by side", "",
            "Heyoka's taylor's attitude error is the formulations' disagreement with the truth. Same equations "
            "of motion, different coordinates: the differences are the coordinates' doing.", "", *tables]

