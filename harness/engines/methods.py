"""The shared vocabulary of integration methods: what an integrator is, whatever an engine calls it.

Names mislead: MuJoCo's `euler` is semi-implicit (velocity first), like Pinocchio's `symplectic_euler`, not like the
registry's `euler` (explicit). Each engine declares the method of each of its integrators (Offer.method); runs of
the same method and dt on a case are compared across engines (agreement.csv, harness.agreement). Two runs of one
method on one state space agree to round-off where they are the same map; a difference above it is a finding.
"""
from __future__ import annotations

# method -> one line saying what it is
METHODS: dict[str, str] = {
    "explicit_euler": "explicit Euler: attitude and velocity both advanced from the step's start",
    "semi_implicit_euler": "semi-implicit (symplectic) Euler: the velocity first, then the attitude with the new "
                           "velocity",
    "rk2": "second-order explicit Runge-Kutta",
    "rk3": "third-order explicit Runge-Kutta",
    "rk4": "classical fourth-order Runge-Kutta (on the rotation group: Runge-Kutta-Munthe-Kaas)",
    "rk5": "fifth-order explicit Runge-Kutta",
    "implicit_midpoint": "implicit midpoint rule (symmetric, second order)",
    "implicit_euler": "implicit (backward) Euler",
}

# The registry's built-in integrators: (name, state space) -> method. A plug-in integrator is compared with nothing
# until its engine says what it is (Offer.method). rk4_naive (the RK4 tableau through a retraction, 2nd order on the
# group) and the geometric splittings are methods of their own: left out.
_REGISTERED = {
    ("euler", "lie"): "explicit_euler", ("symplectic_euler", "lie"): "semi_implicit_euler", ("rk4", "lie"): "rk4",
    ("implicit_midpoint", "lie"): "implicit_midpoint",
    ("euler", "vector"): "explicit_euler", ("rk4", "vector"): "rk4",
    ("implicit_midpoint", "vector"): "implicit_midpoint",
}


def registered_method(integrator: str, state_space: str) -> str:
    """The method of a registered integrator in a state space, "" where it has none in this vocabulary."""
    return _REGISTERED.get((integrator, state_space), "")
