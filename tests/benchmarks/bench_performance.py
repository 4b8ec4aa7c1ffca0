"""The performance figures of issues 6 and 14, each a ratio measured side by side in one process, printed `name value`.

    python tests/benchmarks/bench_performance.py [--repeats N] [--quick] [--only FIGURE,...]

mujoco_overhead      MujocoEngine µs/step over a bare mujoco.rollout (worse of euler and rk4).        target <= 1.1
drake_overhead       DrakeEngine µs/step over a bare Simulator.AdvanceTo(t_end) with the same diagram, integrator and
                     fixed step (the worse of explicit_euler, runge_kutta3 and the discrete plant; needs the extra
                     stereodyn[drake], else printed as skipped).                                       target <= 1.1
pinocchio_overhead   PinocchioEngine rk4 µs/step over a bare Python RKMK4 loop (bench_overhead.py).   target <= 1.2
pinocchio_vs_native  PinocchioEngine rk4 µs per state-step of an ensemble of 1024 states (prepare_ensemble: numpy
                     arithmetic for the group, a stage's accelerations in one pin.abaInParallel call) over the native
                     floor of a step: four articulated-body evaluations batched in C++ (abaInParallel, per state),
                     same threads. Also printed, informational: pinocchio_single_vs_native, one trajectory's µs per
                     step over the same floor (Python's per-call cost: no single trajectory gets near).   goal <= 3
truth_share          time computing the truth over the time of the whole sweep (the suite's four general cases,
                     every engine).                                                                    target <= 0.05
step_scaling         exponent of stepping time against steps over 1e3..1e6 (least squares on log-log; the one
                     farther from 1 of MuJoCo euler and Pinocchio symplectic_euler).                   target 1 ± 0.05
memory_scaling       peak traced memory (tracemalloc: Python and numpy allocations) of a whole run (prepare, run,
                     metrics) of 1e6 steps over one of 1e4 steps, MuJoCo and Pinocchio, the larger.    target <= 1.2
parallel_efficiency  sweep time with --jobs 1 over 2 x the time with --jobs 2 (same runs).             target >= 0.8
"""
from __future__ import annotations

import argparse
import gc
import math
import os
import sys
import tempfile
import time
import tracemalloc
from pathlib import Path

import numpy as np
import pinocchio as pin

sys.path.insert(0, str(Path(__file__).resolve().parent))
import bench_overhead  # noqa: E402 - the overhead benchmarks live beside this file

from stereodyn.harness.scenes import metrics  # noqa: E402
from stereodyn.harness.run import truth as run_truth  # noqa: E402
from stereodyn.harness.scenes.cases import find_case, with_overrides  # noqa: E402
from stereodyn.harness.engines import get_engine  # noqa: E402
from stereodyn.harness.engines.declared import rigid_body  # noqa: E402
from stereodyn.harness.engines.pinocchio import build_model  # noqa: E402
from stereodyn.harness.grid import time_grid  # noqa: E402
from stereodyn.harness.run.sweep import SweepOptions, run_sweep  # noqa: E402

GENERAL_CASES = ("free-asymmetric", "lagrange-top", "kovalevskaya", "heavy-asymmetric")


# ------------------------------------------------------------------------------------------- pinocchio vs native

def pinocchio_vs_native(repeats: int, members: int = 1024, steps: int = 200) -> dict[str, float]:
    """µs per state-step: the engine's rk4 ensemble (PinocchioEngine.prepare_ensemble), one trajectory through the
    engine, and the native floor (the four accelerations of an RK4 step as four abaInParallel calls), all on the
    same threads."""
    case = bench_overhead.lagrange_top()
    dt = bench_overhead.DT
    threads = os.cpu_count() or 1
    model = build_model(case)
    pool = pin.ModelPool(model, threads)
    rng = np.random.default_rng(1)
    quat0 = np.tile(case.quat0, (members, 1))
    omega0 = np.asarray(case.omega0) + 0.01 * rng.standard_normal((members, 3))
    w, x, y, z = quat0.T
    qf, vf = np.asfortranarray(np.stack((x, y, z, w))), np.asfortranarray(omega0.T)
    tau, acc = np.zeros((3, members), order="F"), np.zeros((3, members), order="F")
    engine = get_engine("pinocchio")
    ensemble = rigid_body(engine).prepare_ensemble(case, "rk4", dt, quat0, omega0, threads=threads)
    ensemble_grid = time_grid(steps * dt, dt, 10)
    sim = engine.prepare(case, "rk4", dt)
    single_grid = time_grid(bench_overhead.PINOCCHIO_STEPS * dt, dt, bench_overhead.SAMPLES)
    best = bench_overhead.best_interleaved({
        "native": lambda: [pin.abaInParallel(threads, pool, qf, vf, tau, acc) for _ in range(4 * steps)],
        "ensemble": lambda: ensemble.run(ensemble_grid),
        "single": lambda: sim.run(single_grid)}, repeats)
    return {"native_us": best["native"] / (steps * members) * 1e6,
            "ensemble_us": best["ensemble"] / (steps * members) * 1e6,
            "single_us": best["single"] / single_grid.steps * 1e6, "members": members, "threads": threads}


# ------------------------------------------------------------------------------------------- drake overhead

DRAKE_INTEGRATORS = ("explicit_euler", "runge_kutta3", "discrete")


def drake_overhead(repeats: int) -> dict[str, tuple[float, float]] | None:
    """{integrator: (adapter µs/step, bare µs/step)} on the Lagrange top at dt = 1e-3 over 10 s (10 000 steps, 1000
    samples), or None without pydrake. The bare run is the adapter's own diagram in its own Simulator, reset to the
    initial state and advanced to t_end in one call: Drake's stepping with nothing recorded."""
    try:
        from pydrake.systems.analysis import ResetIntegratorFromFlags, Simulator
    except ImportError:
        return None
    case = bench_overhead.lagrange_top()
    dt = bench_overhead.DT
    grid = time_grid(case.t_end, dt, bench_overhead.SAMPLES)
    out = {}
    for integrator in DRAKE_INTEGRATORS:
        sim = get_engine("drake").prepare(case, integrator, dt, formulation="rpy_ball")
        simulator = Simulator(sim.diagram)
        context = simulator.get_mutable_context()

        def bare(simulator=simulator, context=context, discrete=integrator == "discrete", name=integrator):
            context.SetTime(0.0)
            if discrete:
                context.SetDiscreteState(sim.x0)
            else:
                context.SetContinuousState(sim.x0)
                ResetIntegratorFromFlags(simulator, name, dt).set_fixed_step_mode(True)
            simulator.Initialize()
            simulator.AdvanceTo(grid.t_end)

        best = bench_overhead.best_interleaved({"adapter": lambda sim=sim: sim.run(grid), "bare": bare}, repeats)
        out[integrator] = (best["adapter"] / grid.steps * 1e6, best["bare"] / grid.steps * 1e6)
    return out


# ------------------------------------------------------------------------------------------- truth share

def truth_share(jobs: int, quick: bool) -> dict[str, float]:
    """The truths' time (each case's, computed here, one after the other, as a pool worker computes it: issue 49 made
    them pool tasks, so the sweep's own process no longer sees them) and the sweep's wall time, which includes them."""
    cases = [find_case(name) for name in GENERAL_CASES]
    if quick:
        cases = [with_overrides(c, t_end=5.0) for c in cases]
    start = time.perf_counter()
    for case in cases:
        run_truth.case_truth(case, certify=True)
    truth_s = time.perf_counter() - start
    with tempfile.TemporaryDirectory() as out:
        start = time.perf_counter()
        run_sweep(cases, SweepOptions(["mujoco", "pinocchio", "reference"], Path(out), jobs=jobs))
        total = time.perf_counter() - start
    return {"truth_s": truth_s, "sweep_s": total}


# ------------------------------------------------------------------------------------------- steps and memory

def _stepping_run(engine: str, integrator: str, steps: int, dt: float = 1e-3):
    """A prepared run of `steps` steps (the case's 1000 samples), warmed up: a callable to time."""
    case = with_overrides(find_case("free-asymmetric"), t_end=steps * dt, dt=dt)
    grid = time_grid(case.t_end, dt, case.samples)
    sim = get_engine(engine).prepare(case, integrator, dt)
    return lambda: sim.run(grid)


def step_scaling(repeats: int = 3) -> dict[str, float]:
    """Least-squares exponent of the best time over `repeats` rounds, the four sizes interleaved within a round so
    that a slow spell of the shared machine hits every size alike, not one of them."""
    steps = np.array([1_000, 10_000, 100_000, 1_000_000])
    out = {}
    for engine, integrator in (("mujoco", "euler"), ("pinocchio", "symplectic_euler")):
        runs = {int(n): _stepping_run(engine, integrator, int(n)) for n in steps}
        best = bench_overhead.best_interleaved(runs, repeats)
        times = np.array([best[int(n)] for n in steps])
        out[engine] = float(np.polyfit(np.log(steps), np.log(times), 1)[0])
    return out


def _peak_bytes(engine: str, integrator: str, steps: int, dt: float = 1e-3) -> int:
    case = with_overrides(find_case("free-asymmetric"), t_end=steps * dt, dt=dt)
    grid = time_grid(case.t_end, dt, case.samples)
    gc.collect()
    tracemalloc.start()
    try:
        sim = get_engine(engine).prepare(case, integrator, dt)
        traj = sim.run(grid)
        metrics.drifts(case, traj, metrics.applicable_integrals(case))
        return tracemalloc.get_traced_memory()[1]
    finally:
        tracemalloc.stop()


def memory_scaling() -> dict[str, float]:
    return {engine: _peak_bytes(engine, integrator, 1_000_000) / _peak_bytes(engine, integrator, 10_000)
            for engine, integrator in (("mujoco", "rk4"), ("pinocchio", "symplectic_euler"))}


# ------------------------------------------------------------------------------------------- parallel efficiency

def parallel_efficiency(quick: bool, rounds: int = 2) -> dict[str, float]:
    """Best sweep time with --jobs 1 and with --jobs 2 over `rounds` interleaved rounds, as best_interleaved does for
    the other figures: on a shared machine one sweep swings by ~10% from one minute to the next (the same --jobs 1
    sweep took 21-27 s), and interference only ever adds time."""
    cases = [with_overrides(find_case(name), t_end=5.0 if quick else 20.0) for name in GENERAL_CASES]
    times = {1: math.inf, 2: math.inf}
    for _ in range(rounds):
        for jobs in (1, 2):
            with tempfile.TemporaryDirectory() as out:
                start = time.perf_counter()
                run_sweep(cases, SweepOptions(["mujoco", "pinocchio", "reference"], Path(out), jobs=jobs))
                times[jobs] = min(times[jobs], time.perf_counter() - start)
    return {"jobs1_s": times[1], "jobs2_s": times[2]}


FIGURES = ("mujoco_overhead", "drake_overhead", "pinocchio_overhead", "pinocchio_vs_native", "truth_share",
           "step_scaling", "memory_scaling", "parallel_efficiency")


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--repeats", type=int, default=7)
    parser.add_argument("--quick", action="store_true", help="shorter sweeps for truth_share and parallel_efficiency")
    parser.add_argument("--only", default=",".join(FIGURES),
                        help="comma-separated figures to measure (default: all): " + ", ".join(FIGURES))
    args = parser.parse_args()
    only = args.only.split(",")
    unknown = [name for name in only if name not in FIGURES]
    if unknown:
        parser.error(f"--only: unknown figure {', '.join(unknown)}; valid: {', '.join(FIGURES)}")
    lines = []
    with tempfile.TemporaryDirectory() as scratch:
        os.chdir(scratch)  # MuJoCo writes MUJOCO_LOG.TXT into the working directory on a warning
        case = bench_overhead.lagrange_top()
        if "mujoco_overhead" in only:
            mujoco = [bench_overhead.bench_mujoco(case, integrator, args.repeats) for integrator in ("euler", "rk4")]
            lines.append(f"mujoco_overhead {max(a / b for a, b in mujoco):.3f}")
        if "drake_overhead" in only:
            drake = drake_overhead(args.repeats)
            if drake is None:
                lines.append("drake_overhead skipped (pydrake not installed: pip install 'stereodyn[drake]')")
            else:
                print("# drake us/step, adapter / bare AdvanceTo: " + ", ".join(
                    f"{name} {a:.2f} / {b:.2f}" for name, (a, b) in drake.items()))
                lines.append(f"drake_overhead {max(a / b for a, b in drake.values()):.3f}")
        if "pinocchio_overhead" in only:
            pinocchio = bench_overhead.bench_pinocchio(case, args.repeats)
            lines.append(f"pinocchio_overhead {pinocchio['adapter'] / pinocchio['bare']:.3f}")
        if "pinocchio_vs_native" in only:
            native = pinocchio_vs_native(args.repeats)
            print(f"# pinocchio rk4, us per state-step: ensemble of {native['members']} {native['ensemble_us']:.3f}, "
                  f"one trajectory {native['single_us']:.3f}, native floor (4 x abaInParallel) "
                  f"{native['native_us']:.3f} ({native['threads']} threads)")
            lines.append(f"pinocchio_vs_native {native['ensemble_us'] / native['native_us']:.2f}")
            lines.append(f"pinocchio_single_vs_native {native['single_us'] / native['native_us']:.2f}")
        if "truth_share" in only:
            share = truth_share(2, args.quick)
            print(f"# truth {share['truth_s']:.2f} s of a {share['sweep_s']:.1f} s sweep")
            lines.append(f"truth_share {share['truth_s'] / share['sweep_s']:.4f}")
        if "step_scaling" in only:
            scaling = step_scaling()
            print(f"# step scaling exponents: {scaling}")
            lines.append(f"step_scaling {max(scaling.values(), key=lambda e: abs(e - 1.0)):.3f}")
        if "memory_scaling" in only:
            memory = memory_scaling()
            print(f"# memory ratios 1e6 / 1e4 steps: {memory}")
            lines.append(f"memory_scaling {max(memory.values()):.3f}")
        if "parallel_efficiency" in only:
            parallel = parallel_efficiency(args.quick)
            print(f"# sweep: --jobs 1 {parallel['jobs1_s']:.1f} s, --jobs 2 {parallel['jobs2_s']:.1f} s")
            lines.append(f"parallel_efficiency {parallel['jobs1_s'] / (2.0 * parallel['jobs2_s']):.3f}")
    print("\n".join(lines))


if __name__ == "__main__":
    main()
