"""The report of an output folder: report.md, the figures it shows (DIR/figures/*.png), and report.html.

Sources, all in the folder: results.csv (the table), runs.json and store/ (the sweep's environment and each run's
invariant series, harness.run.store), checks.csv when some check wrote it (DESIGN §4).
"""
from __future__ import annotations

import datetime
import hashlib
import math
import multiprocessing
import os
import sys
from concurrent.futures import ProcessPoolExecutor
from pathlib import Path
from typing import Callable

import numpy as np
import pandas as pd

from ..scenes import checks as theory_checks
from ..analysis import workprecision
from ..analysis.verdicts import failed_integrators, read as read_verdicts
from . import figures, html, index
from . import sections
# the modules whose sections the page shows besides this one's and markdown's (each registers its own)
from .markdown import markdown_table as _md_table, number as _num
from ..run.processes import exit_with_parent, raise_unless_data
from ..run.results import read_csv_table, read_results, write_atomic
from ..run.store import read_manifest, read_records
from ..words import plural

FIGURES_DIR = "figures"
# The endings of the report's figures, CASE-KIND.png: the only PNGs of figures/ a new render removes or replaces.
FIGURE_KINDS = ("-work-precision.png", "-invariants.png", "-tolerance.png")
CHECKS_COLUMNS = ("case", "engine", "formulation", "integrator", "dt", "quantity", "theory", "measured", "error")
# "Good enough" attitude error for the summary's cheapest-run column: a microradian over the case's span.
SUMMARY_ACCURACY = 1e-6
# Figures per extra process when drawing in parallel: a process costs ~2 s to start, a figure 1-3 s to draw on the
# 2-core machine (the quick suite's report, 8 figures: 25-28 s drawn here, 17-19 s on two processes; issue 29).
PARALLEL_FIGURES = 2
NOT_DRAWN = ("Figures not drawn (--no-figures, or STEREODYN_FIGURES=0 in the environment): "
             "`stereodyn report DIR --figures` draws them.")


def _run_name(row) -> str:
    dt = "" if figures.dt_key(row["dt"]) == "" else f" dt={row['dt']:g}"
    return figures.run_label(row) + dt


def summary_lines(df: pd.DataFrame, failed: set = frozenset(), answer_table: pd.DataFrame | None = None) -> list[str]:
    """Per case: the most accurate fixed-step run, and the answer at SUMMARY_ACCURACY over every engine: What to use's
    (answer_table, harness.analysis.answers; without one, the answers of the results' own runs: pareto.csv's rule,
    failed: harness.analysis.verdicts.failed_integrators); where none, why in pareto.csv's words."""
    from ..analysis.answers import answer_setting, answers
    from ..analysis.pareto import ANY, pareto

    if answer_table is None:
        runs = df.assign(**{c: df[c] if c in df else np.nan for c in ("us_per_step_spread", "steps", "tolerance")})
        answer_table = answers(pareto(runs, pd.DataFrame(), set(failed)), None, failed)
    at = answer_table[(answer_table["scope"] == ANY)
                      & ((answer_table["target"] - SUMMARY_ACCURACY).abs() <= 1e-9 * SUMMARY_ACCURACY)]
    rows = []
    for case, group in df.groupby("case", sort=False):
        ok = group[(group["status"] == "ok") & np.isfinite(group["attitude_err"]) & np.isfinite(group["dt"])]
        best = ok.loc[ok["attitude_err"].idxmin()] if len(ok) else None
        answer = at[at["case"] == case]
        answer = answer.iloc[0] if len(answer) else None
        if answer is None or not answer["engine"]:
            cells = [answer["why_none"] if answer is not None and answer["why_none"] else "-", "-", "-"]
        else:
            cells = [f"{_answer_name(answer)} {answer_setting(answer)} ({answer['source']})", _num(answer["error"]),
                     _num(answer["us_per_sim_s"], ".3g")]
        rows.append([case, "-" if best is None else _run_name(best),
                     "-" if best is None else _num(best["attitude_err"]), *cells])
    return _md_table(["case", "most accurate fixed-step run", "att_err",
                      f"answer for att_err <= {SUMMARY_ACCURACY:g} (What to use)", "its att_err", "µs/s"],
                     rows) + [""]


def _answer_name(row) -> str:
    return " ".join(x for x in (row["engine"], row["integrator"]) if x) + (
        f" ({row['formulation']})" if row["formulation"] else "")


@sections.register("summary", 20)
def _summary(context: sections.Context) -> list[str]:
    from ..analysis import answers

    df = context.results
    counts = df["status"].value_counts()
    failed = failed_integrators(read_verdicts(context.out_dir) or [])
    return ["## Summary", "", f"{plural(len(df), 'run')} over {plural(df['case'].nunique(), 'case')}: "
            + ", ".join(f"{counts.get(s, 0)} {s}" for s in ("ok", "diverged", "failed", "skipped")), "",
            *summary_lines(df, failed, answers.read(context.out_dir, failed))]


@sections.register("oracle-and-theory-checks", 80)
def _checks(context: sections.Context) -> list[str]:
    return checks_lines(context.results, context.out_dir)


def figure_sections(df: pd.DataFrame, series: dict[tuple, dict], has_store: bool,
                    ladder: pd.DataFrame | None = None, tolerance: pd.DataFrame | None = None,
                    draw: bool = True, render_map: Callable | None = None) -> tuple[dict[str, list[str]], dict]:
    """Each case's figures as report lines {case: lines} (work–precision, then invariants against time), and the
    figures {relative path: PNG bytes}; the points of the dt ladders (ladder.csv) and of the tolerance ladders
    (tolerance.csv, harness.analysis.workprecision) join their case's work–precision plot. The tolerance figures are
    tolerance_figures'. With draw False (--no-figures) each case gets one line saying so. render_map: _render_all's."""
    if not draw:
        return {case: [NOT_DRAWN, ""] for case in dict.fromkeys(df["case"])}, {}
    images: dict[str, bytes] = {}
    tasks = []
    for case, group in df.groupby("case", sort=False):
        tasks.append(("work-precision", case, _with_tolerance(_with_ladder(group, ladder, case), tolerance, case),
                      None))
        tasks.append(("invariants", case, group, {k: v for k, v in series.items() if k[0] == case}))
    missing = {"work-precision": "No work–precision figure: no run of this case has both a finite error and a "
                                 "timing.",
               "invariants": "No invariants figure: no stored series for this case." if has_store else
               "No invariants figure: no stored series in this folder (DIR/runs.json and DIR/store/ are written by "
               "`stereodyn run`)."}
    lines: dict[str, list[str]] = {}
    for (kind, case, group, _), png in zip(tasks, _render_all(tasks, render_map)):
        if png is None:
            lines.setdefault(case, []).extend([missing[kind], ""])
            continue
        path = f"{FIGURES_DIR}/{figure_stem(case)}-{kind}.png"
        images[path] = png
        lines.setdefault(case, []).extend([f"![{case}: {kind.replace('-', '–')}]({path})", ""])
        if kind == "invariants":
            rows = figures.invariant_rows(group, series, case)
            lines[case].extend([f"Rows of the invariants figure: {'; '.join(rows)}.", ""])
    return lines, images


def figure_stem(case: str) -> str:
    """A figure's file name for a case: the case's own name where it is already a safe, short ASCII slug (the suite's
    are: free-asymmetric-invariants.png); else the slug bounded to 40 characters and a hash of the whole name, so two
    names never share a file (the slug alone maps every non-ASCII name to "")."""
    stem = html.slug(str(case))[:40].strip("-")
    if stem == case:
        return stem
    digest = hashlib.sha256(str(case).encode("utf-8", "surrogatepass")).hexdigest()[:8]
    return f"{stem}-{digest}" if stem else digest


def _render(task: tuple) -> bytes | None:
    kind, case, group, series = task
    if kind == "tolerance":
        return figures.tolerance(group, case)
    return figures.work_precision(group, case) if kind == "work-precision" else figures.invariants(group, series, case)


def tolerance_figures(tolerance: pd.DataFrame | None, draw: bool = True,
                      render_map: Callable | None = None) -> tuple[dict[str, str], dict[str, bytes]]:
    """The tolerance-against-error figure of each case with tolerance ladders (tolerance.csv): ({case: relative
    path}, {relative path: PNG bytes}). render_map: _render_all's."""
    if tolerance is None or tolerance.empty or not draw:
        return {}, {}
    cases = list(dict.fromkeys(tolerance["case"]))
    paths, images = {}, {}
    for case, png in zip(cases, _render_all([("tolerance", case, tolerance, None) for case in cases], render_map)):
        if png is not None:
            paths[case] = f"{FIGURES_DIR}/{figure_stem(case)}-tolerance.png"
            images[paths[case]] = png
    return paths, images


def _render_all(tasks: list[tuple], render_map: Callable | None = None) -> list[bytes | None]:
    """The figures' PNGs, on all cores when there are many: drawing is most of a report's time (1-3 s a figure here).
    render_map(fn, tasks) -> [fn(task), ...] in order: processes already started and imported where the caller has
    some (`stereodyn run`'s worker pool); else this process's own, spawned here."""
    if render_map is not None and len(tasks) > 1:
        try:
            return list(render_map(_render, tasks))
        except Exception as exc:  # a worker died under a figure (the memory killer, a crash at its exit): the report
            raise_unless_data(exc)  # is not lost for it; our own bug in drawing is raised (harness.errors)
            print(f"stereodyn: warning: a worker drawing the figures failed ({type(exc).__name__}: {exc}); drawing "
                  "them in this process", file=sys.stderr)
            return [_render(task) for task in tasks]
    workers = min(os.cpu_count() or 1, len(tasks) // PARALLEL_FIGURES)
    if workers < 2:
        return [_render(task) for task in tasks]
    # spawn, not fork: the caller may hold heyoka's LLVM state and threads (a report at the end of a sweep).
    with ProcessPoolExecutor(workers, mp_context=multiprocessing.get_context("spawn"),
                             initializer=exit_with_parent) as pool:
        return list(pool.map(_render, tasks))


def _with_ladder(group: pd.DataFrame, ladder: pd.DataFrame | None, case: str) -> pd.DataFrame:
    """A case's rows and its ladder points (same columns where they overlap), for the work–precision plot."""
    if ladder is None or ladder.empty:
        return group
    points = ladder[ladder["case"] == case]
    return pd.concat([group, points[[c for c in points.columns if c in group.columns]]], ignore_index=True) \
        if len(points) else group


def _with_tolerance(group: pd.DataFrame, tolerance: pd.DataFrame | None, case: str) -> pd.DataFrame:
    """A case's rows with its tolerance-ladder points, for the work–precision plot: a method with a ladder is drawn
    along its tolerances, so the sweep's row of it (the default tolerance, a point of the same curve) is left out."""
    if tolerance is None or tolerance.empty:
        return group
    points = tolerance[tolerance["case"] == case]
    if points.empty:
        return group
    laddered = {(e, f, i) for e, f, i in zip(points["engine"], points["formulation"], points["integrator"])}
    keys = zip(group["engine"], group["formulation"].fillna(""), group["integrator"])
    adaptive_row = group["dt"].isna().to_numpy() & np.array([k in laddered for k in keys], dtype=bool)
    return pd.concat([group[~adaptive_row], points[[c for c in points.columns if c in group.columns or
                                                     c == "tolerance"]]], ignore_index=True)


def checks_lines(df: pd.DataFrame, out_dir: Path) -> list[str]:
    """Oracle and theory checks: checks.csv when present, and the truth against the exact solutions."""
    lines = ["## Oracle and theory checks", ""]
    checks_path = Path(out_dir) / "checks.csv"
    if checks_path.exists():  # a FIFO is refused by read_csv_table, not skipped
        checks = read_csv_table(checks_path, dtype={"formulation": str}, keep_default_na=True)
        missing = [c for c in CHECKS_COLUMNS if c not in checks]
        if not missing and checks.empty:
            lines += ["checks.csv has no rows: no case of this sweep has a check against theory.", ""]
        elif not missing:  # one row per case and quantity: checks.csv has one per run, hundreds in the default suite
            header, rows = theory_checks.summary_rows(checks.fillna({"formulation": ""}))
            lines += [f"From checks.csv ({len(checks)} rows, one per run and quantity): a quantity measured from each "
                      "run's trajectory against theory; error is relative, or absolute where theory is 0, or the "
                      "angle (rad) for a phase. The truth is engine reference, quaternion, taylor.", "",
                      *_md_table(header, rows), ""]
        else:
            lines += [f"checks.csv lacks the columns {', '.join(missing)} (DESIGN §4); shown as it is.", ""]
            shown = [c for c in CHECKS_COLUMNS if c in checks] or list(checks.columns)
            rows = []
            for _, row in checks.iterrows():
                cells = []
                for column in shown:
                    value = row[column]
                    if column in ("theory", "measured"):
                        cells.append(_num(value, ".8g"))
                    elif column == "error":
                        cells.append(_num(value))
                    elif column == "dt":
                        cells.append(figures.dt_key(value))
                    else:
                        cells.append("" if isinstance(value, float) and math.isnan(value) else str(value))
                rows.append(cells)
            lines += [f"From checks.csv ({len(checks)} rows): a measured quantity against theory.", "",
                      *_md_table(shown, rows), ""]
    oracle = df[np.isfinite(df["oracle_err"])] if "oracle_err" in df else df.iloc[:0]
    if len(oracle):
        header, rows = theory_checks.oracle_rows(df.fillna({"formulation": ""}))
        lines += ["Runs against the case's exact solution (oracle_err: max attitude angle, rad, up to the case's "
                  "horizon; the truth's is DESIGN §4's oracle_err):", "", *_md_table(header, rows), ""]
    if not checks_path.is_file() and not len(oracle):
        lines += ["No checks.csv in this folder, and no run measured oracle_err (no case names an exact solution).",
                  ""]
    return lines


def _series_index(out_dir: Path) -> dict[tuple, dict]:
    index = {}
    for record in read_records(out_dir):
        row, values = record["row"], record.get("series")
        if values:
            index[(row["case"], row["engine"], row.get("formulation", "") or "", row["integrator"],
                   figures.dt_key(row.get("dt")))] = values
    return index


def write_reports(out_dir: Path, df: pd.DataFrame | None = None, self_contained: bool = False,
                  figures: bool = True, render_map: Callable | None = None) -> tuple[Path, Path]:
    """Write DIR/report.md, DIR/figures/*.png and DIR/report.html from the folder's results; return the two pages.
    report.html links the figures in DIR/figures/ (readable at 96 dpi, the ~55 figures of the default run would make a
    self-contained page of over 3 MB); self_contained embeds them instead (one file to send). figures False
    (--no-figures) draws none: the tables only, and no figure of an earlier render is left behind. render_map: where
    the figures are drawn (_render_all)."""
    out_dir = Path(out_dir)
    df = read_results(out_dir / "results.csv") if df is None else df
    manifest = read_manifest(out_dir)
    series = _series_index(out_dir)
    tolerance = workprecision.read_optional(out_dir / workprecision.TOLERANCE_FILE, workprecision.TEXT_COLUMNS)
    case_extras, images = figure_sections(df, series, manifest is not None,
                                          workprecision.read_optional(out_dir / workprecision.LADDER_FILE), tolerance,
                                          draw=figures, render_map=render_map)
    tolerance_paths, tolerance_images = tolerance_figures(tolerance, draw=figures, render_map=render_map)
    images.update(tolerance_images)
    env = dict(manifest["environment"]) if manifest and manifest.get("environment") else None
    if env is not None:
        env["report rendered"] = datetime.datetime.now().astimezone().isoformat(timespec="seconds")
    markdown = sections.render(sections.Context(out_dir, df, series, env, case_extras, tolerance_paths))
    figures_dir = out_dir / FIGURES_DIR
    figures_dir.mkdir(exist_ok=True)
    for path, png in images.items():
        write_atomic(out_dir / path, png)
    for stale in figures_dir.glob("*.png"):  # figures of cases no longer in results.csv: only names the report
        if stale.name.endswith(FIGURE_KINDS) and f"{FIGURES_DIR}/{stale.name}" not in images:  # writes (a user's
            stale.unlink()  # plot.png, compare's and history's figures stay)
    md_path, html_path = out_dir / "report.md", out_dir / "report.html"
    write_atomic(md_path, markdown)
    write_atomic(html_path, html.render(markdown, images, out_dir, embed=self_contained))
    index.write(out_dir)  # last: it lists what the folder holds now
    return md_path, html_path
