"""Engines are plug-ins (entry-point group stereodyn.engines, base class harness.engines.base.Engine): the built-ins
are registered there; a third-party engine package, installed in a temporary directory, runs in a sweep; a broken or
old-style plug-in is refused naming it; and no engine name is spelled in the harness outside its adapter and the
registry."""
import ast
import importlib.metadata
import subprocess
import sys
import textwrap
from importlib.metadata import entry_points
from pathlib import Path

import pandas as pd
import plugin_packages
import pytest

from stereodyn.harness import engines
from stereodyn.harness.engines import Engine, EngineError

ROOT = Path(__file__).resolve().parents[1]
PACKAGE = "stereodyn_toy_engine"

ENTRY_POINTS = {"stereodyn.engines": {"toy": f"{PACKAGE}:ToyEngine", "toy_old": f"{PACKAGE}:OldStyleEngine",
                                     "toy_broken": f"{PACKAGE}:NoSuchClass",
                                     "toy_nosdk": f"{PACKAGE}.needs_sdk:Engine"}}

# The smallest engine a user could write: it wraps the Pinocchio adapter's simulation (the dynamics are not the point
# here; the plug-in seam is), for bodies without external torques.
MODULE = '''
"""A toy engine plug-in: the body stepped by the harness's Lie-group integrators on Pinocchio's dynamics."""
from stereodyn.harness import integrators
from stereodyn.harness.engines.base import Engine


class _Simulation:
    def __init__(self, case, integrator, dt):
        from stereodyn.harness.engines.pinocchio import PinocchioSimulation

        self.inner = PinocchioSimulation(case, integrator, dt)

    def run(self, grid):
        return self.inner.run(grid)


class ToyEngine(Engine):
    name = "toy"
    state_space = "lie"
    linestyle = "-"
    pass_us = 3.0

    def integrators(self):
        return ("rk4",)

    def unsupported(self, case):
        return "toy: no external torques" if case.body.has_external_torque else None

    def prepare(self, case, integrator, dt):
        return _Simulation(case, integrators.get(integrator)(), float(dt))


class OldStyleEngine:
    """Written against the 0.1 protocol: not an Engine subclass."""
    name = "toy_old"

    def integrators(self):
        return ("rk4",)
'''


@pytest.fixture(scope="module")
def installed(tmp_path_factory) -> Path:
    """The package pip-installed into a target folder (the venv is not touched); removed with tmp_path."""
    return plugin_packages.install(tmp_path_factory.mktemp("engine_plugin"), {
        "pyproject.toml": plugin_packages.pyproject(PACKAGE, ENTRY_POINTS),
        f"{PACKAGE}/__init__.py": textwrap.dedent(MODULE)})


def _run(target: Path, *argv: str, cwd: Path) -> subprocess.CompletedProcess:
    return subprocess.run([sys.executable, *argv], capture_output=True, text=True,
                          env=plugin_packages.env_with(target), cwd=cwd)


def test_the_builtin_engines_are_entry_points():
    registered = {entry.name: entry.value for entry in entry_points(group=engines.ENTRY_POINT_GROUP)}
    assert {"mujoco", "pinocchio", "reference"} <= set(registered)
    assert engines.engine_names()[:3] == ("mujoco", "pinocchio", "reference")
    for name in ("mujoco", "pinocchio", "reference"):
        engine = engines.get_engine(name)
        assert isinstance(engine, Engine) and engine.name == name


def test_an_external_engine_runs_in_a_sweep(installed, tmp_path):
    out = tmp_path / "out"
    result = _run(installed, "-m", "stereodyn", "run", "free-asymmetric", "--engines", "toy,pinocchio",
                  "--integrators", "rk4", "--t-end", "1", "--dt", "0.01", "--out", str(out), "--quiet", "--jobs", "1",
                  cwd=tmp_path)
    assert result.returncode == 0, result.stderr[-3000:]
    df = pd.read_csv(out / "results.csv", dtype={"formulation": str}).fillna({"formulation": ""})
    toy = df[df["engine"] == "toy"]
    assert len(toy) == 1 and toy["status"].iloc[0] == "ok", toy[["status", "message"]]
    # the toy engine steps the same equations with the same integrator as Pinocchio's adapter: RK4 at dt = 0.01
    # over 1 s is ~1e-9 rad off the truth there (measured 2e-10 on this case)
    assert toy["attitude_err"].iloc[0] < 1e-7
    pin = df[df["engine"] == "pinocchio"]
    assert abs(toy["attitude_err"].iloc[0] - pin["attitude_err"].iloc[0]) <= 1e-12
    # its declared order comes from the registry through its state space (Engine.declared_order)
    checks = pd.read_csv(out / "convergence.csv", dtype={"formulation": str}).fillna({"formulation": ""})
    assert set(checks["engine"]) <= {"toy", "pinocchio"}


def test_the_external_engine_is_listed_and_old_or_broken_plugins_are_refused(installed, tmp_path):
    code = textwrap.dedent("""
        from stereodyn.harness import engines
        print("names", ",".join(engines.engine_names()))
        print("nosdk", engines.get_engine("toy_nosdk").unsupported(None))
        for name in ("toy_old", "toy_broken"):
            try:
                engines.get_engine(name)
            except engines.EngineError as exc:
                print("refused", exc)
    """)
    result = _run(installed, "-c", code, cwd=tmp_path)
    assert result.returncode == 0, result.stderr[-3000:]
    lines = result.stdout.splitlines()
    # the built-ins, then stereodyn's engines whose SDK is an optional extra (registered whether or not it is
    # installed), by name, then third parties' by name
    extras = ",".join(sorted(set(_OWN) - {"mujoco", "pinocchio", "reference"}))
    assert {"bullet", "drake", "genesis", "newton"} <= set(_OWN)
    assert lines[0] == f"names mujoco,pinocchio,reference,{extras},toy,toy_broken,toy_nosdk,toy_old"
    # a module that cannot be imported (a missing SDK) makes the engine's runs skipped, with the reason
    assert lines[1].startswith("nosdk toy_nosdk engine unavailable: No module named")
    old, broken = lines[2], lines[3]
    assert "engine plug-in 'toy_old'" in old and "not a subclass of stereodyn.harness.engines.base.Engine" in old
    assert "engine plug-in 'toy_broken'" in broken and "does not load" in broken and "NoSuchClass" in broken


def test_an_old_style_plugin_in_a_run_is_a_one_line_error(installed, tmp_path):
    result = _run(installed, "-m", "stereodyn", "run", "free-asymmetric", "--engines", "toy_old", "--out",
                  str(tmp_path / "out"), "--quiet", cwd=tmp_path)
    assert result.returncode == 2 and result.stderr.count("\n") == 1 and "toy_old" in result.stderr


def test_the_base_class_defaults():
    class Minimal(Engine):
        name = "minimal"

    engine = Minimal()
    assert engine.formulations() == () and engine.adaptive("rk4") is False and engine.default_run(None, "", "rk4")
    # the registry's default_sweep: the geometric methods run only when named; an engine's own name is run
    assert engine.in_default_sweep("rk4") and not engine.in_default_sweep("implicit_midpoint")
    assert engine.in_default_sweep("no_such_integrator")
    assert engine.unsupported_run(None, "", "rk4") is None and engine.torque_mode(None) == "none"
    # the scenes it models: the rigid body through the hooks above, nothing else (its rows of another scene are skipped)
    from stereodyn.harness.scenes import scene
    assert set(engine.models()) == {"rigid_body"}
    assert engine.unmodelled(scene("sliding_ladder")) == "minimal adapter does not model the sliding ladder"
    assert engine.declared_order("no_such_integrator") != engine.declared_order("no_such_integrator")  # NaN
    assert engine.declared_order("rk4") == 4.0  # the registry's Lie-group rk4
    with pytest.raises(NotImplementedError, match="minimal"):
        engine.prepare(None, "rk4", 0.1)
    with pytest.raises(NotImplementedError, match="ensembles"):
        engine.prepare_ensemble(None, "rk4", 0.1, None, None)


def test_engine_error_is_a_value_error():
    assert issubclass(EngineError, ValueError)


# ------------------------------------------------------------------------------------------------ engine names

# stereodyn's own engines (built in or an optional extra): every entry point of the group in its pyproject.toml
_OWN = {entry.name: entry.value.split(":")[0] for entry in importlib.metadata.entry_points(group="stereodyn.engines")
        if entry.value.startswith("stereodyn.harness.engines.")}
ENGINE_NAMES = set(_OWN)
# Where an engine name may be spelled: its adapter and the registry (and tests, outside harness/).
ALLOWED = {Path("harness/engines/__init__.py")} | {
    Path("harness/engines", module.rsplit(".", 1)[1] + ".py") for module in _OWN.values()}


def _engine_name_literals(path: Path) -> list[tuple[int, str]]:
    """(line, name) of every string constant in the file that is exactly an engine name, docstrings aside."""
    tree = ast.parse(path.read_text(), filename=str(path))
    docstrings = {id(node.body[0].value) for node in ast.walk(tree)
                  if isinstance(node, (ast.Module, ast.ClassDef, ast.FunctionDef, ast.AsyncFunctionDef))
                  and node.body and isinstance(node.body[0], ast.Expr)
                  and isinstance(node.body[0].value, ast.Constant)}
    return [(node.lineno, node.value) for node in ast.walk(tree)
            if isinstance(node, ast.Constant) and isinstance(node.value, str) and node.value in ENGINE_NAMES
            and id(node) not in docstrings]


def test_no_engine_name_outside_its_adapter_and_the_registry():
    found = [f"{path.relative_to(ROOT)}:{line}: {name!r}"
             for path in sorted((ROOT / "harness").rglob("*.py")) if path.relative_to(ROOT) not in ALLOWED
             for line, name in _engine_name_literals(path)]
    assert not found, "engine names spelled outside their adapter and the registry:\n" + "\n".join(found)


def test_the_engine_name_scan_finds_a_spelled_name(tmp_path):
    planted = tmp_path / "planted.py"
    planted.write_text('"""Docstrings may name mujoco."""\nCOST = {"mujoco": 1.5}\n')
    assert _engine_name_literals(planted) == [(2, "mujoco")]
