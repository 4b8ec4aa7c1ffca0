"""Adapter overhead: each engine adapter against the bare loop it wraps, measured side by side in one process.

    python tests/benchmarks/bench_overhead.py [--repeats N]

mujoco_overhead     = MujocoEngine us/step / bare mujoco.rollout.rollout us/step (same model, same steps; the worse
                      of euler and rk4). Target <= 1.1.
pinocchio_overhead  = PinocchioEngine rk4 us/step / a bare hand-written Python RKMK4 loop with pin.aba and
                      pin.integrate (numpy vector arithmetic, a float helper for dexp^-1). Target <= 1.2. Also
                      printed: the ratio to the same loop fully unrolled on Python floats, the fastest pure-Python
                      form, which the generic tableau-driven step cannot quite match.
The adapters record the case's samples and check divergence; the bare loops only step. Repeats are interleaved
(adapter, bare, adapter, ...) so drifts in machine speed hit both alike; the best of N is kept (garbage collector off).
Scene: the suite's Lagrange top (ω0 = (0.5, 0, 15) rad/s), dt = 1e-3.
"""
from __future__ import annotations

import argparse
import gc
import os
import tempfile
import time

import mujoco
import numpy as np
import pinocchio as pin
from mujoco import rollout

from stereodyn.harness.scenes.cases import Case
from stereodyn.harness.engines.mujoco import MujocoEngine
from stereodyn.harness.engines.pinocchio import PinocchioEngine, build_model
from stereodyn.harness.grid import time_grid

DT = 1e-3
MUJOCO_STEPS = 100_000      # 10 rollout chunks in the adapter; ~0.1 s a run
PINOCCHIO_STEPS = 10_000    # ~0.1 s a run
SAMPLES = 1000


def lagrange_top() -> Case:
    return Case(name="lagrange-top", description="", tags=(), mass=1.0, com=np.array([0.0, 0.0, 0.2]),
                inertia=np.diag([1.0, 1.0, 0.4]), gravity=9.81, gravity_direction=np.array([0.0, 0.0, -1.0]),
                quat0=np.array([np.cos(0.3), np.sin(0.3), 0.0, 0.0]), omega0=np.array([0.5, 0.0, 15.0]),
                t_end=10.0, dt=(DT,), samples=SAMPLES)


def best_interleaved(runs: dict[str, callable], repeats: int) -> dict[str, float]:
    """Best wall time (s) of each callable over `repeats` interleaved rounds, after one warm-up round."""
    for run in runs.values():
        run()
    best = {name: float("inf") for name in runs}
    enabled = gc.isenabled()
    gc.disable()
    try:
        for _ in range(repeats):
            for name, run in runs.items():
                start = time.perf_counter()
                run()
                best[name] = min(best[name], time.perf_counter() - start)
    finally:
        if enabled:
            gc.enable()
    return best


def bare_rkmk4(model, data, q: np.ndarray, v: np.ndarray, h: float, steps: int) -> tuple[np.ndarray, np.ndarray]:
    """RKMK4 written out by hand: classical tableau, stages g exp(theta_i), theta' = dexp^-1_theta(v)."""
    aba, integrate = pin.aba, pin.integrate
    tau = np.zeros(3)
    half, sixth = 0.5 * h, h / 6.0

    def dexp_inv(theta, w):
        # w + 1/2 theta x w + 1/12 theta x (theta x w), on floats (np.cross costs ~15 us on 3-vectors)
        t0, t1, t2 = theta.tolist()
        w0, w1, w2 = w.tolist()
        c0, c1, c2 = t1 * w2 - t2 * w1, t2 * w0 - t0 * w2, t0 * w1 - t1 * w0
        e0, e1, e2 = t1 * c2 - t2 * c1, t2 * c0 - t0 * c2, t0 * c1 - t1 * c0
        return np.array((w0 + 0.5 * c0 + e0 / 12.0, w1 + 0.5 * c1 + e1 / 12.0, w2 + 0.5 * c2 + e2 / 12.0))

    for _ in range(steps):
        k1 = aba(model, data, q, v, tau)
        theta2, v2 = half * v, v + half * k1
        k2 = aba(model, data, integrate(model, q, theta2), v2, tau)
        t2 = dexp_inv(theta2, v2)
        theta3, v3 = half * t2, v + half * k2
        k3 = aba(model, data, integrate(model, q, theta3), v3, tau)
        t3 = dexp_inv(theta3, v3)
        theta4, v4 = h * t3, v + h * k3
        k4 = aba(model, data, integrate(model, q, theta4), v4, tau)
        t4 = dexp_inv(theta4, v4)
        q = integrate(model, q, sixth * (v + 2.0 * t2 + 2.0 * t3 + t4))
        v = v + sixth * (k1 + 2.0 * k2 + 2.0 * k3 + k4)
    return q, v


def unrolled_rkmk4(model, data, q: np.ndarray, v: np.ndarray, h: float, steps: int) -> tuple[np.ndarray, np.ndarray]:
    """The same RKMK4 fully written out on Python floats: the fastest pure-Python form (informational baseline)."""
    aba, integrate, array = pin.aba, pin.integrate, np.array
    tau = np.zeros(3)
    half, sixth = 0.5 * h, h / 6.0
    for _ in range(steps):
        v0, v1, v2 = v.tolist()
        a0, a1, a2 = aba(model, data, q, v, tau).tolist()
        t0, t1, t2 = half * v0, half * v1, half * v2                                  # stage 2
        u0, u1, u2 = v0 + half * a0, v1 + half * a1, v2 + half * a2
        b0, b1, b2 = aba(model, data, integrate(model, q, array((t0, t1, t2))), array((u0, u1, u2)), tau).tolist()
        c0, c1, c2 = t1 * u2 - t2 * u1, t2 * u0 - t0 * u2, t0 * u1 - t1 * u0
        e0, e1, e2 = t1 * c2 - t2 * c1, t2 * c0 - t0 * c2, t0 * c1 - t1 * c0
        s0, s1, s2 = u0 + 0.5 * c0 + e0 / 12.0, u1 + 0.5 * c1 + e1 / 12.0, u2 + 0.5 * c2 + e2 / 12.0
        t0, t1, t2 = half * s0, half * s1, half * s2                                  # stage 3
        u0, u1, u2 = v0 + half * b0, v1 + half * b1, v2 + half * b2
        d0, d1, d2 = aba(model, data, integrate(model, q, array((t0, t1, t2))), array((u0, u1, u2)), tau).tolist()
        c0, c1, c2 = t1 * u2 - t2 * u1, t2 * u0 - t0 * u2, t0 * u1 - t1 * u0
        e0, e1, e2 = t1 * c2 - t2 * c1, t2 * c0 - t0 * c2, t0 * c1 - t1 * c0
        r0, r1, r2 = u0 + 0.5 * c0 + e0 / 12.0, u1 + 0.5 * c1 + e1 / 12.0, u2 + 0.5 * c2 + e2 / 12.0
        t0, t1, t2 = h * r0, h * r1, h * r2                                           # stage 4
        u0, u1, u2 = v0 + h * d0, v1 + h * d1, v2 + h * d2
        f0, f1, f2 = aba(model, data, integrate(model, q, array((t0, t1, t2))), array((u0, u1, u2)), tau).tolist()
        c0, c1, c2 = t1 * u2 - t2 * u1, t2 * u0 - t0 * u2, t0 * u1 - t1 * u0
        e0, e1, e2 = t1 * c2 - t2 * c1, t2 * c0 - t0 * c2, t0 * c1 - t1 * c0
        p0, p1, p2 = u0 + 0.5 * c0 + e0 / 12.0, u1 + 0.5 * c1 + e1 / 12.0, u2 + 0.5 * c2 + e2 / 12.0
        q = integrate(model, q, array((sixth * (v0 + 2.0 * s0 + 2.0 * r0 + p0), sixth * (v1 + 2.0 * s1 + 2.0 * r1 + p1),
                                       sixth * (v2 + 2.0 * s2 + 2.0 * r2 + p2))))
        v = array((v0 + sixth * (a0 + 2.0 * b0 + 2.0 * d0 + f0), v1 + sixth * (a1 + 2.0 * b1 + 2.0 * d1 + f1),
                   v2 + sixth * (a2 + 2.0 * b2 + 2.0 * d2 + f2)))
    return q, v


def bench_mujoco(case: Case, integrator: str, repeats: int) -> tuple[float, float]:
    """(adapter, bare) us/step."""
    grid = time_grid(MUJOCO_STEPS * DT, DT, SAMPLES)
    sim = MujocoEngine().prepare(case, integrator, DT)
    model = mujoco.MjModel.from_xml_string(sim.xml)
    data = mujoco.MjData(model)
    initial = sim.initial_state.copy()
    best = best_interleaved({"adapter": lambda: sim.run(grid),
                             "bare": lambda: rollout.rollout(model, data, initial, nstep=grid.steps)}, repeats)
    return best["adapter"] / grid.steps * 1e6, best["bare"] / grid.steps * 1e6


def bench_pinocchio(case: Case, repeats: int) -> dict[str, float]:
    """us/step of the adapter's rk4 and of the two hand-written loops; checks that all compute the same state."""
    grid = time_grid(PINOCCHIO_STEPS * DT, DT, SAMPLES)
    sim = PinocchioEngine().prepare(case, "rk4", DT)
    model = build_model(case)
    data = model.createData()
    w, x, y, z = case.quat0
    q0, v0 = np.array([x, y, z, w]), np.array(case.omega0, dtype=float)
    trajectory = sim.run(grid)
    for loop in (bare_rkmk4, unrolled_rkmk4):
        _, v_end = loop(model, data, q0, v0, DT, grid.steps)
        # Same scheme, same arithmetic up to the order of additions: they must agree to round-off.
        assert np.abs(trajectory.omega[-1] - v_end).max() < 1e-9, (loop.__name__, trajectory.omega[-1], v_end)
    best = best_interleaved({"adapter": lambda: sim.run(grid),
                             "bare": lambda: bare_rkmk4(model, data, q0, v0, DT, grid.steps),
                             "unrolled": lambda: unrolled_rkmk4(model, data, q0, v0, DT, grid.steps)}, repeats)
    return {name: seconds / grid.steps * 1e6 for name, seconds in best.items()}


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--repeats", type=int, default=7)
    args = parser.parse_args()
    case = lagrange_top()
    with tempfile.TemporaryDirectory() as scratch:
        os.chdir(scratch)  # MuJoCo writes MUJOCO_LOG.TXT into the working directory on a warning
        ratios = []
        for integrator in ("euler", "rk4"):
            adapter, bare = bench_mujoco(case, integrator, args.repeats)
            ratios.append(adapter / bare)
            print(f"mujoco {integrator:<5} adapter {adapter:8.3f} us/step  bare rollout {bare:8.3f} us/step  "
                  f"ratio {adapter / bare:.3f}")
        pinocchio = bench_pinocchio(case, args.repeats)
        print(f"pinocchio rk4 adapter {pinocchio['adapter']:8.3f} us/step  bare RKMK4 loop {pinocchio['bare']:8.3f} "
              f"us/step  ratio {pinocchio['adapter'] / pinocchio['bare']:.3f}")
        print(f"pinocchio rk4 adapter {pinocchio['adapter']:8.3f} us/step  unrolled float RKMK4 "
              f"{pinocchio['unrolled']:8.3f} us/step  ratio {pinocchio['adapter'] / pinocchio['unrolled']:.3f}"
              "  (informational: the fastest pure-Python form)")
        print(f"mujoco_overhead {max(ratios):.3f}")
        print(f"pinocchio_overhead {pinocchio['adapter'] / pinocchio['bare']:.3f}")

if __name__ == "__main__":
    main()
