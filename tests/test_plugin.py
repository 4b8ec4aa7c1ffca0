"""A third-party integrator package, built and installed in a temporary directory, registers an integrator through
the entry-point group stereodyn.integrators; `stereodyn run --integrators heun_plugin` then runs it on the Pinocchio
and reference engines."""
import subprocess
import sys
import textwrap
from pathlib import Path

import pandas as pd
import plugin_packages
import pytest

PACKAGE = "stereodyn_heun_plugin"

MODULE = '''
"""Heun's method (explicit trapezoidal rule), as a user would add it: one tableau, both state spaces; and the explicit
midpoint rule written as a step, with the 0.2.0 signature (time first)."""
from stereodyn.harness.integrators import ButcherTableau, ExplicitRK, Integrator, VectorRK

HEUN = ButcherTableau(a=((0.0, 0.0), (1.0, 0.0)), b=(0.5, 0.5), c=(0.0, 1.0))


class HeunLie(ExplicitRK):
    name = "heun_plugin"
    order = 2
    tableau = HEUN
    description = "Heun's method, Runge-Kutta-Munthe-Kaas on the group"


class HeunVector(VectorRK):
    name = "heun_plugin"
    order = 2
    tableau = HEUN
    description = "Heun's method on a formulation's coordinates"


class MidpointLie(Integrator):
    name, order, stages, symplectic, geometric = "midpoint_plugin", 2, 2, False, True
    description = "explicit midpoint on the group, a hand-written step"

    def step(self, system, t, g, v, h):
        g_half, v_half = system.retract(g, 0.5 * h * v), v + 0.5 * h * system.accel(t, g, v)
        return system.retract(g, h * v_half), v + h * system.accel(t + 0.5 * h, g_half, v_half)


INTEGRATORS = (HeunLie, HeunVector, MidpointLie)
'''


@pytest.fixture(scope="module")
def installed(tmp_path_factory) -> Path:
    """The package pip-installed into a target folder (the venv itself is not touched); removed with tmp_path."""
    return plugin_packages.install(tmp_path_factory.mktemp("plugin"), {
        "pyproject.toml": plugin_packages.pyproject(
            PACKAGE, {"stereodyn.integrators": {"heun_plugin": f"{PACKAGE}:INTEGRATORS"}}),
        f"{PACKAGE}/__init__.py": textwrap.dedent(MODULE)})


_env = plugin_packages.env_with


@pytest.mark.slow  # since 2026-12-02, ~10 s; by default test_engine_plugins.py's external engine in a sweep (the default suite's 8 minutes)
def test_plugin_runs_by_name_on_pinocchio_and_reference(installed, tmp_path):
    out = tmp_path / "out"
    result = subprocess.run([sys.executable, "-m", "stereodyn.harness.cli", "run", "free-asymmetric", "--engines",
                             "pinocchio,reference", "--integrators", "heun_plugin,midpoint_plugin", "--t-end", "1",
                             "--dt", "0.01",
                             "--out", str(out), "--quiet", "--jobs", "1"],
                            capture_output=True, text=True, env=_env(installed), cwd=tmp_path)
    assert result.returncode == 0, result.stderr[-3000:]
    df = pd.read_csv(out / "results.csv").fillna({"formulation": ""})
    rows = df[df["integrator"] == "heun_plugin"]
    assert set(rows["engine"]) == {"pinocchio", "reference"}
    midpoint = df[df["integrator"] == "midpoint_plugin"]
    assert set(midpoint["engine"]) == {"pinocchio"} and (midpoint["status"] == "ok").all()
    assert (midpoint["attitude_err"] < 1e-3).all()  # 2nd order, dt = 0.01 over 1 s, as Heun
    assert (rows["status"] == "ok").all(), rows[["engine", "formulation", "status", "message"]]
    assert (rows["attitude_err"] < 1e-3).all()  # a 2nd-order method at dt = 0.01 over 1 s: ~1e-5 rad


def test_plugin_order_with_harness_testing(installed, tmp_path):
    """The user's CI check, harness.testing.assert_order, in a process that sees the plug-in."""
    code = ("from stereodyn.harness import testing; "
            "print(testing.assert_order('heun_plugin', ['lagrange-top'], dts=[0.02 / 2 ** k for k in range(4)]))")
    result = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, env=_env(installed),
                            cwd=tmp_path)
    assert result.returncode == 0, result.stderr[-3000:]
    assert "lagrange-top" in result.stdout


def test_without_the_plugin_the_name_is_unknown(tmp_path):
    result = subprocess.run([sys.executable, "-m", "stereodyn.harness.cli", "run", "free-asymmetric", "--engines", "pinocchio",
                             "--integrators", "heun_plugin", "--out", str(tmp_path / "out"), "--quiet"],
                            capture_output=True, text=True, cwd=tmp_path)
    assert result.returncode == 2 and "heun_plugin" in result.stderr
