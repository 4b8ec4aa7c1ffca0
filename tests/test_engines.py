"""MuJoCo and Pinocchio adapters: conventions, cross-engine agreement, convergence orders, divergence handling."""
from __future__ import annotations

import functools
import math
import xml.etree.ElementTree as ET

import mujoco
import numpy as np
import pytest

import stereodyn.harness.integrators as integrators
from stereodyn.harness.analysis.fitting import order_slope
from stereodyn.harness.scenes.cases import Case
from stereodyn.harness.trajectory import DIVERGENCE_FACTOR, Status
from stereodyn.harness.grid import time_grid
from stereodyn.harness.integrators import ButcherTableau, ExplicitRK
from stereodyn.reference import truth as reference_truth
from stereodyn.reference.torque_models import BodyTorque, CentralField
from stereodyn.reference.euler_poisson import omega_dot
from stereodyn.reference.rotations import attitude_angle, quat_mul, quat_to_matrix
from stereodyn.harness.engines import mujoco as mujoco_engine  # noqa: E402  (base dependencies: a broken
from stereodyn.harness.engines import pinocchio as pinocchio_engine  # noqa: E402  adapter must fail, not skip)
MUJOCO = mujoco_engine.MujocoEngine()
PINOCCHIO = pinocchio_engine.PinocchioEngine()
ENGINES = {"mujoco": MUJOCO, "pinocchio": PINOCCHIO}


@pytest.fixture(autouse=True)
def clean_cwd(tmp_path, monkeypatch):
    """MuJoCo writes MUJOCO_LOG.TXT into the working directory on a warning: keep it out of the repository."""
    monkeypatch.chdir(tmp_path)
    return tmp_path


def zxz_quat(phi: float, theta: float, psi: float) -> np.ndarray:
    """Quaternion (w, x, y, z) of Rz(phi) Rx(theta) Rz(psi)."""
    def about(axis: int, angle: float) -> np.ndarray:
        q = np.zeros(4)
        q[0], q[axis] = math.cos(angle / 2), math.sin(angle / 2)
        return q
    return quat_mul(quat_mul(about(3, phi), about(1, theta)), about(3, psi))


SUITE = {
    "lagrange-top": dict(inertia=np.diag([1.0, 1.0, 0.4]), com=(0.0, 0.0, 0.2), gravity=9.81,
                         quat0=zxz_quat(0.0, 0.6, 0.0), omega0=(0.5, 0.0, 15.0)),
    "heavy-asymmetric": dict(inertia=np.array([[2.0, 0.1, -0.05], [0.1, 1.6, 0.08], [-0.05, 0.08, 1.1]]),
                             com=(0.1, -0.05, 0.25), gravity=9.81, quat0=zxz_quat(0.1, 0.7, 0.3),
                             omega0=(1.0, -0.5, 2.0)),
    "free-asymmetric": dict(inertia=np.diag([2.0, 1.5, 1.0]), com=(0.0, 0.0, 0.0), gravity=0.0,
                            quat0=zxz_quat(0.3, 0.8, -0.5), omega0=(0.4, 0.1, 2.0)),
}


def make_case(name: str, **overrides) -> Case:
    """A suite case built in code (mass 1, gravity down when present)."""
    spec = SUITE[name]
    fields = dict(name=name, description="", tags=(), mass=1.0, com=np.array(spec["com"]),
                  inertia=np.array(spec["inertia"], dtype=float), gravity=spec["gravity"],
                  gravity_direction=np.array([0.0, 0.0, -1.0]), quat0=np.array(spec["quat0"]),
                  omega0=np.array(spec["omega0"], dtype=float), t_end=10.0, dt=(1e-3,), samples=1000)
    fields.update(overrides)
    return Case(**fields)


def run(engine: str, case: Case, integrator: str, dt: float, t_end: float, samples: int):
    grid = time_grid(t_end, dt, samples)
    return grid, ENGINES[engine].prepare(case, integrator, dt).run(grid)


def angles(quat_a: np.ndarray, quat_b: np.ndarray) -> np.ndarray:
    """Geodesic angle (rad) between attitudes, sample by sample."""
    return attitude_angle(quat_to_matrix(quat_a), quat_to_matrix(quat_b))


# -------------------------------------------------------------------------------------------------- conventions

def test_engine_integrators():
    # discrete from MuJoCo 3.13 (mjtIntegrator; the list is read from the installed MuJoCo: tests/test_engine_sdk.py)
    expected = ("euler", "implicit", "implicitfast", "rk4") + (("discrete",) if hasattr(
        mujoco.mjtIntegrator, "mjINT_DISCRETE") else ())
    assert MUJOCO.name == "mujoco" and MUJOCO.integrators() == expected
    assert PINOCCHIO.name == "pinocchio"
    assert PINOCCHIO.integrators()[:4] == ("euler", "symplectic_euler", "rk4", "rk4_naive")


@pytest.mark.parametrize("name", SUITE)
def test_first_step_acceleration_is_euler_poisson(name):
    """Both models have the case's dynamics: inertia about O from the centre-of-mass form, gravity, frames."""
    case, dt = make_case(name), 1e-6
    expected = omega_dot(case.body, case.quat0, case.omega0)
    # MuJoCo's Euler: omega_1 = omega_0 + dt a(q_0, omega_0), one rounding; dividing by dt amplifies it to ~1e-11.
    _, first = run("mujoco", case, "euler", dt, dt, 2)
    np.testing.assert_allclose((first.omega[1] - case.omega0) / dt, expected, rtol=0, atol=1e-9)
    system = PINOCCHIO.prepare(case, "euler", dt).system
    q = np.array([*case.quat0[1:], case.quat0[0]])
    np.testing.assert_allclose(system.accel(0.0, q, case.omega0), expected, rtol=0, atol=1e-12)


@pytest.mark.parametrize("engine", ENGINES)
def test_initial_sample_is_the_case_state(engine):
    case = make_case("heavy-asymmetric")
    _, trajectory = run(engine, case, "rk4", 1e-3, 0.01, 3)
    np.testing.assert_array_equal(trajectory.quat[0], case.quat0)
    np.testing.assert_array_equal(trajectory.omega[0], case.omega0)


@pytest.mark.parametrize("engine, integrator, stages", [("mujoco", "euler", 1), ("mujoco", "rk4", 4),
                                                       ("pinocchio", "rk4", 4)])
def test_trajectory_bookkeeping(engine, integrator, stages):
    grid, trajectory = run(engine, make_case("lagrange-top"), integrator, 1e-3, 0.5, 11)
    assert trajectory.status is Status.OK and math.isnan(trajectory.diverged_at)
    np.testing.assert_array_equal(trajectory.times, grid.times)
    assert trajectory.steps == grid.steps == 500 and trajectory.rhs_evals == stages * 500
    assert trajectory.quat.shape == (11, 4) and trajectory.omega.shape == (11, 3)


@pytest.mark.parametrize("engine", ENGINES)
def test_runs_are_repeatable(engine):
    grid = time_grid(0.2, 1e-3, 5)
    sim = ENGINES[engine].prepare(make_case("heavy-asymmetric"), "rk4", 1e-3)
    first, second = sim.run(grid), sim.run(grid)
    np.testing.assert_array_equal(first.quat, second.quat)
    np.testing.assert_array_equal(first.omega, second.omega)


def test_mujoco_chunks_do_not_change_the_result(monkeypatch):
    case = make_case("heavy-asymmetric")
    _, whole = run("mujoco", case, "rk4", 1e-3, 0.1, 101)
    monkeypatch.setattr(mujoco_engine, "CHUNK_STEPS", 7)
    _, chunked = run("mujoco", case, "rk4", 1e-3, 0.1, 101)
    np.testing.assert_array_equal(whole.quat, chunked.quat)
    np.testing.assert_array_equal(whole.omega, chunked.omega)


def test_mjcf_is_the_minimal_scene():
    case = make_case("heavy-asymmetric")
    root = ET.fromstring(mujoco_engine.mjcf(case, "rk4", 2e-3))
    option = root.find("option")
    assert option.get("integrator") == "RK4" and float(option.get("timestep")) == 2e-3
    np.testing.assert_array_equal([float(x) for x in option.get("gravity").split()], [0.0, 0.0, -9.81])
    flags = option.find("flag").attrib
    for flag in ("contact", "constraint", "equality", "frictionloss", "limit", "damper", "autoreset"):
        assert flags[flag] == "disable"
    bodies = root.findall(".//body")
    assert len(bodies) == 1 and [j.get("type") for j in bodies[0].findall("joint")] == ["ball"]
    inertial = bodies[0].find("inertial")
    I = case.body.inertia_com
    np.testing.assert_array_equal([float(x) for x in inertial.get("fullinertia").split()],
                                  [I[0, 0], I[1, 1], I[2, 2], I[0, 1], I[0, 2], I[1, 2]])
    np.testing.assert_array_equal([float(x) for x in inertial.get("pos").split()], case.com)
    free = ET.fromstring(mujoco_engine.mjcf(make_case("free-asymmetric"), "euler", 1e-3))
    assert [float(x) for x in free.find("option").get("gravity").split()] == [0.0, 0.0, 0.0]
    assert free.find("option").get("integrator") == "Euler"


def test_unknown_mujoco_integrator_lists_the_valid_ones():
    with pytest.raises(KeyError) as error:
        MUJOCO.prepare(make_case("lagrange-top"), "symplectic_euler", 1e-3)
    assert all(name in str(error.value) for name in MUJOCO.integrators())
    with pytest.raises(KeyError) as error:
        PINOCCHIO.prepare(make_case("lagrange-top"), "implicit", 1e-3)
    assert all(name in str(error.value) for name in PINOCCHIO.integrators())


@pytest.mark.parametrize("term", [BodyTorque(axis=(0.0, 0.0, 1.0), a=0.6, b=-0.2),
                                  CentralField(mu=1.0, radius=10.0, direction=(0.0, 0.0, 1.0), orbit_rate=0.0)])
def test_torques_are_modelled_by_every_engine(term):
    """Issue 5: each engine models the torque exactly (tests/test_torques.py checks how); since 0.2.0 every stage
    gets its time, so a turning field runs everywhere too."""
    case = make_case("free-asymmetric", torques=(term,))
    turning = make_case("free-asymmetric", torques=(CentralField(1.0, 10.0, (1.0, 0.0, 0.0), 0.5),))
    for engine in ENGINES.values():
        for scene in (case, turning):
            assert engine.unsupported(scene) is None
            assert engine.prepare(scene, "rk4", 1e-3).run(time_grid(0.01, 1e-3, 2)).status is Status.OK


def test_pinocchio_runs_a_plugin_integrator(monkeypatch):
    monkeypatch.setattr(integrators.registry, "_registry", dict(integrators.registry._registry))

    @integrators.register
    class Heun(ExplicitRK):
        name = "test_heun"
        order = 2
        tableau = ButcherTableau(a=((0.0, 0.0), (1.0, 0.0)), b=(0.5, 0.5), c=(0.0, 1.0))
        description = "Heun's method, Munthe-Kaas (test plug-in)"

    assert PINOCCHIO.integrators()[-1] == "test_heun"
    _, trajectory = run("pinocchio", make_case("lagrange-top"), "test_heun", 1e-3, 0.1, 3)
    assert trajectory.status is Status.OK and trajectory.rhs_evals == 2 * 100


# ------------------------------------------------------------------------------------------- engine agreement

@pytest.mark.parametrize("name", ["heavy-asymmetric", "lagrange-top"])
def test_mujoco_euler_is_symplectic_euler_on_pinocchio(name):
    case = make_case(name)
    _, mj = run("mujoco", case, "euler", 1e-3, 1.0, 1001)
    _, pn = run("pinocchio", case, "symplectic_euler", 1e-3, 1.0, 1001)
    assert angles(mj.quat, pn.quat).max() <= 1e-10
    np.testing.assert_allclose(mj.omega, pn.omega, rtol=0, atol=1e-9)


def test_rk4_of_mujoco_and_pinocchio_agree_over_10s():
    case = make_case("lagrange-top")
    _, mj = run("mujoco", case, "rk4", 1e-3, 10.0, 1001)
    _, pn = run("pinocchio", case, "rk4", 1e-3, 10.0, 1001)
    assert angles(mj.quat, pn.quat).max() <= 1e-8


# ------------------------------------------------------------------------------------------- convergence order

# The Lagrange top over 2 s (spin 15 rad/s). dts in the asymptotic range: the errors run from ~1e-2 to ~1e-8, far
# above the truth's ~1e-15 and the round-off of a few thousand steps.
FIRST_ORDER_DTS, RK_DTS, ORDER_T_END = (2e-3, 1e-3, 5e-4), (1e-2, 5e-3, 2.5e-3), 2.0
ORDER_CASES = [
    ("mujoco", "euler", FIRST_ORDER_DTS, (0.8, 1.2)),
    ("mujoco", "implicit", FIRST_ORDER_DTS, (0.8, 1.2)),
    ("mujoco", "implicitfast", FIRST_ORDER_DTS, (0.8, 1.2)),
    ("mujoco", "rk4", RK_DTS, (3.7, 4.3)),
    ("mujoco", "discrete", FIRST_ORDER_DTS, (0.8, 1.2)),
    ("pinocchio", "euler", FIRST_ORDER_DTS, (0.8, 1.2)),
    ("pinocchio", "symplectic_euler", FIRST_ORDER_DTS, (0.8, 1.2)),
    ("pinocchio", "rk4", RK_DTS, (3.7, 4.3)),
    ("pinocchio", "rk4_naive", RK_DTS, (1.7, 2.3)),
]


@functools.cache
def final_truth(name: str, t_end: float) -> np.ndarray:
    case = make_case(name)
    return reference_truth.truth(case.body, case.quat0, case.omega0, np.array([0.0, t_end])).quat[-1]


def fitted_order(dts, errors) -> float:
    """Least-squares slope of log(error) against log(dt)."""
    return order_slope(dts, errors)


@pytest.mark.parametrize("engine, integrator, dts, bounds", ORDER_CASES,
                         ids=[f"{e}-{i}" for e, i, _, _ in ORDER_CASES])
def test_fitted_convergence_order(engine, integrator, dts, bounds):
    case = make_case("lagrange-top")
    truth = final_truth(case.name, ORDER_T_END)
    errors = []
    for dt in dts:
        grid, trajectory = run(engine, case, integrator, dt, ORDER_T_END, 2)
        assert trajectory.status is Status.OK and grid.t_end == pytest.approx(ORDER_T_END, rel=1e-12)
        errors.append(float(angles(trajectory.quat[-1], truth)))
    order = fitted_order(dts, errors)
    assert bounds[0] <= order <= bounds[1], (order, errors)


# --------------------------------------------------------------------------------------------------- divergence

# Heavy-asymmetric over 20 s: MuJoCo's Euler (and the same scheme on Pinocchio) first diverges at dt = 0.25; the
# explicit Euler at dt = 0.15; the RK4s, implicit, and rk4_naive stay bounded up to dt = 1 (measured).
DIVERGING = [("mujoco", "euler", 0.3, 54), ("mujoco", "implicitfast", 0.3, 54), ("mujoco", "discrete", 0.3, 54),
             ("pinocchio", "symplectic_euler", 0.3, 54), ("pinocchio", "euler", 0.2, 64)]


@pytest.mark.parametrize("engine, integrator, dt, step", DIVERGING, ids=[f"{e}-{i}" for e, i, _, _ in DIVERGING])
def test_divergence_is_reported_at_the_exact_step(engine, integrator, dt, step, clean_cwd):
    case = make_case("heavy-asymmetric")
    grid, coarse = run(engine, case, integrator, dt, 20.0, 11)
    assert coarse.status is Status.DIVERGED and coarse.message
    assert coarse.diverged_at == pytest.approx(step * dt, rel=1e-12)
    bad = int(np.searchsorted(grid.sample_steps, step))
    assert np.isnan(coarse.quat[bad:]).all() and np.isnan(coarse.omega[bad:]).all()
    assert np.isfinite(coarse.quat[:bad]).all() and np.isfinite(coarse.omega[:bad]).all()
    # Every step recorded: the state just before diverged_at is still within the rule.
    every_grid, every = run(engine, case, integrator, dt, 20.0, grid.steps + 1)
    assert every.diverged_at == coarse.diverged_at
    limit = DIVERGENCE_FACTOR * (1.0 + np.linalg.norm(case.omega0))
    assert np.isfinite(every.quat[step - 1]).all() and np.linalg.norm(every.omega[step - 1]) <= limit
    assert np.isnan(every.omega[step:]).all()
    if engine == "mujoco":   # MuJoCo's own warning is data, not a log file in the working directory
        assert any("QACC" in w for w in every.info["mujoco_warnings"])
        assert not (clean_cwd / "MUJOCO_LOG.TXT").exists()
