"""The drift table in the terminal and report.md."""
from __future__ import annotations

import datetime
import platform
from importlib import metadata
from pathlib import Path

import numpy as np
import pandas as pd

from harness.results import write_atomic

TERMINAL_COLUMNS = ("engine", "integrator", "dt", "status", "energy_drift", "momentum_drift", "casimir_drift",
                    "lagrange_drift", "kovalevskaya_drift", "chaplygin_drift", "hess_drift", "attitude_err",
                    "omega_err", "truth_err", "us_per_step")
SHORT = {"energy_drift": "energy", "momentum_drift": "momentum", "casimir_drift": "casimir",
         "lagrange_drift": "lagrange", "kovalevskaya_drift": "kovalevskaya", "chaplygin_drift": "chaplygin",
         "hess_drift": "hess", "attitude_err": "att_err", "omega_err": "omega_err", "us_per_step": "us/step"}

DEFINITIONS = """\
- *_drift: max over the samples of |I(t) - I(0)| / scale, scale = the sum of the absolute values of the integral's
  terms at t = 0 (for a vector or a dot product, the norms). energy: kinetic + potential of uniform gravity;
  momentum: the world angular momentum K about O for a torque-free body, its vertical component K.d under gravity;
  casimir: | |q|^2 - 1 | of the recorded quaternion (= ||H| - 1| for the heavy body); lagrange: omega along the
  symmetry axis; kovalevskaya: |(p1 + i p2)^2 + (m g / A3)(c1 + i c2)(H1 + i H2)|^2 with H the downward vertical in
  body axes; chaplygin: (p1^2 + p2^2) p3 + lambda^2 p1 H3; hess: K.k. A special integral is shown only on cases that
  meet its conditions (FORMULARY G5-G8), NaN elsewhere. Every integral is computed from the recorded states by the same
  code for every engine, never from an engine's own energy.
- attitude_err / attitude_err_end: max / final geodesic angle (rad) between the run's attitude and the truth's at the
  same times, up to the case's horizon; omega_err: max |omega - omega_truth| / max |omega_truth|.
- truth: engine reference, integrator taylor (heyoka, adaptive, tolerance 1e-16); truth_err is the largest angle
  between it and a quadruple-precision rerun (only with --certify).
- us_per_step: stepping time only, best of up to 3 timed runs after an untimed accuracy run (which is the warm-up),
  metrics off. Runs share the machine's cores (--jobs), so compare timings within one report."""


def _fmt(value, column: str) -> str:
    if isinstance(value, str):
        return value
    if value is None or (isinstance(value, float) and np.isnan(value)):
        return "" if column in ("dt",) else "-"
    if column == "dt":
        return f"{value:g}"
    if column == "us_per_step":
        return f"{value:.3g}"
    return f"{value:.2e}"


def _shown_columns(df: pd.DataFrame, columns: tuple[str, ...]) -> list[str]:
    """Drop numeric columns that are NaN on every row (integrals the case does not have)."""
    return [c for c in columns if c in ("engine", "integrator", "dt", "status") or df[c].notna().any()]


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


def _markdown_table(cells: list[list[str]]) -> str:
    lines = ["| " + " | ".join(cells[0]) + " |", "|" + "---|" * len(cells[0])]
    return "\n".join(lines + ["| " + " | ".join(row) + " |" for row in cells[1:]])


def environment() -> dict[str, str]:
    versions = {}
    for package in ("numpy", "scipy", "pandas", "mujoco", "pin", "heyoka", "stereodyn"):
        try:
            versions[package] = metadata.version(package)
        except metadata.PackageNotFoundError:
            versions[package] = "absent"
    return {"python": platform.python_version(), **versions, "machine": platform.machine(),
            "processor": platform.processor() or platform.machine(),
            "date": datetime.datetime.now().astimezone().isoformat(timespec="seconds")}


def report_markdown(df: pd.DataFrame) -> str:
    counts = df["status"].value_counts()
    lines = ["# stereodyn report", "",
             f"{len(df)} runs over {df['case'].nunique()} cases: "
             + ", ".join(f"{counts.get(s, 0)} {s}" for s in ("ok", "diverged", "failed", "skipped")), ""]
    problems = df[df["status"].isin(["failed", "skipped"])]
    if len(problems):
        lines += ["## Runs that did not complete", "",
                  _markdown_table(_table(problems, ["case", "engine", "integrator", "dt", "status", "message"])), ""]
    lines += ["## Drift tables", ""]
    columns = TERMINAL_COLUMNS[:-2] + ("attitude_err_end", "truth_err", "wall_s", "us_per_step")
    for case, group in df.groupby("case", sort=False):
        lines += [f"### {case}", "", _markdown_table(_table(group, _shown_columns(group, columns))), ""]
        diverged = group[group["status"] == "diverged"]
        for _, row in diverged.iterrows():
            lines.append(f"- {row['engine']} {row['integrator']} dt={row['dt']:g} diverged at t = "
                         f"{row['diverged_at']:.4g} s")
        if len(diverged):
            lines.append("")
    lines += ["## Definitions", "", DEFINITIONS, "", "## Environment", ""]
    lines += [f"- {key}: {value}" for key, value in environment().items()]
    return "\n".join(lines) + "\n"


def write_report(df: pd.DataFrame, out_dir: Path) -> Path:
    path = Path(out_dir) / "report.md"
    write_atomic(path, report_markdown(df))
    return path
