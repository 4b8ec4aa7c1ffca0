"""Issue 49's measured curve: the quick suite (.ci/run's, without figures) on a Dask LocalCluster of 1, 2 and 4
single-threaded worker processes, its wall time and parallel efficiency at each. A script run by hand, not a test.

    python tests/benchmarks/bench_dask_curve.py [--workers 1,2,4] [--rounds 1]

efficiency(n) = T(1) / (n * T(n)), with T the best wall time of `stereodyn run --scheduler` over the rounds (the
rounds alternate the worker counts, so that a slow period of the machine does not land on one count only). Each
cluster is started before the clock starts and closed after it stops. A count above this machine's cores is
oversubscribed: its workers share cores, its timings queue for a free core (timing.on_a_free_core), and its
efficiency measures that, not the scaling; it is printed so. Measure on an idle machine (print `uptime` beside it).
"""
from __future__ import annotations

import argparse
import math
import os
import sys
import tempfile
import time
from pathlib import Path

from distributed import LocalCluster

from stereodyn.harness import cli
from stereodyn.harness.cli.matrix import QUICK


def wall_time(workers: int, out: Path) -> float:
    """Seconds of one quick-suite `stereodyn run` on a fresh LocalCluster of `workers` processes."""
    with LocalCluster(n_workers=workers, threads_per_worker=1, processes=True, dashboard_address=None) as cluster:
        start = time.perf_counter()
        code = cli.main(["run", *QUICK, "--quiet", "--no-figures", "--scheduler", cluster.scheduler_address,
                         "--out", str(out)])
        seconds = time.perf_counter() - start
    if code != 0:
        sys.exit(f"stereodyn run on {workers} workers exited {code}")
    return seconds


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--workers", default="1,2,4", help="comma-separated worker counts (default 1,2,4)")
    parser.add_argument("--rounds", type=int, default=1, help="alternating rounds; the best of each count is kept")
    args = parser.parse_args()
    counts = [int(n) for n in args.workers.split(",")]
    cores = len(os.sched_getaffinity(0)) if hasattr(os, "sched_getaffinity") else os.cpu_count() or 1
    best = {n: math.inf for n in counts}
    with tempfile.TemporaryDirectory() as scratch:
        os.chdir(scratch)  # MuJoCo writes MUJOCO_LOG.TXT into the working directory on a warning
        for round_ in range(args.rounds):
            for n in counts:
                best[n] = min(best[n], wall_time(n, Path(scratch) / f"quick-{n}-{round_}"))
    load = os.getloadavg() if hasattr(os, "getloadavg") else (math.nan,) * 3
    print(f"# quick suite on a Dask LocalCluster, {cores} cores, load average {load[0]:.2f} {load[1]:.2f} "
          f"{load[2]:.2f} at the end, best of {args.rounds} round(s)")
    base = best.get(1)
    for n in counts:
        efficiency = base / (n * best[n]) if base is not None else math.nan
        note = f"  (oversubscribed: {n} workers on {cores} cores)" if n > cores else ""
        print(f"workers {n}  wall_s {best[n]:.1f}  efficiency {efficiency:.3f}{note}")


if __name__ == "__main__":
    main()
