"""What issue 14's adaptive methods add to the default run (`stereodyn run` with no arguments), in seconds.

    python tests/benchmarks/bench_adaptive.py [--jobs N]

adaptive_sweep_s      the default sweep's scipy rows (default_run: scipy_rk45, scipy_dop853, scipy_lsoda on the
                      quaternion formulation of every rigid-body case): each row's accuracy run, metrics and checks
                      (harness.run.sweep.execute), then their timing phase (time_specs), all in this process: an upper
                      bound, since the default run spreads the accuracy runs over its workers.
tolerance_ladders_s   the default tolerance ladders (free-asymmetric, heavy-asymmetric; every adaptive method of every
                      engine, DEFAULT_TOLERANCES): accuracy runs on N workers, then the timing phase here.
added_s               their sum.                                                              target <= 90 on an
                      idle 2-core machine (the default run took 4 min 57 s there before issue 14)
The truths are computed first and not counted (the sweep computes them anyway).
"""
from __future__ import annotations

import argparse
import time


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--jobs", type=int, default=2, help="workers of the tolerance ladders' accuracy runs")
    args = parser.parse_args()

    from stereodyn.harness.run import sweep as runner
    from stereodyn.harness.scenes.rigid_body import compute_truth
    from stereodyn.harness.pipeline import tolerance_ladders
    from stereodyn.harness.analysis import ladders, workprecision
    from stereodyn.harness.scenes.cases import load_suite
    from stereodyn.harness.engines import engine_names
    from stereodyn.harness.integrators import scipy_ivp
    from stereodyn.harness.run.plan import plan

    cases = [case for case in load_suite() if case.kind == "rigid_body"]
    specs = [s for s in plan(cases, list(engine_names()), None)[0] if s.integrator in scipy_ivp.METHODS]
    truths = {case.name: compute_truth(case, case.dt, certify=False) for case in cases}
    start = time.perf_counter()
    rows = [runner.execute(spec, truths[spec.case.name]) for spec in specs]
    runner.time_specs(specs, [row.get("steps", float("nan")) for row in rows])
    sweep_s = time.perf_counter() - start

    laddered = [case for case in cases if case.name in workprecision.DEFAULT_LADDER]
    families = ladders.adaptive_families(laddered, list(engine_names()), None,
                                          workprecision.DEFAULT_LADDER_FORMULATIONS)
    start = time.perf_counter()
    with runner.worker_pool(args.jobs) as pool:
        tolerance_ladders.run_ladders(families, pool, tolerances=tolerance_ladders.DEFAULT_TOLERANCES)
    ladders_s = time.perf_counter() - start
    print(f"adaptive_sweep_s {sweep_s:.1f}  ({len(specs)} rows)")
    print(f"tolerance_ladders_s {ladders_s:.1f}  ({len(families)} ladders)")
    print(f"added_s {sweep_s + ladders_s:.1f}  target <= 90 (idle 2-core machine)")


if __name__ == "__main__":
    main()
