"""How far two CPUs move the gate's metrics (docs/DESIGN.md §4, Baselines: the cross-machine mode). Run by hand:

    python tests/benchmarks/cross_cpu_spread.py simulate A.npz      # on each machine: numpy only, ~1 s
    python tests/benchmarks/cross_cpu_spread.py spread A.npz B.npz  # anywhere: per run, bit-identical or not, and
                                                                    # the ratio B / A of each state's energy drift

A heavy asymmetric top (moments 2, 1.5, 1; centre of mass (0.1, 0.05, 0.2); m g = 9.81) from 16 random states (seeded)
over 2 s at dt 1e-2 and 3e-3, with RK4 (quaternion renormalised each step) and Lie-Euler (exponential map: numpy's
vectorised sin and cos, the calls whose SIMD code differs between AVX2 and AVX-512): the arithmetic of the reference
engine's formulations, with no stereodyn, heyoka or engine needed on the second machine.
"""
import sys

import numpy as np

I, COM, MG = np.array([2.0, 1.5, 1.0]), np.array([0.1, 0.05, 0.2]), 9.81


def qm(a, b):
    w1, x1, y1, z1 = a.T
    w2, x2, y2, z2 = b.T
    return np.stack([w1 * w2 - x1 * x2 - y1 * y2 - z1 * z2, w1 * x2 + x1 * w2 + y1 * z2 - z1 * y2,
                     w1 * y2 - x1 * z2 + y1 * w2 + z1 * x2, w1 * z2 + x1 * y2 - y1 * x2 + z1 * w2], 1)


def zb(q):
    """The world's vertical in body components."""
    w, x, y, z = q.T
    return np.stack([2 * (x * z - w * y), 2 * (y * z + w * x), 1 - 2 * (x * x + y * y)], 1)


def f(q, w):
    tau = MG * np.cross(COM, -zb(q))
    return 0.5 * qm(q, np.concatenate([0 * w[:, :1], w], 1)), (tau - np.cross(w, I * w)) / I


def energy(q, w):
    return 0.5 * np.sum(I * w * w, 1) + MG * (zb(q) @ COM)


def simulate(out: str) -> None:
    rng = np.random.default_rng(7)
    q0 = rng.normal(size=(16, 4))
    q0 /= np.linalg.norm(q0, axis=1)[:, None]
    w0 = rng.normal(size=(16, 3)) * 3
    arrays = {}
    for dt in (1e-2, 3e-3):
        for method in ("rk4", "lie"):
            q, w = q0.copy(), w0.copy()
            quats, energies = [q], [energy(q, w)]
            for _ in range(int(round(2 / dt))):
                if method == "rk4":
                    a1, b1 = f(q, w)
                    a2, b2 = f(q + dt / 2 * a1, w + dt / 2 * b1)
                    a3, b3 = f(q + dt / 2 * a2, w + dt / 2 * b2)
                    a4, b4 = f(q + dt * a3, w + dt * b3)
                    q, w = q + dt / 6 * (a1 + 2 * a2 + 2 * a3 + a4), w + dt / 6 * (b1 + 2 * b2 + 2 * b3 + b4)
                    q /= np.linalg.norm(q, axis=1)[:, None]
                else:
                    _, b = f(q, w)
                    h = np.linalg.norm(w, axis=1) * dt / 2
                    s = np.sin(h) / np.where(h > 0, h, 1)
                    q = qm(q, np.concatenate([np.cos(h)[:, None], (s * dt / 2)[:, None] * w], 1))
                    w = w + dt * b
                quats.append(q)
                energies.append(energy(q, w))
            arrays[f"{method}-{dt:g}/q"], arrays[f"{method}-{dt:g}/e"] = np.array(quats), np.array(energies)
    np.savez(out, **arrays)


def spread(path_a: str, path_b: str) -> None:
    a, b = np.load(path_a), np.load(path_b)
    for stem in sorted({key.split("/")[0] for key in a.files}):
        ea, eb = a[f"{stem}/e"], b[f"{stem}/e"]
        ratio = (np.max(np.abs(eb - eb[0]), 0) / np.max(np.abs(ea - ea[0]), 0))
        same = np.array_equal(a[f"{stem}/q"], b[f"{stem}/q"]) and np.array_equal(ea, eb)
        print(f"{stem:10s} {'bit-identical' if same else 'differs'}; energy drift B / A in "
              f"[{ratio.min():.15f}, {ratio.max():.15f}]")


if __name__ == "__main__":
    simulate(sys.argv[2]) if sys.argv[1] == "simulate" else spread(sys.argv[2], sys.argv[3])
