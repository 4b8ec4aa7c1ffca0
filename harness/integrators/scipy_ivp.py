"""scipy's solve_ivp methods as adaptive integrators of the "vector" state space: y' = f(t, chart, y) in a chart that
the system may change (harness.integrators.vector's VectorSystem, e.g. a formulation of reference.formulations).

The loop is solve_ivp's own (scipy.integrate._ivp.ivp): the method's solver class is stepped one accepted step at a
time and its dense output evaluated at the grid's sample times inside the step. Driving the class directly, rather
than calling solve_ivp, gives what solve_ivp does not return: the accepted steps, a chart change after any step, and
the divergence rule (harness.trajectory) checked on every accepted state, so a run that blows up stops there.

Charts: after each accepted step the system re-charts exactly as between fixed steps (VectorSystem.rechart: the same
criterion, at the step's end); when the chart changes, the solver is restarted from that state in the new chart,
which is what solve_ivp's terminal events do (the new solver picks its first step afresh, and the implicit methods
their Jacobian). A rechart that raises ArithmeticError (the coordinates became singular with chart changes off) ends
the run as diverged, naming it, as with fixed steps.

Counting: rhs_evals is every call of the system's right-hand side, counted where it is called. For Radau, BDF and
LSODA that includes the finite-difference Jacobians (n calls each, plus scipy's occasional refinements), which
scipy's own nfev leaves out for Radau and BDF (it counts njev instead); scipy's nfev, njev and nlu go to
Trajectory.info. steps: accepted steps.
"""
from __future__ import annotations

import math

import numpy as np
from scipy import integrate

from .. import budget
from ..grid import TimeGrid
from .vector import VectorSystem
from ..trajectory import Status, Trajectory, divergence_limit2, divergence_message, sample_good

# Integrator name -> scipy's method (scipy.integrate.solve_ivp's `method`), in report order.
METHODS = {"scipy_rk45": "RK45", "scipy_dop853": "DOP853", "scipy_radau": "Radau", "scipy_bdf": "BDF",
           "scipy_lsoda": "LSODA"}
DEFAULT_TOLERANCE = 1e-8  # the adaptive contract's default (relative and absolute) for the sweep's row
# scipy raises rtol below 100 eps to 100 eps (with a warning): a smaller request would not be what ran.
MIN_TOLERANCE = 100 * float(np.finfo(float).eps)
# Accepted steps one run may take: the default suite's runs take 10-20 000 (measured on the 2-core dev machine, BDF at
# 1e-13 the most); a run needing more is reported failed instead of running for many minutes in Python.
MAX_STEPS = 500_000


class ScipyIVP:
    """One of METHODS at tolerance tol (scipy's rtol = atol = tol) on a VectorSystem."""

    def __init__(self, name: str, tol: float = DEFAULT_TOLERANCE, max_steps: int = MAX_STEPS):
        if name not in METHODS:
            raise KeyError(f"unknown scipy method {name!r}; valid: {', '.join(METHODS)}")
        tol = float(tol)
        if not (math.isfinite(tol) and tol >= MIN_TOLERANCE):
            raise ValueError(f"{name}: tolerance must be finite and >= {MIN_TOLERANCE:.3g} (scipy raises a smaller "
                             f"rtol to 100 eps), got {tol!r}")
        self.name, self.method, self.tol, self.max_steps = name, METHODS[name], tol, max_steps
        self.solver_class = getattr(integrate, self.method)

    def integrate(self, system: VectorSystem, chart0: object, y0: np.ndarray, grid: TimeGrid) -> Trajectory:
        """From (chart0, y0) at t = 0 to grid.times[-1], the states recorded at grid.times from the dense output."""
        times = np.asarray(grid.times, dtype=float)
        n = times.size
        quat, omega = np.full((n, 4), np.nan), np.full((n, 3), np.nan)
        chart, y = chart0, np.array(y0, dtype=float)
        quat[0], omega[0] = system.observe(chart, y)
        limit2 = divergence_limit2(omega[0])
        rhs = system.rhs
        calls = [0]
        current = [chart]  # the chart the solver's right-hand side works in (changes between solvers only)

        def fun(t, state):
            calls[0] += 1
            # scipy hands the columns of a matrix to a non-vectorised function (finite-difference Jacobians)
            return rhs(t, current[0], np.ascontiguousarray(state))

        t, t_end, filled, steps = 0.0, float(times[-1]), 1, 0
        counters = {"nfev": 0, "njev": 0, "nlu": 0}
        status, message, diverged_at = Status.OK, "", math.nan
        with np.errstate(all="ignore"):  # overflow on the way to a divergence is an outcome, reported as one
            while t < t_end and status is Status.OK:
                solver = self.solver_class(fun, t, y, t_end, rtol=self.tol, atol=self.tol)
                restart = False
                while solver.status == "running" and not restart:
                    budget.check()  # the run's wall-time budget
                    if steps >= self.max_steps:
                        status, message = Status.FAILED, (f"scipy {self.method}: more than {self.max_steps} steps "
                                                          f"before t = {t_end:g} s (stopped at t = {solver.t:.6g} s)")
                        break
                    try:
                        step_message = solver.step()
                    except (ValueError, ArithmeticError, np.linalg.LinAlgError) as exc:  # e.g. a Jacobian not finite
                        status, first = Status.FAILED, (str(exc).splitlines() or [""])[0]
                        message = f"scipy {self.method}: {type(exc).__name__}: {first} at t = {solver.t:.6g} s"
                        break
                    if solver.status == "failed":
                        status = Status.FAILED
                        message = f"scipy {self.method}: {step_message} at t = {solver.t:.6g} s"
                        break
                    steps += 1
                    t_new, y_new = float(solver.t), solver.y
                    last = int(np.searchsorted(times, t_new, side="right"))
                    if last > filled:
                        states = solver.dense_output()(times[filled:last]).T
                        if times[last - 1] == t_new:  # the step's end: the solver's state, not its interpolant
                            states[-1] = y_new
                        for index, state in enumerate(states, start=filled):
                            quat[index], omega[index] = system.observe(chart, state)
                    # the divergence rule on the step's end and on the samples inside it; the first bad one ends it
                    bad = [i for i in range(filled, last) if not sample_good(quat[i], omega[i], limit2)]
                    if bad or not (sample_good(*system.observe(chart, y_new), limit2) and np.isfinite(y_new).all()):
                        diverged_at = float(times[bad[0]]) if bad else t_new
                        status, message = Status.DIVERGED, divergence_message(diverged_at)
                        quat[bad[0] if bad else last:], omega[bad[0] if bad else last:] = np.nan, np.nan
                        break
                    filled = last
                    try:
                        new_chart, y_next = system.rechart(chart, y_new)
                    except ArithmeticError as exc:
                        status, diverged_at, message = Status.DIVERGED, t_new, f"{exc} at t = {t_new:.6g} s"
                        quat[filled:], omega[filled:] = np.nan, np.nan
                        break
                    t, y = t_new, np.array(y_new, dtype=float)
                    if new_chart is not chart:  # the solver's history is in the old coordinates: start afresh
                        chart, y, restart = new_chart, np.array(y_next, dtype=float), True
                        current[0] = chart
                for key in counters:
                    counters[key] += int(getattr(solver, key, 0))
                if solver.status == "finished" and status is Status.OK:
                    t = t_end
        if status is Status.FAILED:
            quat[filled:], omega[filled:] = np.nan, np.nan
        elif status is Status.OK and filled < n:
            raise ValueError(f"scipy {self.method} ended at t = {t:.6g} s with {n - filled} samples unfilled")
        info = {"tolerance": self.tol, "scipy_method": self.method, **{f"scipy_{k}": v for k, v in counters.items()}}
        return Trajectory(grid.times, quat, omega, status, message, diverged_at, steps, calls[0], info,
                          system.chart_changes(chart))
