"""What the short ladders (issue 13) add to the default run: its work–precision phase on a finished default run's
results.csv, with and without them, on the same pool.

    stereodyn run --out /tmp/default            # once, the default suite
    python tests/benchmarks/bench_short_ladders.py /tmp/default [--jobs 2]

Prints the phase's wall time both ways (default ladders only, then default and short ladders) and how many families
each gives an order. Target: the short ladders add <= 60 s on two cores. Run on an idle machine: the other helpers'
processes slow one of the two measurements and not the other.
"""
from __future__ import annotations

import argparse
import tempfile
import time
from pathlib import Path

import numpy as np
import pandas as pd

from stereodyn.harness.scenes import cases as case_files
from stereodyn.harness.run import sweep as runner
from stereodyn.harness.analysis import workprecision
from stereodyn.harness.pipeline import work_precision
from stereodyn.harness.run.results import read_results

ENGINES = ["mujoco", "pinocchio", "reference"]


def phase(results: pd.DataFrame, jobs: int, short: bool) -> tuple[float, pd.DataFrame]:
    suite = case_files.load_suite()
    chosen = workprecision.short_ladder_families
    if not short:
        workprecision.short_ladder_families = lambda *args, **kwargs: []
    try:
        with tempfile.TemporaryDirectory() as out, runner.worker_pool(jobs) as pool:
            start = time.perf_counter()
            work_precision.analyse(Path(out), results, suite, ENGINES, None, ladder="default", pool=pool)
            seconds = time.perf_counter() - start
            return seconds, pd.read_csv(Path(out) / workprecision.CONVERGENCE_FILE)
    finally:
        workprecision.short_ladder_families = chosen


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("run_dir", type=Path, help="a default run's output folder (its results.csv)")
    parser.add_argument("--jobs", type=int, default=2)
    args = parser.parse_args()
    results = read_results(args.run_dir / "results.csv")
    for short in (False, True):
        seconds, convergence = phase(results, args.jobs, short)
        fitted = int(np.isfinite(convergence["order"]).sum())
        print(f"{'with' if short else 'without'} short ladders: {seconds:.1f} s on {args.jobs} workers, "
              f"{fitted} of {len(convergence)} families fitted")


if __name__ == "__main__":
    main()
