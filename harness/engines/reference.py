"""The reference engine: the classical formulations of reference.formulations, each integrated by heyoka (integrator
`taylor`, adaptive, truth grade; formulation quaternion with taylor is the truth row), by scipy's solve_ivp methods
(scipy_rk45, scipy_dop853, scipy_radau, scipy_bdf, scipy_lsoda: adaptive, harness.integrators.scipy_ivp) and by the
harness's fixed-step integrators of state space "vector" applied to the formulation's coordinates, with chart changes
between steps.
"""
from __future__ import annotations

import numpy as np

from .. import integrators
from .. import budget
from ..scenes.cases import Case
from ..trajectory import SlidingLadderTrajectory, Status, Trajectory, diverged_trajectory
from .base import RIGID_BODY, SLIDING_LADDER, About, Engine, Offer, RigidBodyModel, SceneModel, Timing, singular_torque
from ..grid import TimeGrid
from ..integrators import scipy_ivp
from ...reference import formulations as ref_formulations  # the module; `formulations` is the engine's method
from ...reference import sliding_ladder as ref_ladder
from ...reference.formulations import Chart, ChartSingularity, Formulation
from ...reference.truth import check_tolerance as truth_tolerance

TAYLOR = "taylor"
# The scipy methods a sweep that names no integrators runs, on the quaternion formulation only (SceneModel.default_run).
# Measured on the 2-core dev machine, one run of each at tol 1e-8 over the 25 rigid-body cases of the suite: RK45 1.0 s,
# DOP853 0.5 s, LSODA 0.5 s, Radau 5.7 s, BDF 3.0 s in all; a row costs about 4 runs (accuracy, checks, timing), and
# each charted formulation as much again. The implicit Radau and BDF (for stiff problems, which these scenes are not)
# and the charted formulations run in the tolerance ladders and with --integrators.
DEFAULT_SCIPY = ("scipy_rk45", "scipy_dop853", "scipy_lsoda")
STATE_SPACE = "vector"
SLIDING_LADDER_EQUATION = "theta"  # the sliding ladder's equation of motion in θ (reference.sliding_ladder)


class FormulationSystem:
    """A formulation as a harness VectorSystem: charts are reference.formulations.Chart, y the formulation's state.

    chart_changes False: the coordinates are never re-charted, and reaching their singularity raises
    ChartSingularity (an ArithmeticError), which ends the run as diverged with the singularity named.
    compiled: the right-hand side is the formulation's heyoka equations compiled to a function (3.5-8 µs a call),
    else its numpy implementation (~100 µs a call on one state: for cross-checks, not for sweeps).
    """

    def __init__(self, formulation: Formulation, chart_changes: bool = True, compiled: bool = True):
        self.formulation = formulation
        self.enabled = chart_changes
        # bound once: it is the hot path
        self.rhs = formulation.fast_rhs if compiled else formulation.rhs

    def rechart(self, chart: Chart, y: np.ndarray) -> tuple[Chart, np.ndarray]:
        return self.formulation.check_chart(chart, y, self.enabled)

    def observe(self, chart: Chart, y: np.ndarray) -> tuple[tuple, tuple]:
        return self.formulation.observe_one(chart, y)

    def chart_changes(self, chart: Chart) -> int | None:
        return chart.changes if self.formulation.charted else None


class TaylorSimulation:
    """A formulation integrated by heyoka at tolerance tol (None: the truth's); run() starts from the case's initial
    state every time. rhs_evals stays 0: a Taylor step computes the series' coefficients, not stages of the
    right-hand side, so there is no count to compare with the other methods'."""

    def __init__(self, case: Case, formulation: str, chart_changes: bool = True, tol: float | None = None):
        self.case, self.formulation, self.chart_changes, self.tol = case, formulation, chart_changes, tol

    def run(self, grid: TimeGrid) -> Trajectory:
        result = ref_formulations.integrate_taylor(self.formulation, self.case.body, self.case.quat0, self.case.omega0,
                                                   grid.times, chart_changes=self.chart_changes, tol=self.tol,
                                                   deadline=budget.deadline())  # OutOfTime: the run's budget
        status = Status.DIVERGED if result.message else Status.OK
        return Trajectory(grid.times, result.quat, result.omega, status, result.message, result.stopped_at,
                          steps=result.steps, info={"wall_s": result.wall_s}, chart_changes=result.chart_changes)


class _CoordinateSimulation:
    """A formulation's coordinates stepped by a harness-side method (integrate(system, chart, y, grid)); run() starts
    from the case's state every time, and a start on a chart singularity is a diverged run at t = 0."""

    def __init__(self, case: Case, formulation: str, method, chart_changes: bool = True, compiled: bool = True):
        self.case, self.method = case, method
        self.formulation = ref_formulations.get(formulation, case.body)
        self.system = FormulationSystem(self.formulation, chart_changes, compiled)
        ref_formulations.compiled_rhs(formulation)  # compile here, not in the timed run

    def run(self, grid: TimeGrid) -> Trajectory:
        try:
            chart, y = self.formulation.start(self.case.quat0, self.case.omega0, self.system.enabled)
        except ChartSingularity as exc:
            n = grid.times.size
            return diverged_trajectory(grid, np.full((n, 4), np.nan), np.full((n, 3), np.nan), 0, 0.0, 0,
                                       message=f"{exc} at t = 0 s")
        return self.method.integrate(self.system, chart, y, grid)


class ScipySimulation(_CoordinateSimulation):
    """A formulation integrated by one of scipy's solve_ivp methods (harness.integrators.scipy_ivp), the states taken
    from its dense output on the grid's sample times."""

    def __init__(self, case: Case, formulation: str, method: scipy_ivp.ScipyIVP, chart_changes: bool = True):
        super().__init__(case, formulation, method, chart_changes)


class FixedStepSimulation(_CoordinateSimulation):
    """A formulation stepped by a vector-state integrator with a fixed dt."""

    def __init__(self, case: Case, formulation: str, integrator: integrators.Integrator, dt: float,
                 chart_changes: bool = True, compiled: bool = True):
        super().__init__(case, formulation, integrator, chart_changes, compiled)
        self.integrator, self.dt = integrator, dt

    def run(self, grid: TimeGrid) -> Trajectory:
        if grid.dt != self.dt:
            raise ValueError(f"grid dt {grid.dt} differs from the prepared dt {self.dt}")
        return super().run(grid)


class SlidingLadderEquation:
    """The sliding ladder's equation (reference.sliding_ladder), solved by heyoka with the detachment as an event."""

    def __init__(self, ladder):
        self.ladder = ladder

    def run(self, grid: TimeGrid) -> SlidingLadderTrajectory:
        motion = ref_ladder.solve(self.ladder, grid.times, deadline=budget.deadline())
        state = ref_ladder.planar_state(self.ladder, motion.theta, motion.theta_dot)
        return SlidingLadderTrajectory(grid.times, state, ref_ladder.constraint_violation(self.ladder, state),
                                       steps=grid.steps, detach_angle=motion.detach_angle)


class LadderEquationModel(SceneModel):
    """The sliding ladder's equation (harness.scenes.sliding_ladder), on heyoka whatever the sweep's integrators."""

    def variants(self) -> tuple[str, ...]:
        return (SLIDING_LADDER_EQUATION,)

    def integrators(self, chosen: list[str]) -> list[str]:
        return [TAYLOR]

    def prepare(self, case, variant: str, integrator: str, dt: float | None,
                tolerance: float | None = None) -> SlidingLadderEquation:
        if (variant, integrator) != (SLIDING_LADDER_EQUATION, TAYLOR):
            raise KeyError(f"the reference engine solves the sliding ladder's equation only "
                           f"({SLIDING_LADDER_EQUATION!r} with {TAYLOR!r}), not {variant!r} with {integrator!r}")
        return SlidingLadderEquation(case.ladder)


class ReferenceRigidBody(RigidBodyModel):
    """The rigid body in the reference formulations: each a variant; the torque in the right-hand side."""

    def variants(self) -> tuple[str, ...]:
        return tuple(ref_formulations.FORMULATIONS)

    def default_run(self, case: Case, variant: str, integrator: str) -> bool:
        """scipy's methods: DEFAULT_SCIPY on the quaternion formulation; everything else runs."""
        if integrator in scipy_ivp.METHODS:
            return integrator in DEFAULT_SCIPY and variant == ref_formulations.Quaternion.name
        return True

    def torque_mode(self, case: Case) -> str:
        return "rhs" if case.body.has_external_torque else "none"


class ReferenceEngine(Engine):
    """Formulations quaternion, gibbs, gibbs_hamiltonian, euler_zxz; integrators taylor, scipy's (scipy_ivp.METHODS)
    and the registry's "vector" ones (euler, rk4, then plug-ins)."""

    name = "reference"
    # measured on the suite's four general cases (2-core AMD EPYC): 5.6-7.5 µs per stage per step; Python step loops
    # over compiled right-hand sides: nothing is built per grid length (a short warm-up)
    timing = Timing(pass_us=6.5, short_warm_up=True)
    about = About(packages=("heyoka",), linestyle=":", state_space=STATE_SPACE,
                  formulation=ref_formulations.Quaternion.name)

    def models(self) -> dict:
        return {**super().models(), RIGID_BODY: ReferenceRigidBody(self), SLIDING_LADDER: LadderEquationModel()}

    def integrators(self) -> tuple[str, ...]:
        return (TAYLOR,) + tuple(scipy_ivp.METHODS) + integrators.names(state_space=STATE_SPACE)

    def offer(self, integrator: str) -> Offer:
        return Offer(adaptive=integrator == TAYLOR or integrator in scipy_ivp.METHODS)

    def unsupported(self, case: Case) -> str | None:
        return singular_torque(case)

    def prepare(self, case: Case, integrator: str | type[integrators.Integrator], dt: float | None,
                formulation: str = ref_formulations.Quaternion.name, chart_changes: bool = True,
                tolerance: float | None = None) -> TaylorSimulation | ScipySimulation | FixedStepSimulation:
        """chart_changes False follows each chart into its singularity (the run then ends diverged, naming it).
        tolerance (Engine.prepare): heyoka's tol for taylor (None: the truth's, 1e-16), scipy's rtol = atol for the
        scipy methods (None: scipy_ivp.DEFAULT_TOLERANCE, 1e-8); ignored by the fixed-step integrators."""
        if formulation not in ref_formulations.FORMULATIONS:
            raise KeyError(f"unknown formulation {formulation!r}; valid: {', '.join(ref_formulations.FORMULATIONS)}")
        if integrator == TAYLOR:
            return TaylorSimulation(case, formulation, chart_changes,
                                    None if tolerance is None else truth_tolerance(tolerance))
        if isinstance(integrator, str) and integrator in scipy_ivp.METHODS:
            method = scipy_ivp.ScipyIVP(integrator, scipy_ivp.DEFAULT_TOLERANCE if tolerance is None else tolerance)
            return ScipySimulation(case, formulation, method, chart_changes)
        try:
            cls = integrators.get(integrator, state_space=STATE_SPACE)
        except KeyError:
            raise KeyError(f"unknown integrator {integrator!r} for the reference engine; "
                           f"valid: {', '.join(self.integrators())}") from None
        if cls.state_space != STATE_SPACE:
            raise KeyError(f"integrator {cls.name!r} works on state space {cls.state_space!r}, not {STATE_SPACE!r}; "
                           f"valid: {', '.join(self.integrators())}")
        if dt is None or not dt > 0:
            raise ValueError(f"integrator {cls.name!r} needs a step dt > 0, got {dt!r}")
        return FixedStepSimulation(case, formulation, cls(), float(dt), chart_changes)
