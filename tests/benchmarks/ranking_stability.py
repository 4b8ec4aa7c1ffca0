"""How often two runs of the sweep name the same "What to use" winner (pareto.csv), cell by cell.

    stereodyn run --out A && stereodyn run --out B      # two consecutive default runs, machine otherwise idle
    python tests/benchmarks/ranking_stability.py A B

A cell is (case, scope, target) with a winner in both runs (scope: an engine, or "any"). It is `same` when both name the same run (engine, formulation,
integrator, dt); `tie` when they differ but either run lists the other's winner among its ties (the report marks the
cell "tie"); `differs` otherwise: a winner that moved with no mark, the case the tie rule must prevent. The acceptance
of issue 11 asks same >= 95 % and differs = 0.
"""
from __future__ import annotations

import argparse
import math
import sys
from pathlib import Path

import pandas as pd


def _run(row) -> str:
    """A winner's name as pareto.csv's `ties` spell it (harness.fitting: _candidate_name)."""
    parts = [row[c] for c in ("engine", "formulation", "integrator") if isinstance(row[c], str) and row[c]]
    dt, tol = float(row["dt"]), float(row.get("tolerance", math.nan))
    setting = f"dt={dt:.3g}" if math.isfinite(dt) else f"tol={tol:.0e}" if math.isfinite(tol) else "default tol"
    return " ".join(parts) + " " + setting


def _ties(row) -> set[str]:
    """The runs a pareto row lists as tied with its winner, named as _run names them."""
    ties = row["ties"] if isinstance(row["ties"], str) else ""
    return {entry.split(" (")[0].strip() for entry in ties.split(";") if entry.strip()}


def _cell(row) -> tuple:
    """(case, scope, target): pareto.csv has a winner per engine (scope = its name) and over all (scope "any")."""
    return row["case"], row.get("scope", "any"), float(row["target"])


def compare(a: pd.DataFrame, b: pd.DataFrame) -> dict[str, list[str]]:
    cells: dict[str, list[str]] = {"same": [], "tie": [], "differs": []}
    b_by_cell = {_cell(r): r for _, r in b.iterrows()}
    for _, ra in a.iterrows():
        rb = b_by_cell.get(_cell(ra))
        if rb is None or not (isinstance(ra["engine"], str) and ra["engine"]) \
                or not (isinstance(rb["engine"], str) and rb["engine"]):
            continue
        wa, wb = _run(ra), _run(rb)
        label = f"{ra['case']} {ra.get('scope', 'any')} {float(ra['target']):g}: {wa} " \
                f"({ra['us_per_sim_s']:.4g} µs/s) | {wb} ({rb['us_per_sim_s']:.4g} µs/s)"
        kind = "same" if wa == wb else "tie" if (wb in _ties(ra) or wa in _ties(rb)) else "differs"
        cells[kind].append(label)
    return cells


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("a", type=Path)
    parser.add_argument("b", type=Path)
    args = parser.parse_args(argv)
    read = lambda d: pd.read_csv(d / "pareto.csv", keep_default_na=False, na_values=[""])  # noqa: E731
    cells = compare(read(args.a), read(args.b))
    total = sum(len(v) for v in cells.values())
    for kind in ("tie", "differs"):
        for label in cells[kind]:
            print(f"{kind:8s}{label}")
    same = len(cells["same"]) / total if total else math.nan
    print(f"cells {total}: same winner {len(cells['same'])} ({same:.1%}), differing but tie-marked "
          f"{len(cells['tie'])}, differing unmarked {len(cells['differs'])}")
    return 0 if total and same >= 0.95 and not cells["differs"] else 1


if __name__ == "__main__":
    sys.exit(main())
