"""The plane pendulum ϑ̈ = -w² sin ϑ in closed form (Jacobi elliptic functions), for the compound-pendulum motions
of the heavy body (Mlodzejowski rotations, the b1 of the Hess–Grioli precessions, FORMULARY G11).

With the energy parameter e = (ϑ̇ / 2w)² + sin²(ϑ/2):
* e < 1, libration:  sin(ϑ/2) = √e sn(w t + u0 | e),   cos(ϑ/2) = dn,   ϑ̇ = 2 w √e cn;
* e > 1, rotation:   ϑ/2 = ± am(√e w t + u0 | 1/e),     ϑ̇ = ± 2 w √e dn;
* e = 1, separatrix: ϑ/2 = ± gd(w t + u0),              ϑ̇ = ± 2 w sech;
* equilibria (ϑ̇ = 0, sin ϑ = 0) stay put.
The angle is continuous (unwrapped) from its initial value, so whole turns are counted.
"""
from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from scipy.special import ellipkm1

from ..closed_form import first_kind, jacobi


@dataclass(frozen=True, eq=False)
class PendulumMotion:
    """Samples of a pendulum motion: angle (n,) rad, continuous; rate (n,) rad/s; sin and cos of the angle (n,),
    computed from the elliptic functions directly (not from the unwrapped angle)."""

    angle: np.ndarray
    rate: np.ndarray
    sin: np.ndarray
    cos: np.ndarray


def pendulum(angle0: float, rate0: float, frequency: float, times: np.ndarray) -> PendulumMotion:
    """Solve ϑ̈ = -frequency² sin ϑ from ϑ(0) = angle0 (rad), ϑ̇(0) = rate0 (rad/s); frequency > 0 (rad/s);
    times (n,) s. ϑ = 0 is the stable equilibrium."""
    times = np.asarray(times, dtype=float)
    w = float(frequency)
    wrapped = math.remainder(angle0, 2.0 * math.pi)  # in [-π, π]
    half_sin, half_cos = math.sin(0.5 * wrapped), math.cos(0.5 * wrapped)
    kinetic = (0.5 * rate0 / w) ** 2
    energy = kinetic + half_sin * half_sin
    # 1 - e and e - 1 as differences of the two terms that cancel near the separatrix
    below = half_cos * half_cos - kinetic
    if rate0 == 0.0 and half_sin * half_cos == 0.0:
        ones = np.ones_like(times)
        return PendulumMotion(angle0 * ones, 0.0 * ones, math.sin(wrapped) * ones, math.cos(wrapped) * ones)

    if below > 0.0:  # libration
        k = math.sqrt(energy)
        quarter = float(ellipkm1(below))
        u0 = first_kind(half_sin / k, rate0 / (2.0 * w * k), half_cos, quarter)
        sn, cn, dn, *_ = jacobi(u0 + w * times, energy, quarter, below)
        sn0, _, dn0, *_ = jacobi(np.array([u0]), energy, quarter, below)
        angle = angle0 + 2.0 * (np.arctan2(k * sn, dn) - math.atan2(k * sn0[0], dn0[0]))
        return PendulumMotion(angle, 2.0 * w * k * cn, 2.0 * k * sn * dn, dn * dn - energy * sn * sn)

    direction = math.copysign(1.0, rate0)
    if below == 0.0:  # separatrix: ϑ/2 = ± gd(w t + u0)
        u0 = math.asinh(direction * half_sin / half_cos)
        u = u0 + w * times
        tanh, sech = np.tanh(u), 1.0 / np.cosh(u)
        angle = angle0 + direction * 2.0 * (np.arctan(np.sinh(u)) - math.atan(math.sinh(u0)))
        return PendulumMotion(angle, direction * 2.0 * w * sech, direction * 2.0 * tanh * sech,
                              sech * sech - tanh * tanh)

    # rotation: with s = sign ϑ̇, s ϑ/2 = am(√e w t + u0 | 1/e); the half angle s ϑ0/2 lies in [-π/2, π/2]
    k = math.sqrt(energy)
    parameter = 1.0 / energy
    complement = -below / energy
    quarter = float(ellipkm1(complement))
    u0 = first_kind(direction * half_sin, half_cos, abs(rate0) / (2.0 * w * k), quarter)
    sn, cn, dn, j, sn_r, cn_r, _ = jacobi(u0 + k * w * times, parameter, quarter, complement)
    # am(u) = j π + atan2(sn r, cn r) with |r| <= K (cn r >= 0): continuous across the half periods
    amplitude = j * math.pi + np.arctan2(sn_r, cn_r)
    _, _, _, j0, sn0, cn0, _ = jacobi(np.array([u0]), parameter, quarter, complement)
    amplitude0 = j0[0] * math.pi + math.atan2(sn0[0], cn0[0])
    angle = angle0 + direction * 2.0 * (amplitude - amplitude0)
    return PendulumMotion(angle, direction * 2.0 * w * k * dn, direction * 2.0 * sn * cn, cn * cn - sn * sn)
