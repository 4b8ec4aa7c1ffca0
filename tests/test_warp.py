"""The MuJoCo Warp engine (harness/engines/warp.py, the optional extra stereodyn[warp]): agreement with MuJoCo C to
float32, the captured graph against plain stepping, the default sweep's coarse step, and the message when the extra
is missing. Skipped where mujoco-warp is not installed (but the missing-extra test runs). The first use of Warp on a
machine compiles its kernels (~40 s, then cached on disk: ~1 s)."""
from __future__ import annotations

import dataclasses
import subprocess
import sys

import numpy as np
import pytest
from helpers import assert_skipped_without_sdk

from stereodyn.harness.scenes.cases import find_case, with_overrides
from stereodyn.harness.engines import get_engine
from stereodyn.harness.engines.declared import rigid_body
from stereodyn.harness.grid import time_grid
from stereodyn.harness.trajectory import Status


@pytest.fixture(scope="module")
def warp():
    pytest.importorskip("mujoco_warp")
    return get_engine("warp")


def _case(name, t_end, samples=101):
    return dataclasses.replace(with_overrides(find_case(name), t_end=t_end), samples=samples)


def test_without_the_extra_the_rows_are_skipped_naming_the_install_command():
    assert_skipped_without_sdk("warp", "mujoco_warp")


@pytest.mark.parametrize("integrator", ["euler", "rk4"])
def test_agrees_with_mujoco_c_to_float32(warp, integrator):
    """heavy-asymmetric, 2 s at dt 0.01: MuJoCo Warp is MuJoCo C 4.0's algorithm in float32 (measured 3e-7 to 1e-5
    over 2-20 s, both integrators): bound 1e-4; and not float64 (a difference above 1e-9)."""
    case = _case("heavy-asymmetric", 2.0)
    grid = time_grid(case.t_end, 0.01, case.samples)
    c = get_engine("mujoco").prepare(case, integrator, 0.01).run(grid)
    traj = warp.prepare(case, integrator, 0.01).run(grid)
    assert traj.status is Status.OK and traj.steps == 200
    diff = max(np.max(np.abs(traj.quat - c.quat)), np.max(np.abs(traj.omega - c.omega)))
    assert 1e-9 < diff <= 1e-4


def test_the_captured_graph_steps_as_plain_stepping_and_runs_restart(warp):
    """The replayed graph (prepare's capture) gives bit for bit what mujoco_warp.step launched from Python gives, and
    a second run starts from the initial state again (the reset graph)."""
    import mujoco_warp as mjw
    import warp as wp

    case = _case("kovalevskaya", 0.5, samples=3)
    sim = warp.prepare(case, "euler", 0.01)
    grid = time_grid(case.t_end, 0.01, case.samples)
    first, second = sim.run(grid), sim.run(grid)
    assert np.array_equal(first.quat, second.quat) and np.array_equal(first.omega, second.omega)
    with wp.ScopedDevice("cpu"):
        data = mjw.put_data(*_host(case))
        for _ in range(grid.steps):
            mjw.step(sim.model, data)
        assert np.array_equal(data.qpos.numpy()[0], first.quat[-1].astype(np.float32))
        assert np.array_equal(data.qvel.numpy()[0], first.omega[-1].astype(np.float32))


def _host(case):
    from stereodyn.harness.engines.warp import compiled_model

    return compiled_model(case, "euler", 0.01)


def test_default_sweep_is_euler_and_rk4_at_a_coarse_step_on_the_general_cases(warp):
    heavy, turning = find_case("heavy-asymmetric"), find_case("central-field-turning")
    model = rigid_body(warp)
    assert warp.offer("euler").precisions == ("float32",)
    assert model.default_run(heavy, "", "euler") and not model.default_run(find_case("hess"), "", "euler")
    assert model.default_dts(heavy, "euler", heavy.dt) == (0.01,)  # 0.3 is beyond Euler's stability
    assert not model.default_run(turning, "", "euler") and "per-stage callback" in model.unsupported_run(turning, "",
                                                                                                        "euler")


def test_a_sweep_on_a_machine_without_a_gpu_keeps_stderr_empty(warp, tmp_path):
    """Warp's C code prints "Could not find or load the NVIDIA CUDA driver" to file descriptor 2 at init on a machine
    without a GPU: the adapter silences it, so `run --quiet` prints nothing (seen in every worker's output before)."""
    child = subprocess.run([sys.executable, "-m", "stereodyn", "run", "free-asymmetric", "--engines", "warp",
                            "--integrators", "euler", "--t-end", "0.1", "--dt", "1e-2", "--no-ladder", "--jobs", "1",
                            "--quiet", "--out", str(tmp_path / "out")], capture_output=True, text=True, timeout=300)
    assert child.returncode == 0, child.stderr
    assert child.stderr == "", child.stderr
