"""Issue 49's rule, measured: is a worker's core quiet enough to time a run while the other core times another run?

    python tests/benchmarks/bench_timing_cores.py [--rounds 7] [--phase-s 10 --phases 8]

A process pinned to core A times a run best of 3 (timing.measure, after a warm-up, as the timing phase does) in
rounds, alternately with core B idle and with core B busy running another run in a loop (a second process pinned to
core B: what a second worker timing its chunk does). Printed per run: the median over the rounds of its best of 3
with B idle and with B busy, and their ratio (busy / idle): 1.00 means the other core's timing does not reach this
one. With --phases, then the tail, which a median hides: each run timed once after the other, back to back, for
--phase-s seconds at a time, B idle and busy in turn; printed per run and state, each single time over the run's
fastest: the median, the 90th and 99th percentiles and the share beyond 1.15 (what moves a best of 3 between two
default runs). Needs two cores; measure on an idle machine (the load average is printed with it).
"""
from __future__ import annotations

import argparse
import multiprocessing
import os
import statistics
import sys
import tempfile
import time

from stereodyn.harness.run import timing
from stereodyn.harness.run.measure import prepare
from stereodyn.harness.run.plan import plan
from stereodyn.harness.scenes.cases import find_case, with_overrides

# what is timed on core A, and what the other core runs meanwhile: the quick suite's sizes (t_end 2, dt 3e-3)
TIMED = (("lagrange-top", "mujoco", "rk4"), ("lagrange-top", "pinocchio", "rk4"), ("lagrange-top", "reference", "rk4"))
BUSY = ("kovalevskaya", "pinocchio", "rk4")


def _spec(case: str, engine: str, integrator: str):
    specs, _ = plan([with_overrides(find_case(case), t_end=2.0, dt=[3e-3])], [engine], [integrator])
    return specs[0]


def _busy(core: int, start, stop) -> None:
    os.sched_setaffinity(0, {core})
    sim, grid = prepare(_spec(*BUSY))
    sim.run(grid)
    while True:
        start.wait()
        while not stop.is_set():
            sim.run(grid)
        start.clear()


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--rounds", type=int, default=7)
    parser.add_argument("--phases", type=int, default=0, help="tail phases, B idle and busy in turn (default: none)")
    parser.add_argument("--phase-s", type=float, default=10.0)
    args = parser.parse_args()
    cores = sorted(os.sched_getaffinity(0))
    if len(cores) < 2:
        sys.exit("needs two cores")
    mine, other = cores[0], cores[1]
    os.chdir(tempfile.mkdtemp())  # MuJoCo's log
    context = multiprocessing.get_context("spawn")
    start, stop = context.Event(), context.Event()
    busy = context.Process(target=_busy, args=(other, start, stop), daemon=True)
    busy.start()
    os.sched_setaffinity(0, {mine})
    runs = []
    for key in TIMED:
        sim, grid = prepare(_spec(*key))
        timing.warm_up(sim, grid, key[1])
        runs.append((key, lambda sim=sim, grid=grid: sim.run(grid)))
    best = {key: {"idle": [], "busy": []} for key, _ in runs}
    for _ in range(args.rounds):
        for state in ("idle", "busy"):
            if state == "busy":
                stop.clear()
                start.set()
            for key, run in runs:
                best[key][state].append(timing.measure(run, repeats=3, budget_s=0.0, min_repeats=3).best)
            stop.set()
    samples = _tail(runs, args.phases, args.phase_s, start, stop) if args.phases else {}
    busy.kill()
    load = os.getloadavg()
    print(f"# best of 3 on core {mine}, core {other} idle or running {' '.join(BUSY)} in a loop; median of "
          f"{args.rounds} rounds; load average {load[0]:.2f} {load[1]:.2f} {load[2]:.2f} at the end")
    for key, states in best.items():
        idle, loaded = statistics.median(states["idle"]), statistics.median(states["busy"])
        print(f"{' '.join(key):32s} idle {idle * 1e3:8.2f} ms  busy {loaded * 1e3:8.2f} ms  ratio {loaded / idle:.3f}")
    if samples:
        print(f"# tail: single times over each run's fastest, {args.phases} phases of {args.phase_s:g} s, B idle "
              "and busy in turn")
    for key, states in samples.items():
        fastest = min(min(times) for times in states.values())
        for state, times in states.items():
            ratios = sorted(t / fastest for t in times)
            at = lambda q: ratios[min(len(ratios) - 1, int(q * len(ratios)))]  # noqa: E731
            print(f"{' '.join(key):32s} {state:4s} n {len(ratios):5d}  median {at(0.5):.3f}  q90 {at(0.9):.3f}  "
                  f"q99 {at(0.99):.3f}  beyond 1.15 {sum(r > 1.15 for r in ratios) / len(ratios):.3f}")


def _tail(runs, phases: int, phase_s: float, start, stop) -> dict:
    """{run key: {"idle": [s, ...], "busy": [...]}}: single times, back to back, phase by phase."""
    samples = {key: {"idle": [], "busy": []} for key, _ in runs}
    for phase in range(phases):
        state = "busy" if phase % 2 else "idle"
        if state == "busy":
            stop.clear()
            start.set()
        end = time.perf_counter() + phase_s
        while time.perf_counter() < end:
            for key, run in runs:
                samples[key][state].append(timing.measure(run, repeats=1, budget_s=0.0, min_repeats=1).best)
        stop.set()
        time.sleep(0.2)  # B back in its wait
    return samples


if __name__ == "__main__":
    main()
