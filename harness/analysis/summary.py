"""The answers at a glance: what `stereodyn run` prints by default, and the grouped reasons the report shows.

The terminal summary is short by design (issue 15): counts, the verdicts, the runs that did not finish grouped by
reason, the cheapest run for a few accuracy targets, and where the report is. The drift tables are `--verbose`.
"""
from __future__ import annotations

import re
from pathlib import Path

import numpy as np
import pandas as pd

from ..words import plural
from .text import grouped_reasons, reason  # noqa: F401 (reason: part of this API)

# Accuracy targets (max attitude error, rad) of the terminal's "cheapest run" lines: three decades of pareto.csv's.
TERMINAL_TARGETS = (1e-3, 1e-6, 1e-9)
# Reasons listed in the terminal before "... and N more reasons": keeps the default suite's summary under 80 lines.
TERMINAL_REASONS = 8
# Failed verdicts listed before "... and N more" (all of them are in verdicts.csv and the report).
TERMINAL_VERDICTS = 20


def cheapest_lines(out_dir: Path, targets=TERMINAL_TARGETS) -> list[str]:
    """Per engine scope of the answers (analysis.answers, the report's), then `any` (every run): per accuracy target,
    on how many cases some run of the scope reaches it, the run named most often with the steps (or tolerances) it
    reached it at, and the case whose answer is the most expensive (the target's worst case); where no case is
    reached, why."""
    from . import answers
    from .pareto import ANY, scope_rows, scopes, setting

    # the report's one answer per case, engine and target (What to use, Step-size advice, Summary), not a fourth
    table = answers.read(Path(out_dir))
    if table is None or table.empty:
        return []
    table = table.assign(source=table["why_none"])  # why a cell has no answer, in pareto.csv's words
    lines = ["cheapest run reaching an accuracy (max attitude error), per engine and over all (report: What to use):"]
    cases = table["case"].nunique()
    for scope in [*scopes(table), ANY]:
        rows = scope_rows(table, scope)
        name = _method if scope == ANY else _own_method
        for k, target in enumerate(targets):
            head = f"  {scope:10s} " if k == 0 else " " * 13
            # atol 0: np.isclose's default 1e-8 would take 1e-9 .. 1e-12 for one target
            at = rows[np.isclose(rows["target"], target, rtol=1e-9, atol=0.0)]
            hit = at[at["engine"] != ""].drop_duplicates("case")
            if hit.empty:
                why = at["source"].value_counts() if "source" in at else pd.Series(dtype=int)
                lines.append(f"{head}<= {target:.0e}: no case" + (" (" + ", ".join(
                    f"{reason}: {count}" for reason, count in why.items()) + ")" if len(why) else ""))
                continue
            names = hit.apply(name, axis=1)
            counts = names.value_counts(sort=False)
            best = counts.idxmax()
            worst = hit.loc[hit["us_per_sim_s"].idxmax()]
            lines.append(f"{head}<= {target:.0e}: {len(hit)}/{cases} cases, most often {best} "
                         f"{_settings(hit[names == best])} ({counts[best]}); most expensive {worst['case']}: "
                         f"{name(worst)} {setting(worst)} ({worst['us_per_sim_s']:.3g} µs/s)")
    return lines


def _settings(rows: pd.DataFrame) -> str:
    """The steps (or tolerances) of one method's answers: 'dt=0.01', 'dt=0.0025..0.01', 'tol=1e-10..1e-06', or
    'default tol'."""
    for column, label, spec in (("dt", "dt", ".3g"), ("tolerance", "tol", ".0e")):
        values = pd.to_numeric(rows[column], errors="coerce").dropna() if column in rows else pd.Series(dtype=float)
        if len(values):
            low, high = format(values.min(), spec), format(values.max(), spec)
            return f"{label}={low}" if low == high else f"{label}={low}..{high}"
    return "default tol"


def _method(row) -> str:
    return " ".join(str(row[c]) for c in ("engine", "formulation", "integrator") if isinstance(row[c], str) and row[c])


def _own_method(row) -> str:
    """A run named within its engine's scope: formulation and integrator."""
    return " ".join(str(row[c]) for c in ("formulation", "integrator") if isinstance(row[c], str) and row[c])


# The reason of a run skipped because its engine's SDK is not installed (harness.engines: UnavailableEngine's message)
_NOT_INSTALLED = re.compile(r"^(\S+) engine unavailable: No module named")


def not_installed(df: pd.DataFrame) -> list[str]:
    """The engines whose runs were skipped because their SDK is not installed, in table order."""
    skipped = df[df["status"] == "skipped"]
    found = (_NOT_INSTALLED.match(m) for m in skipped.get("message", pd.Series(dtype=object)) if isinstance(m, str))
    return list(dict.fromkeys(match.group(1) for match in found if match))


def terminal_lines(df: pd.DataFrame, found: list, out_dir: Path, report: Path | None = None,
                   elapsed_s: float | None = None) -> list[str]:
    """The default output of `stereodyn run`: the runs of engines not installed are one line, apart from the runs
    that did not complete."""
    from .. import install
    from . import verdicts

    missing = not_installed(df)
    absent = df["engine"].isin(missing) & (df["status"] == "skipped")
    ran = df[~absent]
    counts = ran["status"].value_counts()
    lines = [f"{plural(len(ran), 'run')} over {plural(ran['case'].nunique(), 'case')}: "
             + ", ".join(f"{counts.get(s, 0)} {s}" for s in ("ok", "diverged", "failed", "skipped"))
             + (f"; in {_clock(elapsed_s)}" if elapsed_s is not None else "")]
    if missing:
        hint = install.hint(missing[0] if len(missing) == 1 else "engines")
        lines.append(f"not installed: {', '.join(missing)} ({plural(int(absent.sum()), 'run')} not run) — {hint}")
    verdict_lines = verdicts.summary_lines(found)
    lines += verdict_lines[:1 + TERMINAL_VERDICTS]
    if len(verdict_lines) > 1 + TERMINAL_VERDICTS:
        lines.append(f"... and {plural(len(verdict_lines) - 1 - TERMINAL_VERDICTS, 'more failed verdict')}: "
                     "verdicts.csv")
    entries = grouped_reasons(ran)
    if entries:
        lines.append("did not complete, by reason (the first run's message; every run in results.csv):")
        for entry in entries[:TERMINAL_REASONS]:
            more = f"; {entry['count'] - 1} more like it" if entry["count"] > 1 else ""
            lines.append(f"  {entry['count']:4d} {entry['status']}: {entry['example']} ({entry['runs'][0]}{more})")
        if len(entries) > TERMINAL_REASONS:
            rest = entries[TERMINAL_REASONS:]
            lines.append(f"  ... and {plural(len(rest), 'more reason')} "
                         f"({plural(sum(e['count'] for e in rest), 'run')}): report.md, Runs that did not complete")
    lines += cheapest_lines(out_dir)
    if report is not None:
        lines.append(f"report: {report}  (drift tables: --verbose, or report.md)")
    return lines


def _clock(seconds: float) -> str:
    """An elapsed time as a person reads it: '48 s', '3 min 12 s', '1 h 02 min'."""
    seconds = int(round(seconds))
    if seconds < 60:
        return f"{seconds} s"
    if seconds < 3600:
        return f"{seconds // 60} min {seconds % 60:02d} s"
    return f"{seconds // 3600} h {seconds % 3600 // 60:02d} min"
