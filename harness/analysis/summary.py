"""The answers at a glance: what `stereodyn run` prints by default, and the grouped reasons the report shows.

The terminal summary is short by design (issue 15): counts, the verdicts, the runs that did not finish grouped by
reason, the cheapest run for a few accuracy targets, and where the report is. The drift tables are `--verbose`.
"""
from __future__ import annotations

from pathlib import Path

import numpy as np
import pandas as pd

from .text import grouped_reasons, reason  # noqa: F401 (reason: part of this API)

# Accuracy targets (max attitude error, rad) of the terminal's "cheapest run" lines: three decades of pareto.csv's.
TERMINAL_TARGETS = (1e-3, 1e-6, 1e-9)
# Reasons listed in the terminal before "... and N more reasons": keeps the default suite's summary under 80 lines.
TERMINAL_REASONS = 8
# Failed verdicts listed before "... and N more" (all of them are in verdicts.csv and the report).
TERMINAL_VERDICTS = 20


def cheapest_lines(out_dir: Path, targets=TERMINAL_TARGETS) -> list[str]:
    """Per engine scope of pareto.csv, then `any` (every run): per accuracy target, on how many cases some run of the
    scope reaches it, the run named most often, and the case whose cheapest run is dearest (the target's worst case);
    where no case is reached, why (pareto.csv's `source`)."""
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
            counts = hit.apply(name, axis=1).value_counts(sort=False)
            best = counts.idxmax()
            dearest = hit.loc[hit["us_per_sim_s"].idxmax()]
            lines.append(f"{head}<= {target:.0e}: {len(hit)}/{cases} cases, most often {best} ({counts[best]}); "
                         f"dearest {dearest['case']}: {name(dearest)} {setting(dearest)} "
                         f"({dearest['us_per_sim_s']:.3g} µs/s)")
    return lines


def _method(row) -> str:
    return " ".join(str(row[c]) for c in ("engine", "formulation", "integrator") if isinstance(row[c], str) and row[c])


def _own_method(row) -> str:
    """A run named within its engine's scope: formulation and integrator."""
    return " ".join(str(row[c]) for c in ("formulation", "integrator") if isinstance(row[c], str) and row[c])


def terminal_lines(df: pd.DataFrame, found: list, out_dir: Path, report: Path | None = None) -> list[str]:
    """The default output of `stereodyn run`."""
    from . import verdicts

    counts = df["status"].value_counts()
    lines = [f"{len(df)} runs over {df['case'].nunique()} cases: "
             + ", ".join(f"{counts.get(s, 0)} {s}" for s in ("ok", "diverged", "failed", "skipped"))]
    verdict_lines = verdicts.summary_lines(found)
    lines += verdict_lines[:1 + TERMINAL_VERDICTS]
    if len(verdict_lines) > 1 + TERMINAL_VERDICTS:
        lines.append(f"... and {len(verdict_lines) - 1 - TERMINAL_VERDICTS} more failed verdicts: verdicts.csv")
    entries = grouped_reasons(df)
    if entries:
        lines.append("did not complete, by reason (numbers elided; every run in results.csv):")
        for entry in entries[:TERMINAL_REASONS]:
            more = f", +{entry['count'] - 1}" if entry["count"] > 1 else ""
            lines.append(f"  {entry['count']:4d} {entry['status']}: {entry['reason']} ({entry['runs'][0]}{more})")
        if len(entries) > TERMINAL_REASONS:
            rest = entries[TERMINAL_REASONS:]
            lines.append(f"  ... and {len(rest)} more reasons ({sum(e['count'] for e in rest)} runs): "
                         "report.md, Runs that did not complete")
    lines += cheapest_lines(out_dir)
    if report is not None:
        lines.append(f"report: {report}  (drift tables: --verbose, or report.md)")
    return lines
