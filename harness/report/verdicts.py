"""The report's "Verdicts" section, from DIR/verdicts.csv (harness.analysis.verdicts)."""
from __future__ import annotations

from pathlib import Path

from ..analysis.verdicts import FAIL, FIXED, KNOWN, NO_REASON, NOT_ENOUGH, UNMEASURED, read, summary_lines
from . import sections
from .markdown import markdown_table


def report_lines(out_dir: Path) -> list[str]:
    """The section's lines (empty without verdicts.csv)."""
    verdicts = read(out_dir)
    if verdicts is None:
        return []
    lines = ["## Verdicts", "", summary_lines(verdicts)[0] + ". Failed verdicts come first, then claims nothing "
             f"measured and no reason excuses, then misses found on too few points (`{NOT_ENOUGH}`), then known "
             "engine deviations "
             f"(`{KNOWN}`: declared by the engine with their upstream reference, not failures) and those "
             f"that stopped matching (`{FIXED}`); each row states its rule.", ""]
    ordered = sorted(verdicts, key=lambda v: (v.status != FAIL, v.status != NO_REASON, v.status != NOT_ENOUGH,
                                              v.status != FIXED, v.status != KNOWN, v.status != UNMEASURED))
    shown = {FAIL: "**FAIL**", NO_REASON: "**not measured, no reason**"}
    if ordered:
        rows = [[shown.get(v.status, v.status), v.verdict, v.subject, v.detail, v.rule] for v in ordered]
        lines += markdown_table(["status", "verdict", "subject", "finding", "rule"], rows) + [""]
    return lines


@sections.register("verdicts", 10)
def _verdicts(context: sections.Context) -> list[str]:
    return report_lines(context.out_dir)
