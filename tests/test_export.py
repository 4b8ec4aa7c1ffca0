"""stereodyn export: the MJCF loads in MuJoCo and the URDF in Pinocchio, each with the adapter's dynamics."""
import mujoco
import numpy as np
import pinocchio as pin
import pytest

from stereodyn.harness import cli
from stereodyn.harness.scenes.cases import load_suite
from stereodyn.harness.engines.mujoco import MujocoEngine
from stereodyn.harness.engines.pinocchio import PinocchioSystem, build_model
from stereodyn.reference.euler_poisson import omega_dot
from stereodyn.reference.rotations import matrix_to_quat

# Scenes whose torque enters at run time (or that are not a body with a fixed point) have no exported model:
# test_a_case_the_adapters_cannot_model_is_bad_input.
SUITE = {case.name: case for case in load_suite() if case.kind == "rigid_body" and not case.body.has_external_torque}
# Same state, same dynamics: agreement to round-off. 1e-12 relative leaves room for the URDF's gimbal chart
# (angles from R, rates through the 3x3 joint Jacobian, cos(pitch) >= 0.36 below).
RTOL = 1e-12


def _rotation(axis: int, angle: float) -> np.ndarray:
    c, s = np.cos(angle), np.sin(angle)
    i, j = [(1, 2), (2, 0), (0, 1)][axis]
    r = np.eye(3)
    r[i, i], r[i, j], r[j, i], r[j, j] = c, -s, s, c
    return r


def states(case, count=5, seed=7):
    """Attitudes away from the gimbal's singular pitch (|pitch| <= 1.2 rad), angular velocities at the case's scale.
    Yields (yaw, pitch, roll), R (body -> world), omega (rad/s, body)."""
    rng = np.random.default_rng(seed)
    scale = max(1.0, float(np.linalg.norm(case.omega0)))
    for _ in range(count):
        yaw, roll = rng.uniform(-np.pi, np.pi, 2)
        pitch = rng.uniform(-1.2, 1.2)
        rotation = _rotation(2, yaw) @ _rotation(1, pitch) @ _rotation(0, roll)
        yield (yaw, pitch, roll), rotation, rng.normal(size=3) * scale


def close(got, want):
    assert np.linalg.norm(got - want) <= RTOL * max(1.0, np.linalg.norm(want)), (got, want)


def export(tmp_path, name, fmt):
    path = tmp_path / f"{name}.{'xml' if fmt == 'mjcf' else 'urdf'}"
    assert cli.main(["export", name, "--format", fmt, "--out", str(path)]) == 0
    return path


@pytest.mark.parametrize("name", sorted(SUITE))
def test_the_exported_mjcf_has_the_adapters_dynamics(tmp_path, name):
    case = SUITE[name]
    model = mujoco.MjModel.from_xml_path(str(export(tmp_path, name, "mjcf")))
    data = mujoco.MjData(model)
    adapter = MujocoEngine().prepare(case, "rk4", case.dt[0]).model
    adapter_data = mujoco.MjData(adapter)
    assert model.opt.timestep == case.dt[0] and model.opt.integrator == mujoco.mjtIntegrator.mjINT_RK4
    for _, rotation, omega in states(case):
        for m, d in ((model, data), (adapter, adapter_data)):
            d.qpos[:] = matrix_to_quat(rotation)
            d.qvel[:] = omega
            mujoco.mj_forward(m, d)
        close(data.qacc, adapter_data.qacc)
        close(data.qacc, omega_dot(case.body, matrix_to_quat(rotation), omega))


@pytest.mark.parametrize("name", sorted(SUITE))
def test_the_exported_urdf_has_the_adapters_dynamics(tmp_path, name):
    """The gimbal's state is mapped from (R, omega): angles from R, rates from omega through the joint Jacobian;
    the body's angular acceleration is read back from Pinocchio's forward kinematics."""
    case = SUITE[name]
    model = pin.buildModelFromUrdf(str(export(tmp_path, name, "urdf")))
    model.gravity.linear = case.body.gravity * np.asarray(case.body.gravity_direction)
    data = model.createData()
    body = model.getJointId("roll")
    assert model.nv == 3 and [model.names[i] for i in range(1, 4)] == ["yaw", "pitch", "roll"]
    adapter = PinocchioSystem(build_model(case))
    for angles, rotation, omega in states(case):
        q = pin.neutral(model)
        for joint, angle in zip(model.joints[1:], angles):
            # continuous joints are unbounded revolutes, stored (cos, sin); a bounded one would store the angle
            q[joint.idx_q:joint.idx_q + joint.nq] = [np.cos(angle), np.sin(angle)] if joint.nq == 2 else [angle]
        pin.forwardKinematics(model, data, q)
        assert np.allclose(data.oMi[body].rotation, rotation, rtol=0, atol=1e-14)
        jacobian = pin.computeJointJacobian(model, data, q, body)[3:]  # angular rows, body frame
        rates = np.linalg.solve(jacobian, omega)
        accelerations = pin.aba(model, data, q, rates, np.zeros(3))
        pin.forwardKinematics(model, data, q, rates, accelerations)
        close(data.v[body].angular, omega)
        w, x, y, z = matrix_to_quat(rotation)
        close(data.a[body].angular, adapter.accel(0.0, np.array([x, y, z, w]), omega))


def test_export_to_standard_output(capsys):
    assert cli.main(["export", "kovalevskaya", "--format", "urdf"]) == 0
    out = capsys.readouterr().out
    assert out.startswith("<?xml") and '<robot name="kovalevskaya">' in out and out.count('type="continuous"') == 3
    assert cli.main(["export", "kovalevskaya", "--format", "mjcf", "--integrator", "euler", "--dt", "0.002"]) == 0
    out = capsys.readouterr().out
    assert 'integrator="Euler"' in out and 'timestep="0.002"' in out


def test_a_case_the_adapters_cannot_model_is_bad_input(tmp_path, capsys):
    spun = tmp_path / "spun.toml"
    spun.write_text("[body]\nmass = 1.0\ncom = [0.0, 0.0, 0.0]\nprincipal_moments = [1.0, 1.0, 1.5]\n"
                    "[body_torque]\naxis = [0.0, 0.0, 1.0]\na = 0.5\nb = 0.0\n"
                    "[initial]\nattitude = { quaternion = [1.0, 0.0, 0.0, 0.0] }\nomega = [0.0, 0.0, 1.0]\n"
                    "[run]\nt_end = 1.0\ndt = [0.1]\n")
    for fmt in ("mjcf", "urdf"):
        assert cli.main(["export", str(spun), "--format", fmt]) == 2
        err = capsys.readouterr().err
        assert "[body_torque]" in err and err.count("\n") == 1
    assert cli.main(["export", "lagrange-top", "--format", "mjcf", "--integrator", "verlet"]) == 2
    assert "unknown MuJoCo integrator" in capsys.readouterr().err
