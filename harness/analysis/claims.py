"""The rules that judge an integrator's declared properties (issue 30), each on the figure that
harness.integrators.properties measures in a few short steps: the verdicts of `stereodyn run`
(harness.analysis.verdicts) and harness.testing's assert_claims apply the same check.

- symplectic: ‖JᵀΩJ − Ω‖_max of one step in canonical coordinates at each h of SYMPLECTIC_STEPS; passes when every
  defect is <= SYMPLECTIC_DEFECT_MAX.
- symmetric: a step of h then −h, the attitude angle and relative ω error to the start at each h of REVERSAL_STEPS;
  passes when every error is <= REVERSAL_MAX.
- stages: right-hand-side calls over STAGE_STEPS steps of STAGE_STEP, counted by a wrapper; passes with exactly
  `stages` a step, or at least that many for an `iterative` method.
- geometric: max ‖q‖² − 1 of the raw attitude quaternion over GROUP_STEPS steps of GROUP_STEP; <= GROUP_DRIFT_MAX.
- casimir_preserving: max |σv|²/|σv0|² − 1 over GROUP_STEPS steps on FREE_CASE; <= CASIMIR_DRIFT_MAX.

Symplectic or not: a symplectic step's defect is the central differences' error, flat in h (strang_free_flow and
moser_veselov: 2.0e-11 to 2.5e-11 at every h; the vector implicit midpoint on gibbs_hamiltonian <= 1.8e-12); a
non-symplectic one of order p shows C h^(p+1) (rk4: 8.7e-5, 2.9e-6, 9.2e-8 at h = 0.2, 0.1, 0.05, slope 4.9; euler
8.1e-2 ... slope 2). SYMPLECTIC_DEFECT_MAX = 1e-9 is 40x the largest symplectic defect measured and 1e-4 of rk4's at
h = 0.2 (|ω| h = 0.46 on CHECK_CASE): a method must be non-symplectic only at order ~10 to hide under it there.
"""
from __future__ import annotations

import functools
import math
from dataclasses import dataclass

import numpy as np

from ..integrators import properties
from ..integrators.base import Integrator
from ..scenes.cases import load_case, suite_dir

# Every property is measured on CHECK_CASE (uniform gravity, an asymmetric body on non-principal axes, |ω0| = 2.3
# rad/s: every term of the dynamics), or on FREE_CASE where the method refuses gravity (moser_veselov) and for the
# Casimir (|σv|² is conserved only without a torque).
CHECK_CASE, FREE_CASE = "heavy-asymmetric", "free-asymmetric"
SYMPLECTIC_STEPS = (0.2, 0.05)
SYMPLECTIC_DEFECT_MAX = 1e-9  # module docstring
REVERSAL_STEPS = (0.1, 0.05)
# symmetric built-ins: <= 2.7e-16 (implicit_midpoint, strang_free_flow, moser_veselov); rk4 1.4e-7 at h = 0.1
REVERSAL_MAX = 1e-12
STAGE_STEP, STAGE_STEPS = 0.05, 10
GROUP_STEP, GROUP_STEPS = 0.05, 50
# the built-ins on the group: <= 3.3e-15 over 200 steps (a random walk of the quaternion products' rounding); over
# the 50 steps checked rk4 on the quaternion formulation drifts 1.6e-7, euler 0.3
GROUP_DRIFT_MAX = 1e-12
# the midpoint rule, the free flow and Moser–Veselov: <= 4.0e-15 over 200 steps; rk4 over the 50 steps checked 1.4e-9
CASIMIR_DRIFT_MAX = 1e-12
CLAIMS = ("symplectic", "symmetric", "stages", "geometric", "casimir_preserving")


@dataclass(frozen=True)
class Finding:
    """One claim of an integrator class judged: claim (CLAIMS), passed, figure (the measured number the rule reads:
    the largest defect, error or drift, or right-hand-side calls a step), detail (what it declares and what was
    measured, in words), rule (the rule, in words), case (where it was measured)."""

    claim: str
    passed: bool
    figure: float
    detail: str
    rule: str
    case: str


def claimed(cls: type[Integrator]) -> tuple[str, ...]:
    """The claims of cls to check: every property it declares True, and its stages."""
    return tuple(c for c in CLAIMS if c == "stages" or getattr(cls, c, False) is True)


@functools.lru_cache(maxsize=None)
def _start(name: str):
    case = load_case(suite_dir() / f"{name}.toml")  # the suite's file alone (find_case reads all 30: ~0.5 s)
    return case.name, case.body, case.quat0, case.omega0


def _on_check_case(cls: type[Integrator], measure):
    """measure(body, quat0, omega0) on CHECK_CASE, or on FREE_CASE where the method refuses CHECK_CASE's gravity
    (its stepper raises ValueError or TypeError); (case name, result)."""
    name, body, quat0, omega0 = _start(CHECK_CASE)
    try:
        return name, measure(body, quat0, omega0)
    except (ValueError, TypeError):
        name, body, quat0, omega0 = _start(FREE_CASE)
        return name, measure(body, quat0, omega0)


def _slope(hs, values) -> float:
    """The log-log slope of values against hs (NaN where a value is not positive and finite)."""
    x, y = np.log(np.asarray(hs, dtype=float)), np.asarray(values, dtype=float)
    if len(x) < 2 or not (np.isfinite(y).all() and (y > 0).all()):
        return math.nan
    return float(np.polyfit(x, np.log(y), 1)[0])


def _list(values) -> str:
    return ", ".join(f"{v:.1e}" for v in values)


def check(cls: type[Integrator], claim: str) -> Finding:
    """Measure and judge one claim of cls (a plug-in's exception propagates: the caller decides what it is)."""
    if claim == "symplectic":
        hs = SYMPLECTIC_STEPS
        case, defects = _on_check_case(cls, lambda *start: [properties.symplectic_defect(cls, *start, h) for h in hs])
        worst = max(defects)
        coordinates = ("exponential coordinates and their momenta" if cls.state_space == "lie"
                       else f"{properties.SYMPLECTIC_FORMULATION}'s (q, p)")
        slope = _slope(hs, defects)
        return Finding(claim, worst <= SYMPLECTIC_DEFECT_MAX, worst,
                       f"declares symplectic: defect |J^T Omega J - Omega| {_list(defects)} at h = "
                       f"{', '.join(f'{h:g}' for h in hs)} s on {case} ({coordinates})"
                       + (f", slope {slope:.1f} in h" if worst > SYMPLECTIC_DEFECT_MAX and math.isfinite(slope)
                          else ""),
                       f"defect <= {SYMPLECTIC_DEFECT_MAX:g} at every h (round-off, flat in h); a non-symplectic "
                       f"method of order p shows C h^(p+1)", case)
    if claim == "symmetric":
        hs = REVERSAL_STEPS
        case, errors = _on_check_case(cls, lambda *start: [properties.reversal_error(cls, *start, h) for h in hs])
        worst = max(errors)
        return Finding(claim, worst <= REVERSAL_MAX, worst,
                       f"declares symmetric: a step of h then -h misses the start by {_list(errors)} at h = "
                       f"{', '.join(f'{h:g}' for h in hs)} s on {case}",
                       f"attitude angle (rad) and relative omega error after h, -h <= {REVERSAL_MAX:g}", case)
    if claim == "stages":
        case, per_step = _on_check_case(cls, lambda *start: properties.rhs_evals_per_step(
            cls, *start, STAGE_STEP, STAGE_STEPS))
        iterative = bool(getattr(cls, "iterative", False))
        ok = per_step >= cls.stages if iterative else per_step == cls.stages
        return Finding(claim, ok, per_step,
                       f"declares {cls.stages} stage{'s' * (cls.stages != 1)}{' (iterative: the least)' * iterative}: "
                       f"counted {per_step:.2f} right-hand-side evaluations a step over {STAGE_STEPS} steps of "
                       f"{STAGE_STEP:g} s on {case}",
                       "evaluations counted a step >= stages (iterative)" if iterative
                       else "evaluations counted a step == stages", case)
    if claim == "geometric":
        case, drift = _on_check_case(cls, lambda *start: properties.group_drift(cls, *start, GROUP_STEP, GROUP_STEPS))
        where = "g's quaternion" if cls.state_space == "lie" else f"the {properties.GROUP_FORMULATION} formulation's q"
        return Finding(claim, drift <= GROUP_DRIFT_MAX, drift,
                       f"declares geometric (the attitude stays on the group): max ||q|^2 - 1| {drift:.1e} of {where} "
                       f"over {GROUP_STEPS} steps of {GROUP_STEP:g} s on {case}",
                       f"max ||q|^2 - 1| of the raw quaternion <= {GROUP_DRIFT_MAX:g}", case)
    if claim == "casimir_preserving":
        case, body, quat0, omega0 = _start(FREE_CASE)
        drift = properties.casimir_drift(cls, body, quat0, omega0, GROUP_STEP, GROUP_STEPS)
        return Finding(claim, drift <= CASIMIR_DRIFT_MAX, drift,
                       f"declares casimir_preserving: max ||sigma v|^2 / |sigma v0|^2 - 1| {drift:.1e} over "
                       f"{GROUP_STEPS} steps of {GROUP_STEP:g} s on {case}",
                       f"relative drift of |M|^2 on a torque-free body <= {CASIMIR_DRIFT_MAX:g}", case)
    raise ValueError(f"unknown claim {claim!r}; valid: {', '.join(CLAIMS)}")


def findings(cls: type[Integrator]) -> list[Finding]:
    """Every claim of cls (claimed(cls)) measured and judged."""
    return [check(cls, claim) for claim in claimed(cls)]
