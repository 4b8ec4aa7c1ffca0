"""The report's "Cross-engine agreement" section, from DIR/agreement.csv (harness.analysis.agreement)."""
from __future__ import annotations

from ..analysis import agreement
from ..engines.methods import METHODS
from . import sections
from .markdown import markdown_table, number


@sections.register("cross-engine-agreement", 35)
def _agreement(context: sections.Context) -> list[str]:
    df = agreement.read(context.out_dir)
    if df is None or df.empty:
        return []
    table = agreement.summary(df)
    lines = ["## Cross-engine agreement", "",
             f"Runs of the same method at the same dt on a case, on two engines ({len(df)} pairs, `agreement.csv`): "
             "the largest state difference over the run (max of the attitude angle, rad, and the relative omega "
             "difference, up to the case's horizon), as errors are measured against the truth. Two engines running "
             "the same map agree to round-off; more is another map under the same name, other coordinates, or "
             "another precision. Methods: " + "; ".join(f"`{m}`: {METHODS[m]}" for m in dict.fromkeys(
                 table["method"]) if m in METHODS) + ".", ""]
    rows = [[row["method"], agreement.run_name(row["engine_b"], row["integrator_b"], row["precision_b"]),
             agreement.run_name(row["engine_a"], row["integrator_a"], row["precision_a"]), str(row["pairs"]),
             number(row["state_diff_max"]), row["at"], number(row["state_diff_median"])]
            for _, row in table.iterrows()]
    lines += markdown_table(["method", "run", "against", "case-dt pairs", "largest difference", "at",
                             "median"], rows) + [""]
    return lines
