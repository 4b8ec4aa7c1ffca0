"""The integrators each adapter runs are read from its SDK (harness/engines/offered.py, issue 48): every integrator the
installed SDK offers is modelled (an order and a method declared) or has a stated reason; one a newer release adds
(a test double of the SDK's enum) is named as not modelled by `stereodyn engines` and by a run, in one line, without
a code change."""
from __future__ import annotations

import enum
import math
import sys

import mujoco
import pandas as pd
import pytest

from stereodyn.harness.engines import get_engine, offered
from stereodyn.harness.engines import mujoco as mujoco_engine
from stereodyn.harness.engines.backends import MujocoBackend
from stereodyn.harness.engines.catalog import render, rows
from stereodyn.harness.engines.declared import declared_order, in_default_sweep, method
from stereodyn.harness.run.plan import plan
from stereodyn.harness.scenes.cases import find_case as load_suite_case

from helpers import installed_engine


class _Release(enum.IntEnum):
    """mjtIntegrator of a MuJoCo release newer than the adapter: today's members and one more."""

    mjINT_EULER = 0
    mjINT_RK4 = 1
    mjINT_IMPLICIT = 2
    mjINT_IMPLICITFAST = 3
    mjINT_DISCRETE = 4
    mjINT_LEAPFROG = 5


@pytest.fixture
def newer_mujoco(monkeypatch):
    monkeypatch.setattr(mujoco, "mjtIntegrator", _Release)


def test_every_integrator_of_the_installed_mujoco_is_modelled_or_says_why():
    members = [name for name in mujoco.mjtIntegrator.__members__ if name.startswith("mjINT_")]
    assert members, "mjtIntegrator lists no mjINT_ member: the adapter's read of MuJoCo is broken"
    engine = get_engine("mujoco")
    for member in members:
        name = member[len("mjINT_"):].lower()
        stated = name in mujoco_engine.INTEGRATORS or name in mujoco_engine.NOT_MODELLED
        assert stated, (f"mujoco {mujoco.__version__}'s mjtIntegrator has {member}: model it in "
                        f"harness/engines/mujoco.py (INTEGRATORS, ORDERS, METHODS) or say why in NOT_MODELLED")
        assert name in engine.integrators()
        if name in mujoco_engine.INTEGRATORS:  # runs: a declared order and a method, in the default sweep
            offer = engine.offer(name)
            assert not offer.unmodelled and not math.isnan(offer.order) and in_default_sweep(engine, name)
            assert method(engine, name) or name == "implicit", name  # implicit is MuJoCo's own (no shared method)
    # an adapter's name the installed MuJoCo lacks (discrete before 3.13) is not offered: no row, nothing to run
    assert set(engine.integrators()) == {m[len("mjINT_"):].lower() for m in members}


@pytest.mark.skipif(not hasattr(mujoco.mjtIntegrator, "mjINT_DISCRETE"), reason="MuJoCo < 3.13 has no discrete")
def test_discrete_runs_with_its_declared_order_and_is_eulers_update_on_a_ball_joint():
    """MuJoCo's discrete solves the velocity update in the metric M + hD + h^2 K; without damping, stiffness and
    constraints (the scene) that is Euler's semi-implicit update: order 1, the same states (measured: equal to the last
    bit on 4.0.0; compared here to 1e-12 of the state's size)."""
    from stereodyn.harness.grid import time_grid

    engine = get_engine("mujoco")
    assert declared_order(engine, "discrete") == 1.0 and method(engine, "discrete") == "semi_implicit_euler"
    case = load_suite_case("heavy-asymmetric")
    grid = time_grid(1.0, 1e-3, 11)
    discrete = engine.prepare(case, "discrete", 1e-3).run(grid)
    euler = engine.prepare(case, "euler", 1e-3).run(grid)
    assert abs(discrete.omega - euler.omega).max() <= 1e-12 * abs(euler.omega).max()
    assert abs(discrete.quat - euler.quat).max() <= 1e-12


def test_a_newer_mujocos_integrator_is_named_not_modelled(newer_mujoco):
    engine = get_engine("mujoco")
    assert engine.integrators()[-1] == "leapfrog" and "discrete" in engine.integrators()
    reason = engine.offer("leapfrog").unmodelled
    assert reason.startswith(offered.NOT_MODELLED + ": ") and "mjtIntegrator offers it" in reason
    row = next(r for r in rows() if r.name == "mujoco")
    assert dict(row.unmodelled) == {"leapfrog": reason}
    assert not any(i.rstrip("*") == "leapfrog" for i in row.integrators)  # not listed as run
    text = render([row], wide=True).splitlines()
    assert f"  leapfrog: {reason}" in text
    # the default sweep gives it one skipped row per case (no dt: nothing was stepped), never a run
    cases = [load_suite_case("free-asymmetric"), load_suite_case("lagrange-top")]
    specs, skipped = plan(cases, ["mujoco"], None)
    assert not [s for s in specs if s.integrator == "leapfrog"]
    mine = [r for r in skipped if r["integrator"] == "leapfrog"]
    assert len(mine) == 2 and all(r["status"] == "skipped" and r["message"] == reason for r in mine)
    assert {s.integrator for s in specs} == set(mujoco_engine.INTEGRATORS)


def test_a_run_names_the_newer_integrator_in_one_line(newer_mujoco, tmp_path, capsys):
    from stereodyn.harness.cli import main

    out = tmp_path / "out"
    code = main(["run", "free-asymmetric", "--engines", "mujoco", "--integrators", "leapfrog", "--t-end", "0.1",
                 "--dt", "1e-2", "--no-figures", "--no-certify", "--out", str(out)])
    assert code == 0
    results = pd.read_csv(out / "results.csv")
    assert list(results["integrator"]) == ["leapfrog"] and list(results["status"]) == ["skipped"]
    printed = [line for line in capsys.readouterr().out.splitlines() if "leapfrog" in line]
    assert len(printed) == 1 and offered.NOT_MODELLED in printed[0], printed


def test_the_names_keep_the_adapters_order_then_the_sdks_others():
    assert offered.names(["b", "x", "a"], ["a", "b", "c"]) == ("a", "b", "x")  # c: an older SDK lacks it
    assert offered.unmodelled("a", ["a", "x"], ["a"], {}, "sdk") == ""
    assert offered.unmodelled("x", ["a", "x"], ["a"], {"x": "why"}, "sdk") == f"{offered.NOT_MODELLED}: why"
    assert offered.unmodelled("y", ["a", "x"], ["a"], {}, "sdk") == ""  # not offered: not this engine's at all


def test_a_backends_integrators_are_read_from_its_sdks_enum_without_importing_it(tmp_path, monkeypatch):
    """MJX's and MuJoCo Warp's IntegratorType, read from the module's source (importing it costs seconds: jax, warp);
    a member the adapter does not model is named, one whose enum cannot be read falls back to the adapter's list."""
    package = tmp_path / "fake_sdk"
    package.mkdir()
    (package / "__init__.py").write_text("raise ImportError('the source is read, never imported')\n")
    (package / "types.py").write_text("import enum\nclass IntegratorType(enum.IntEnum):\n  '''doc'''\n"
                                      "  EULER = 0\n  RK4 = 1\n  DISCRETE = 4\n  # unsupported: IMPLICIT\n")
    monkeypatch.syspath_prepend(str(tmp_path))

    class Backend(MujocoBackend):
        name = "fake-backend"
        stages, orders = {"euler": 1, "rk4": 4, "implicitfast": 1}, {"euler": 1.0, "rk4": 4.0, "implicitfast": 1.0}
        sdk_enum = ("fake_sdk.types", "IntegratorType")

        def prepare(self, case, integrator, dt, **keywords):
            raise AssertionError("not run")

    backend = Backend()
    assert offered.enum_members("fake_sdk.types", "IntegratorType") == ("EULER", "RK4", "DISCRETE")
    assert "fake_sdk.types" not in sys.modules and "fake_sdk" not in sys.modules
    assert backend.integrators() == ("euler", "rk4", "discrete")  # implicitfast: this release lacks it
    assert backend.offer("discrete").unmodelled.startswith(offered.NOT_MODELLED)
    assert backend.offer("rk4").unmodelled == ""
    Backend.sdk_enum = ("fake_sdk.absent", "IntegratorType")
    assert backend.integrators() == ("euler", "rk4", "implicitfast")


@pytest.mark.parametrize("name, module", [("mjx", "mujoco.mjx._src.types"), ("warp", "mujoco_warp._src.types")])
def test_an_installed_backends_enum_is_modelled_or_says_why(name, module):
    engine = installed_engine(name)  # skips where the extra is absent
    members = offered.enum_members(module, "IntegratorType")
    assert members, f"{module}.IntegratorType could not be read: the adapter would fall back to its own list"
    for member in members:
        assert member.lower() in engine.stages or member.lower() in engine.not_modelled, (name, member)


def test_every_scheme_of_the_installed_drake_is_modelled_or_says_why():
    engine = installed_engine("drake")
    drake = sys.modules[type(engine).__module__]
    from pydrake.systems.analysis import GetIntegrationSchemes

    for scheme in GetIntegrationSchemes():
        assert scheme in drake.MODELLED or scheme in drake.NOT_MODELLED, (
            f"Drake's GetIntegrationSchemes() has {scheme!r}: model it in harness/engines/drake.py or say why in "
            "NOT_MODELLED")
    assert "cenic" not in drake.MODELLED or "cenic" not in drake.NOT_MODELLED
    assert engine.offer("rk4").unmodelled == "" and not in_default_sweep(engine, "rk4")  # another engine's name
    for integrator in engine.integrators():
        offer = engine.offer(integrator)
        assert bool(offer.unmodelled) == (integrator not in drake.MODELLED)
