"""The Genesis engine (harness/engines/genesis.py, the optional extra stereodyn[genesis]): its conventions against
MuJoCo's Euler on both models, torques, float32, and the message when the extra is missing. Skipped where genesis or
torch is not installed (but the missing-extra test runs). Importing Genesis costs 15-30 s and a first build compiles
for a minute or more (then the kernel cache serves): the tests share one module-scoped engine."""
from __future__ import annotations

import importlib
import inspect
import sys
import types

import numpy as np
import pytest
from helpers import assert_skipped_without_sdk, installed_engine

from stereodyn.harness.engines import get_engine
from stereodyn.harness.engines.declared import rigid_body
from stereodyn.harness.grid import time_grid
from stereodyn.harness.scenes.cases import find_case
from stereodyn.harness.trajectory import Status
from stereodyn.reference.rotations import attitude_angle, quat_to_matrix


@pytest.fixture(scope="module")
def genesis():
    return installed_engine("genesis")


def _against_mujoco_euler(engine, case, integrator, model, precision, seconds=2.0, dt=1e-2):
    grid = time_grid(seconds, dt, 21)
    ours = engine.prepare(case, integrator, dt, formulation=model, precision=precision).run(grid)
    theirs = get_engine("mujoco").prepare(case, "euler", dt).run(grid)
    assert ours.status is Status.OK, ours.message
    angle = float(np.max(attitude_angle(quat_to_matrix(ours.quat), quat_to_matrix(theirs.quat))))
    return ours, angle, float(np.max(np.abs(ours.omega - theirs.omega)))


class _Watched(types.ModuleType):
    """A module that counts the reads of its __file__: inspect.getmodule's walk of sys.modules reads every one."""
    reads = 0

    @property
    def __file__(self):
        _Watched.reads += 1
        return "/nowhere/stereodyn_watched.py"


def test_genesis_import_spares_inspect_its_walks_of_sys_modules(tmp_path, monkeypatch):
    """Before Genesis imports, inspect learns that no module holds importlib's frozen frames: it answers the same for
    such a frame (what Quadrants' decorators ask ~2,900 times during the import) without walking sys.modules."""
    adapter = pytest.importorskip("stereodyn.harness.engines.genesis", exc_type=ImportError)  # needs the extra
    (tmp_path / "stereodyn_frame_probe.py").write_text("import sys\nFRAME = sys._getframe(1)\n")
    monkeypatch.syspath_prepend(str(tmp_path))
    frame = importlib.import_module("stereodyn_frame_probe").FRAME  # the frame that executed the module's body
    monkeypatch.delitem(sys.modules, "stereodyn_frame_probe")
    assert frame.f_code.co_filename in adapter.IMPORT_FRAME_FILES
    monkeypatch.setitem(sys.modules, "stereodyn_watched", _Watched("stereodyn_watched"))
    monkeypatch.setattr(inspect, "modulesbyfile", {file: name for file, name in inspect.modulesbyfile.items()
                                                   if file not in adapter.IMPORT_FRAME_FILES})
    _Watched.reads = 0
    unseeded = inspect.getframeinfo(frame)
    assert _Watched.reads > 0  # without the seed, each such question walks every module
    _Watched.reads = 0
    adapter.spare_import_scans()
    assert inspect.getframeinfo(frame) == unseeded
    assert _Watched.reads == 0


def test_without_the_extra_the_rows_are_skipped_naming_the_install_command():
    assert_skipped_without_sdk("genesis", "genesis", hide_specs=True)


# heavy-asymmetric: a full inertia off the principal axes and the centre of mass off every axis, on the ball joint;
# free-asymmetric on the free joint (O is its centre of mass); self-excited-conic: a torque that depends on omega.
@pytest.mark.parametrize("name, model", [("heavy-asymmetric", "ball"), ("free-asymmetric", "free"),
                                         ("self-excited-conic", "ball")])
def test_euler_is_mujocos_euler_in_float64(genesis, name, model):
    """Genesis's euler and MuJoCo's are the same semi-implicit map: 200 steps agree to round-off (measured 1.2e-15 ..
    1.7e-15 rad, 4e-16 .. 1.9e-15 rad/s; torqued cases included). A world-frame omega, a moved inertial frame
    (align=True) or a torque in the wrong frame would be off by 1e-3 or more."""
    run, angle, omega = _against_mujoco_euler(genesis, find_case(name), "euler", model, "float64")
    assert angle < 1e-12 and omega < 1e-12
    assert run.info["torque_mode"] == ("step" if find_case(name).body.has_external_torque else "none")


def test_float32_is_within_single_precision_and_implicitfast_keeps_a_free_bodys_energy(genesis):
    """float32 euler on the heavy top: 5.2e-7 rad, 1.4e-6 rad/s from MuJoCo's float64 Euler after 200 steps
    (measured); bounded by 1e-4, far below the 1e-2 of a wrong map and far above float64's 1e-15. On the free body
    implicitfast treats the gyroscopic term implicitly: it is not Euler (4e-3 rad apart after 2 s) and keeps the
    kinetic energy to round-off (Euler drifts by 1e-3 relative here)."""
    _, angle, omega = _against_mujoco_euler(genesis, find_case("heavy-asymmetric"), "euler", "ball", "float32")
    assert 1e-9 < angle < 1e-4 and omega < 1e-4
    case = find_case("free-asymmetric")
    run, angle, _ = _against_mujoco_euler(genesis, case, "implicitfast", "free", "float64")
    assert angle > 1e-4
    inertia = np.asarray(case.body.inertia)
    energy = 0.5 * np.einsum("ni,ij,nj->n", run.omega, inertia, run.omega)
    assert np.max(np.abs(energy - energy[0])) / energy[0] < 1e-12


def test_a_second_run_starts_afresh_and_the_free_model_needs_com_at_o(genesis):
    case = find_case("lagrange-top")
    simulation = genesis.prepare(case, "euler", 1e-2)
    grid = time_grid(0.5, 1e-2, 6)
    first, second = simulation.run(grid), simulation.run(grid)
    assert np.array_equal(first.quat, second.quat) and np.array_equal(first.omega, second.omega)
    assert "com = 0" in rigid_body(genesis).unsupported_run(case, "free", "euler")
    assert rigid_body(genesis).unsupported_run(find_case("free-asymmetric"), "free", "euler") is None
