"""Adding a scene means a scene module plus each supporting engine's model (issue 20): a toy third scene, a physical
pendulum about a fixed horizontal axis, defined here and nowhere else, registered, given a model on the reference
engine, and run by `stereodyn run` (plan, truth, the one run -> row path, store, work–precision phase, report)."""
from __future__ import annotations

import dataclasses
import math
from pathlib import Path

import numpy as np
import pandas as pd
import pytest
from scipy.integrate import solve_ivp

from stereodyn.harness import cli, integrators, scenes
from stereodyn.harness.engines.base import SceneModel
from stereodyn.harness.engines.reference import ReferenceEngine
from stereodyn.harness.scenes.checks import ROW_KEY
from stereodyn.harness.trajectory import Status

KIND = "physical_pendulum"
TOP = (frozenset({"name", "description", "tags", "kind", "pendulum", "run"}), frozenset({"kind", "pendulum", "run"}))
PENDULUM = (frozenset({"mass", "distance", "inertia", "g", "theta0", "omega0"}),
            frozenset({"mass", "distance", "inertia", "g", "theta0"}))


@dataclasses.dataclass(frozen=True, eq=False)
class PendulumCase:
    """I θ'' = -m g d sin θ: inertia I (kg m², about the axis), d (m, axis -> centre of mass), θ from the downward
    vertical (rad), ω = θ' (rad/s)."""

    name: str
    description: str
    tags: tuple[str, ...]
    mass: float
    distance: float
    inertia: float
    g: float
    theta0: float
    omega0: float
    t_end: float
    dt: tuple[float, ...]
    samples: int
    path: Path | None = None
    kind: str = KIND

    def rate(self, y: np.ndarray) -> np.ndarray:
        return np.array([y[1], -self.mass * self.g * self.distance / self.inertia * math.sin(y[0])])

    def energy(self, theta: np.ndarray, omega: np.ndarray) -> np.ndarray:
        return 0.5 * self.inertia * omega ** 2 - self.mass * self.g * self.distance * np.cos(theta)


@dataclasses.dataclass
class PendulumTrajectory:
    times: np.ndarray
    state: np.ndarray  # (n, 2): θ, ω
    status: Status = Status.OK
    message: str = ""
    diverged_at: float = math.nan


@dataclasses.dataclass(frozen=True)
class PendulumTruth:
    times: np.ndarray
    state: np.ndarray

    def on(self, grid) -> np.ndarray:
        return self.state[np.searchsorted(self.times, grid.times)]


class PendulumScene:
    """The scene module: its TOML, its truth, its metrics and checks, its columns."""

    kind = KIND
    title = "the physical pendulum"
    needs_truth = True
    keeps_states = False
    work_precision = False
    # swing_amplitude (rad, max |θ| over the samples) is this scene's own column: results.csv and the report carry it
    columns = ("energy_drift", "attitude_err", "attitude_err_end", "omega_err", "torque_mode", "swing_amplitude")

    def parse(self, parser, data: dict) -> PendulumCase:
        parser.table(data, "", TOP)
        name, description, tags = parser.words(data)
        table = parser.table(data["pendulum"], "pendulum", PENDULUM)
        t_end, dt, samples = parser.run(data["run"])
        return PendulumCase(name, description, tags, *(parser.positive(table[k], f"pendulum.{k}")
                                                        for k in ("mass", "distance", "inertia", "g")),
                            parser.number(table["theta0"], "pendulum.theta0"),
                            parser.number(table.get("omega0", 0.0), "pendulum.omega0"), t_end, dt, samples,
                            Path(parser.path))

    def truth(self, case: PendulumCase, grids, certify: bool) -> PendulumTruth:
        times = np.unique(np.concatenate([g.times for g in grids]))
        solution = solve_ivp(lambda t, y: case.rate(y), (0.0, times[-1]), [case.theta0, case.omega0],
                             method="DOP853", t_eval=times, rtol=1e-13, atol=1e-13)
        return PendulumTruth(times, solution.y.T)

    def metrics(self, run, model, traj: PendulumTrajectory, grid, truth, full, rerun, keep_states=False) -> dict:
        case, (theta, omega) = run.case, traj.state.T
        energy = case.energy(theta, omega)
        scale = abs(case.energy(case.theta0, 0.0)) + 0.5 * case.inertia * case.omega0 ** 2
        out = {"torque_mode": "none", "energy_drift": float(np.max(np.abs(energy - energy[0]))) / scale,
               "swing_amplitude": float(np.max(np.abs(theta)))}
        if truth is not None:
            exact = truth.on(grid)
            angle = np.abs(theta - exact[:, 0])
            out.update(attitude_err=float(angle.max()), attitude_err_end=float(angle[-1]),
                       omega_err=float(np.max(np.abs(omega - exact[:, 1])) / np.max(np.abs(exact[:, 1]))))
        if full:
            out[ROW_KEY] = [{"quantity": "energy_drift", "theory": 0.0, "measured": out["energy_drift"],
                             "error": out["energy_drift"]}]
        return out


class PendulumSystem:
    """The pendulum as a harness vector system (no charts): y = (θ, ω)."""

    def __init__(self, case: PendulumCase):
        self.rhs = lambda t, chart, y: case.rate(y)

    @staticmethod
    def rechart(chart, y):
        return chart, y


class PendulumModel(SceneModel):
    """The reference engine's model of the pendulum: the registry's vector integrators on PendulumSystem."""

    def integrators(self, chosen: list[str]) -> list[str]:
        return [name for name in chosen if name in integrators.names(state_space="vector")]

    def prepare(self, case, variant, integrator, dt, tolerance=None):
        step = integrators.get(integrator, state_space="vector")().stepper(PendulumSystem(case), dt)

        class Simulation:
            def run(self, grid) -> PendulumTrajectory:
                y, done, state = np.array([case.theta0, case.omega0]), 0, [[case.theta0, case.omega0]]
                for target in grid.sample_steps[1:].tolist():
                    for k in range(done, target):
                        _, y = step(k * grid.dt, None, y)
                    done = target
                    state.append(y)
                return PendulumTrajectory(grid.times, np.array(state))

        return Simulation()


@pytest.fixture
def pendulum_scene(monkeypatch):
    scenes.register(PendulumScene())
    original = ReferenceEngine.models
    monkeypatch.setattr(ReferenceEngine, "models", lambda self: {**original(self), KIND: PendulumModel()})
    yield
    scenes.unregister(KIND)


CASE = """kind = "physical_pendulum"
name = "toy-pendulum"
[pendulum]
mass = 2.0
distance = 0.5
inertia = 0.75
g = 9.81
theta0 = 1.0
[run]
t_end = 4.0
dt = [2e-2, 1e-2]
samples = 201
"""


def test_a_toy_scene_runs_through_a_sweep_and_the_report(pendulum_scene, tmp_path):
    path = tmp_path / "pendulum.toml"
    path.write_text(CASE)
    out = tmp_path / "out"
    assert cli.main(["run", "--case-file", str(path), "--engines", "reference,mujoco", "--integrators", "rk4,euler",
                     "--jobs", "1", "--quiet", "--out", str(out)]) == 0
    df = pd.read_csv(out / "results.csv")
    rows = df[df.engine == "reference"].set_index(["integrator", "dt"])
    assert set(rows.index) == {("rk4", 2e-2), ("rk4", 1e-2), ("euler", 2e-2), ("euler", 1e-2)}
    assert (rows.status == "ok").all() and (df.case == "toy-pendulum").all()
    # the reference integrators converge at their declared orders on the new scene (4: error ratio 16 per halving,
    # 1: 2); measured 15.7 and 2.32 (explicit Euler's error is 0.4-0.9 rad here, not yet asymptotic): the bounds hold
    # an order within ~0.4 of the declared one and no neighbouring order
    rk4 = rows.loc[("rk4", 2e-2), "attitude_err"] / rows.loc[("rk4", 1e-2), "attitude_err"]
    euler = rows.loc[("euler", 2e-2), "attitude_err"] / rows.loc[("euler", 1e-2), "attitude_err"]
    assert 12.0 < rk4 < 21.0 and 1.6 < euler < 3.0
    # energy: RK4 1.0e-8 at dt 1e-2, Euler 0.45 (it pumps energy in)
    assert rows.loc[("rk4", 1e-2), "energy_drift"] < 1e-7 and rows.loc[("euler", 1e-2), "energy_drift"] > 1e-2
    assert np.isfinite(rows.wall_s).all()  # the timing phase timed them, through the same prepare
    # the scene's own column reaches results.csv: released from rest at 1 rad, RK4 swings back to 1 rad (measured
    # 1 - 1e-7 at dt 1e-2), Euler pumps energy in and swings wider (measured 1.32); the bounds hold 1e-4 and 1.05
    assert abs(rows.loc[("rk4", 1e-2), "swing_amplitude"] - 1.0) < 1e-4
    assert rows.loc[("euler", 1e-2), "swing_amplitude"] > 1.05
    assert list(df.columns)[-1] == "swing_amplitude"
    # an engine without a model of the scene: one skipped row saying so
    mujoco = df[df.engine == "mujoco"]
    assert len(mujoco) == 1 and mujoco.status.iloc[0] == "skipped"
    assert mujoco.message.iloc[0] == "mujoco adapter does not model the physical pendulum"
    checks = pd.read_csv(out / "checks.csv")
    assert set(checks[checks.case == "toy-pendulum"].quantity) >= {"energy_drift"}
    report = (out / "report.md").read_text()
    assert "toy-pendulum" in report and (out / "report.html").is_file()
    # ... and the report's table of the case (its header row names it; the value of RK4 at dt 1e-2 shows as 1.00e+00)
    section = report[report.index("### toy-pendulum"):]
    header = next(line for line in section.splitlines() if line.startswith("| engine"))
    assert header.rstrip(" |").endswith("swing_amplitude")


def test_without_the_scene_the_kind_is_unknown(tmp_path):
    path = tmp_path / "pendulum.toml"
    path.write_text(CASE)
    assert cli.main(["run", "--case-file", str(path), "--out", str(tmp_path / "out"), "--quiet"]) == 2
