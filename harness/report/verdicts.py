"""The report's "Verdicts" section, from DIR/verdicts.csv (harness.analysis.verdicts): what did not pass first, in
full; the passes folded into one line per claim kind (the rows in a <details>); each rule stated once."""
from __future__ import annotations

from pathlib import Path

from ..analysis.verdicts import (FAIL, FIXED, KNOWN, NO_REASON, NOT_ASYMPTOTIC, NOT_ENOUGH, PASS, UNMEASURED,
                                 read, summary_lines)
from . import sections
from .markdown import markdown_table

ORDER = (FAIL, NO_REASON, NOT_ENOUGH, NOT_ASYMPTOTIC, FIXED, KNOWN, UNMEASURED)


def report_lines(out_dir: Path) -> list[str]:
    """The section's lines (empty without verdicts.csv)."""
    verdicts = read(out_dir)
    if verdicts is None:
        return []
    lines = ["## Verdicts", "", summary_lines(verdicts)[0] + ". Failed verdicts come first, then claims nothing "
             f"measured and no reason excuses, then misses found on too few points (`{NOT_ENOUGH}`), then claims "
             f"whose local slopes still move toward the declared order at the finest dt (`{NOT_ASYMPTOTIC}`), then "
             "known engine deviations "
             f"(`{KNOWN}`: declared by the engine with their upstream reference, not failures) and those "
             f"that stopped matching (`{FIXED}`); the passes follow, one line per kind of claim (open it for its "
             "rows); the rules are stated once, below.", ""]
    rank = {status: k for k, status in enumerate(ORDER)}
    open_rows = sorted((v for v in verdicts if v.status != PASS), key=lambda v: rank.get(v.status, len(ORDER)))
    shown = {FAIL: "**FAIL**", NO_REASON: "**not measured, no reason**"}
    if open_rows:
        rows = [[shown.get(v.status, v.status), v.verdict, v.subject, v.detail] for v in open_rows]
        lines += markdown_table(["status", "verdict", "subject", "finding"], rows) + [""]
    passes: dict[str, list] = {}
    for v in verdicts:
        if v.status == PASS:
            passes.setdefault(v.verdict, []).append(v)
    for kind, group in passes.items():
        subjects = "integrators" if all(v.integrator for v in group) else "cases" if not any(
            v.integrator for v in group) else "subjects"
        lines += [f"<details><summary>{kind}: {len(group)} {subjects} passed</summary>", "",
                  *markdown_table(["subject", "finding"], [[v.subject, v.detail] for v in group]), "", "</details>",
                  ""]
    rules: dict[str, list[str]] = {}
    for v in verdicts:
        if v.rule and v.rule not in rules.setdefault(v.verdict, []):
            rules[v.verdict].append(v.rule)
    if rules:
        lines += ["Rules:", ""] + [f"- {kind}: {rule}" for kind, texts in rules.items() for rule in texts] + [""]
    return lines


@sections.register("verdicts", 10)
def _verdicts(context: sections.Context) -> list[str]:
    return report_lines(context.out_dir)
