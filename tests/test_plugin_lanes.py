"""Integrator plug-ins in one line and in their lane (issue 30, items 3 and 4): a plug-in that does not load is named
with its distribution and error, a tableau refusal with its row and condition, and `--integrators NAME` for it says
so (exit 2), not "unknown"; a plug-in joins a sweep when named or when its package opts in (default_sweep = True);
a sweep naming integrators has rows only from the engines that offer them."""
import os
import subprocess
import sys
import textwrap
from argparse import Namespace
from importlib.metadata import EntryPoint
from pathlib import Path

import pandas as pd

import pytest

from stereodyn.harness import cli
from stereodyn.harness.cli import common as cli_common
from stereodyn.harness import integrators
from stereodyn.harness.engines import UnavailableEngine, get_engine
from stereodyn.harness.integrators import ButcherTableau
from stereodyn.harness.run import plan as planning
from stereodyn.harness.scenes.cases import find_case, load_case, with_overrides

PACKAGE, DIST = "stereodyn_lanes_plugin", "stereodyn-lanes-plugin 0.1.0"
HEUN = '''
from stereodyn.harness.integrators import ButcherTableau, ExplicitRK

TABLEAU = ButcherTableau(a=((0.0, 0.0), (1.0, 0.0)), b=(0.5, 0.5), c=(0.0, 1.0))


class Heun(ExplicitRK):
    name, order, tableau, description = "lanes_heun", 2, TABLEAU, "Heun's method, run only when named"


class Liar(ExplicitRK):
    name, order, tableau, description = "lanes_liar", 4, TABLEAU, "Heun's method declared fourth order"


class OptIn(ExplicitRK):
    name, order, tableau, description = "lanes_optin", 2, TABLEAU, "Heun's method in every default sweep"
    default_sweep = True  # the package opts in
'''
BAD = '''
from stereodyn.harness.integrators import ButcherTableau, ExplicitRK


class Bad(ExplicitRK):
    name, order, description = "lanes_bad", 2, "a tableau whose second row does not sum to its node"
    tableau = ButcherTableau(a=((0.0, 0.0), (0.9, 0.0)), b=(0.5, 0.5), c=(0.0, 1.0))
'''
ENTRIES = {"lanes_heun": f"{PACKAGE}:Heun", "lanes_liar": f"{PACKAGE}:Liar", "lanes_optin": f"{PACKAGE}:OptIn",
           "lanes_bad": f"{PACKAGE}.bad:Bad", "lanes_boom": f"{PACKAGE}.boom:Boom"}
FILES = {f"{PACKAGE}/__init__.py": HEUN, f"{PACKAGE}/bad.py": BAD,
         f"{PACKAGE}/boom.py": 'raise RuntimeError("boom at import")\n'}
ROW_2 = "tableau is not consistent: row 2: c_2 = 1.0 but the row of a sums to 0.9 (need c_i = sum_j a_ij)"


@pytest.fixture
def plugged(monkeypatch, tmp_path):
    """The package's entry points in this process's registry (a scratch copy), its modules on sys.path."""
    for path, text in FILES.items():
        (tmp_path / path).parent.mkdir(parents=True, exist_ok=True)
        (tmp_path / path).write_text(textwrap.dedent(text))
    monkeypatch.syspath_prepend(str(tmp_path))
    entries = [EntryPoint(name, value, integrators.ENTRY_POINT_GROUP) for name, value in ENTRIES.items()]
    monkeypatch.setattr(integrators.registry, "entry_points", lambda group: entries)
    monkeypatch.setattr(integrators.registry, "_registry", dict(integrators.registry._registry))
    monkeypatch.setattr(integrators.registry, "_from_entry_points", set())
    monkeypatch.setattr(integrators.registry, "_failed", {})
    monkeypatch.setattr(integrators.registry, "_plugins_loaded", False)
    for module in [m for m in sys.modules if m.startswith(PACKAGE)]:
        monkeypatch.delitem(sys.modules, module)
    with pytest.warns(UserWarning):  # the two broken entries, one PluginWarning each
        integrators.names()


@pytest.fixture
def site(tmp_path) -> Path:
    """The package as an installed distribution (its files and a .dist-info folder written by hand: no pip)."""
    for path, text in FILES.items():
        (tmp_path / path).parent.mkdir(parents=True, exist_ok=True)
        (tmp_path / path).write_text(textwrap.dedent(text))
    info = tmp_path / "stereodyn_lanes_plugin-0.1.0.dist-info"
    info.mkdir()
    (info / "METADATA").write_text("Metadata-Version: 2.1\nName: stereodyn-lanes-plugin\nVersion: 0.1.0\n")
    (info / "entry_points.txt").write_text(f"[{integrators.ENTRY_POINT_GROUP}]\n"
                                           + "".join(f"{k} = {v}\n" for k, v in ENTRIES.items()))
    return tmp_path


def test_a_plugin_that_does_not_load_is_one_line_naming_its_distribution(site, tmp_path):
    """From Python (a plug-in's CI) and from the command line alike: one line per broken entry point, with its
    distribution and error; Python's warning no longer points at a line of stereodyn's source."""
    env = {**os.environ, "PYTHONPATH": os.pathsep.join([str(site), os.environ.get("PYTHONPATH", "")])}
    library = subprocess.run([sys.executable, "-c", "from stereodyn.harness import integrators; integrators.names()"],
                             capture_output=True, text=True, env=env, cwd=tmp_path)
    assert library.returncode == 0, library.stderr
    lines = library.stderr.splitlines()
    assert len(lines) == 2 and all(line.startswith("stereodyn:0: PluginWarning: integrator plug-in 'lanes_")
                                   and f"distribution {DIST}) not loaded: " in line for line in lines), lines
    assert lines[0].endswith(ROW_2), lines
    named = subprocess.run([sys.executable, "-m", "stereodyn", "run", "free-asymmetric", "--engines", "pinocchio",
                            "--integrators", "lanes_bad", "--out", str(tmp_path / "out")],
                           capture_output=True, text=True, env=env, cwd=tmp_path)
    assert named.returncode == 2 and named.stderr.splitlines()[-1] == (
        f"stereodyn: error: --integrators: lanes_bad: integrator plug-in 'lanes_bad' ({PACKAGE}.bad:Bad, "
        f"distribution {DIST}) not loaded: ValueError: {ROW_2}"), named.stderr


@pytest.mark.parametrize("kwargs, words", [
    (dict(a=((0.0, 0.0), (0.9, 0.0)), b=(0.5, 0.5), c=(0.0, 1.0)), ROW_2),
    (dict(a=((0.0, 0.0), (1.0, 0.0)), b=(0.5, 0.4), c=(0.0, 1.0)),
     "tableau is not consistent: the weights b sum to 0.9 (need sum_i b_i = 1)"),
    (dict(a=((0.0, 0.0, 0.0), (0.5, 0.0, 0.0), (0.0, 0.5, 0.5)), b=(0.2, 0.3, 0.5), c=(0.0, 0.5, 1.0)),
     "tableau is not explicit: row 3: a[3][3] = 0.5 on or above the diagonal"),
])
def test_a_tableau_refusal_names_the_row_and_the_condition(kwargs, words):
    with pytest.raises(ValueError) as refused:
        ButcherTableau(**kwargs)
    assert str(refused.value).startswith(words)


def test_the_registry_names_a_plugin_that_did_not_load(plugged):
    assert {"lanes_heun", "lanes_liar", "lanes_optin"} <= set(integrators.names())
    assert "lanes_bad" not in integrators.names() and "lanes_boom" not in integrators.names()
    assert integrators.failed_plugin("lanes_bad") == (
        f"integrator plug-in 'lanes_bad' ({PACKAGE}.bad:Bad) not loaded: ValueError: {ROW_2}")
    assert integrators.failed_plugin("lanes_boom").endswith("not loaded: RuntimeError: boom at import")
    assert integrators.failed_plugin("rk4") is None and integrators.failed_plugin("no_such") is None
    with pytest.raises(KeyError, match="integrator 'lanes_bad': integrator plug-in 'lanes_bad'"):
        integrators.get("lanes_bad")


@pytest.mark.parametrize("name, error", [("lanes_bad", f"ValueError: {ROW_2}"),
                                         ("lanes_boom", "RuntimeError: boom at import")])
def test_integrators_naming_a_plugin_that_did_not_load_says_so(plugged, tmp_path, capsys, name, error):
    out = tmp_path / "out"
    assert cli.main(["run", "free-asymmetric", "--engines", "pinocchio", "--integrators", f"rk4,{name}", "--quiet",
                     "--out", str(out)]) == 2
    last = capsys.readouterr().err.splitlines()[-1]
    assert last.startswith(f"stereodyn: error: --integrators: {name}: integrator plug-in '{name}' (") and \
        last.endswith(f"not loaded: {error}"), last
    assert "unknown" not in last and not out.exists()


def test_a_plugin_runs_in_a_default_sweep_only_when_its_package_opts_in(plugged):
    assert not integrators.in_default_sweep("lanes_heun") and not integrators.in_default_sweep("lanes_liar")
    assert integrators.in_default_sweep("lanes_optin")
    pinocchio = get_engine("pinocchio")
    sweep = planning.Selection.of(pinocchio, None).integrators
    assert "lanes_optin" in sweep and "lanes_heun" not in sweep and "lanes_liar" not in sweep and "rk4" in sweep
    assert "lanes_liar" in planning.Selection.of(pinocchio, ["lanes_liar"]).integrators  # named: it runs

    class Script(integrators.ExplicitRK):  # a class registered in Python (a script, a test) keeps default_sweep
        name, order, tableau, description = "lanes_script", 2, integrators.lie.CLASSICAL_RK4, "registered in Python"

    integrators.register(Script)
    assert integrators.in_default_sweep("lanes_script")


def test_named_integrators_have_rows_only_from_engines_that_offer_them(tmp_path):
    """MuJoCo offers no implicit_midpoint: no row for it, not even the skipped row of a case it cannot model
    (Hairer–Lubich–Wanner's unphysical inertia, which MuJoCo's compiler refuses); an engine not installed is left out
    of the default engines when integrators are named."""
    (tmp_path / "hlw.toml").write_text(
        "[body]\nmass = 1.0\ncom = [0.0, 0.0, 0.0]\nprincipal_moments = [2.0, 1.0, 0.6666666666666666]\n"
        "physical = false\n[initial]\nattitude = { quaternion = [1.0, 0.0, 0.0, 0.0] }\nomega = [0.2, 0.0, 1.3]\n"
        "[run]\nt_end = 1.0\ndt = [1e-2]\nsamples = 11\n")
    hlw = load_case(tmp_path / "hlw.toml")
    assert get_engine("mujoco").unsupported(hlw)  # else the skipped row below could not appear
    free = with_overrides(find_case("free-asymmetric"), t_end=1.0, dt=[0.01])
    specs, skipped = planning.plan([free, hlw], ["mujoco", "pinocchio"], ["implicit_midpoint"])
    assert {spec.engine for spec in specs} == {"pinocchio"} and skipped == []
    _, skipped = planning.plan([hlw], ["mujoco", "pinocchio"], ["rk4"])  # mujoco offers rk4: its row says why not
    assert [row["engine"] for row in skipped] == ["mujoco"]
    default = Namespace(engines=None, integrators=["rk4"], dt_ladder=False, no_ladder=True, ladder_max_steps=None)
    cli_common.load()
    cli_common.check_names(default)
    assert default.engines and not any(isinstance(get_engine(e), UnavailableEngine) for e in default.engines)


# slow: a sweep on the default engines in a subprocess, ~13 s of CPU (2-core machine, load ~3)
@pytest.mark.slow
def test_an_installed_package_stays_in_its_lane(tmp_path):
    """Issue 30's acceptance, the package pip-installed as a user would: `--integrators lanes_heun,rk4 --strict` on
    the default engines has rows only from the engines that offer them (no skipped rows for the engines not
    installed), the two broken entries are one warning line each naming the distribution, and the installed
    lanes_liar (Heun declared fourth order) neither runs nor changes the exit."""
    import plugin_packages

    site = plugin_packages.install(tmp_path / "package", {
        "pyproject.toml": plugin_packages.pyproject(PACKAGE, {"stereodyn.integrators": ENTRIES}),
        **{path: textwrap.dedent(text) for path, text in FILES.items()}})
    out = tmp_path / "out"
    result = subprocess.run([sys.executable, "-m", "stereodyn", "run", "free-asymmetric", "--integrators",
                             "lanes_heun,rk4", "--t-end", "1", "--dt", "0.04,0.02,0.01", "--strict", "--no-certify",
                             "--jobs", "1", "--quiet", "--out", str(out)],
                            capture_output=True, text=True, env=plugin_packages.env_with(site), cwd=tmp_path)
    assert result.returncode == 0, result.stderr[-3000:]
    warnings = [line for line in result.stderr.splitlines() if line.startswith("stereodyn: warning:")]
    assert len(warnings) == 2 and all(f"distribution {DIST}) not loaded: " in line for line in warnings), warnings
    assert any(line.endswith(ROW_2) for line in warnings), warnings
    rows = pd.read_csv(out / "results.csv", keep_default_na=False)
    rows = rows[rows.integrator != "taylor"]
    assert set(rows.engine) == {"mujoco", "pinocchio", "reference"} and set(rows.status) == {"ok"}
    assert set(rows.integrator) == {"lanes_heun", "rk4"}
    assert set(rows[rows.integrator == "lanes_heun"].engine) == {"pinocchio"}
