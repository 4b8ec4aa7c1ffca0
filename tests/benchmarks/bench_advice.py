"""What the checked step-size advice (advice.csv, issue 21 item 2) adds to the default run: the advice phase alone,
on a finished default run's tables (results.csv, ladder.csv, tolerance.csv, convergence.csv), on a pool of --jobs
workers, as pipeline.work_precision runs it.

    python tests/benchmarks/bench_advice.py reports/default [--jobs 2] [--targets 1e-3,1e-6,1e-9]

Prints the phase's wall time, the families and rows advised, the check runs made, and how many rows have a dt or
tolerance (the others say why). Run on an idle machine.
"""
from __future__ import annotations

import argparse
import time
from pathlib import Path

import numpy as np
import pandas as pd

from stereodyn.harness.analysis import workprecision
from stereodyn.harness.pipeline import advice as advising
from stereodyn.harness.pipeline.dt_ladders import families
from stereodyn.harness.analysis.fitting import tolerance_fits
from stereodyn.harness.run import sweep as runner
from stereodyn.harness.run.results import read_results
from stereodyn.harness.scenes import cases as case_files


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("run_dir", type=Path, help="a default run's output folder")
    parser.add_argument("--jobs", type=int, default=2)
    parser.add_argument("--targets", default=",".join(f"{t:g}" for t in workprecision.DEFAULT_ADVICE_TARGETS))
    args = parser.parse_args()
    results = read_results(args.run_dir / "results.csv")
    text = workprecision.TEXT_COLUMNS
    ladder = workprecision.read_optional(args.run_dir / workprecision.LADDER_FILE, text)
    tolerance = workprecision.read_optional(args.run_dir / workprecision.TOLERANCE_FILE, text)
    convergence = workprecision.read_optional(args.run_dir / workprecision.CONVERGENCE_FILE, ("formulation", "note",
                                                                                             "source"))
    suite = [c for c in case_files.load_suite() if c.name in workprecision.DEFAULT_LADDER]
    engines = [e for e in dict.fromkeys(results["engine"]) if e]
    chosen = [f for f in families(suite, engines, None, workprecision.DEFAULT_LADDER_FORMULATIONS)
              if f.integrator not in workprecision.DEFAULT_LADDER_SKIP]
    adaptive = workprecision.default_tolerance_families(suite, engines, None)
    tasks = advising.advice_tasks(chosen, adaptive, results, ladder[ladder["source"] == "ladder"], tolerance,
                                  convergence, tolerance_fits(tolerance))
    targets = tuple(float(t) for t in args.targets.split(","))
    with runner.worker_pool(args.jobs) as pool:
        start = time.perf_counter()
        table = advising.run_advice(tasks, targets, workprecision.DEFAULT_MAX_STEPS, pool)
        seconds = time.perf_counter() - start
    advised = np.isfinite(table["dt"]) | np.isfinite(table["tolerance"])
    print(f"advice: {seconds:.1f} s on {args.jobs} workers; {len(tasks)} families, {len(table)} rows, "
          f"{int(table['runs'].sum())} check runs, {int(advised.sum())} rows with a dt or tolerance")
    pd.set_option("display.width", 250)
    print(table[["case", "engine", "formulation", "integrator", "target", "dt", "tolerance", "error_checked",
                 "us_per_sim_s", "fails_at", "runs", "note"]].to_string())


if __name__ == "__main__":
    main()
