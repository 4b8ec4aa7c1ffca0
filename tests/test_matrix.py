"""`stereodyn matrix` (issue 31 item 5): one environment per specification (uv), the runs in each, the history over
them and a compare of each neighbouring pair; environments cached between calls; a failed install is a row.

The fast test needs no network and builds no engine: two local wheels of a toy engine plug-in, versions 1.0 and 2.0
(2.0 "regresses": its rk4 steps the classical tableau without the dexp^-1 correction, 2nd order on the group, as
MuJoCo 3.x's RK4 does on a ball joint), installed with uv from a local folder (UV_FIND_LINKS, UV_NO_INDEX) over this
environment's packages (--overlay). The real two-release matrix (MuJoCo 3.x and 4.0 from the registry, isolated
environments) is `-m slow`.
"""
import base64
import hashlib
import json
import zipfile
from pathlib import Path

import pandas as pd
import pytest

from stereodyn.harness import cli

pytest.importorskip("uv", reason="stereodyn matrix needs uv (pip install 'stereodyn[matrix]')")

DIST, PACKAGE = "stereodyn-mtoy", "stereodyn_mtoy"
OTHER = "stereodyn-mother"  # a second toy distribution: an environment may vary two packages at once
ENGINE = '''
"""A toy engine plug-in, version {version}: the body stepped by the harness's Lie-group integrators on Pinocchio's
dynamics; its rk4 is {inner}."""
from stereodyn.harness import integrators
from stereodyn.harness.engines.base import About, Engine, Timing


class _Simulation:
    def __init__(self, case, integrator, dt):
        from stereodyn.harness.engines.pinocchio import PinocchioSimulation

        self.inner = PinocchioSimulation(case, integrator, dt)

    def run(self, grid):
        return self.inner.run(grid)


class MatrixToyEngine(Engine):
    name = "mtoy"
    about = About(state_space="lie", linestyle="-")

    def integrators(self):
        return ("rk4",)

    def unsupported(self, case):
        return "mtoy: no external torques" if case.body.has_external_torque else None

    def prepare(self, case, integrator, dt):
        return _Simulation(case, integrators.get("{inner}")(), float(dt))
'''
# the runs: one case, two steps, the toy engine only; no ladder, no certification (the machinery is the point)
RUN = ["free-asymmetric", "--engines", "mtoy", "--t-end", "1", "--dt", "1e-2,5e-3", "--no-certify", "--no-ladder",
       "--jobs", "1", "--quiet"]


def wheel(folder: Path, version: str, inner: str, dist: str = DIST) -> Path:
    """A wheel of the toy engine, or of another toy distribution (PEP 427: the module, METADATA, WHEEL,
    entry_points.txt, RECORD)."""
    package = dist.replace("-", "_")
    dist_info = f"{package}-{version}.dist-info"
    files = {f"{package}/__init__.py": ENGINE.format(version=version, inner=inner),
             f"{dist_info}/METADATA": f"Metadata-Version: 2.1\nName: {dist}\nVersion: {version}\n",
             f"{dist_info}/WHEEL": "Wheel-Version: 1.0\nGenerator: test\nRoot-Is-Purelib: true\nTag: py3-none-any\n",
             f"{dist_info}/entry_points.txt": f"[stereodyn.engines]\nmtoy = {PACKAGE}:MatrixToyEngine\n"
             if dist == DIST else ""}
    path = folder / f"{package}-{version}-py3-none-any.whl"
    record = []
    with zipfile.ZipFile(path, "w") as archive:
        for name, text in files.items():
            data = text.encode()
            archive.writestr(name, data)
            digest = base64.urlsafe_b64encode(hashlib.sha256(data).digest()).rstrip(b"=").decode()
            record.append(f"{name},sha256={digest},{len(data)}")
        archive.writestr(f"{dist_info}/RECORD", "\n".join(record + [f"{dist_info}/RECORD,,"]) + "\n")
    return path


@pytest.fixture
def offline(tmp_path, monkeypatch):
    """uv finds the toy wheels in a local folder and never the network; the matrix's cache and uv's in tmp_path; the
    runs in the command's own process (no worker pool to start: STEREODYN_IN_PROCESS)."""
    wheels = tmp_path / "wheels"
    wheels.mkdir()
    wheel(wheels, "1.0", "rk4")
    wheel(wheels, "2.0", "rk4_naive")
    wheel(wheels, "1.0", "rk4", dist=OTHER)
    monkeypatch.setenv("UV_FIND_LINKS", str(wheels))
    monkeypatch.setenv("UV_NO_INDEX", "1")
    monkeypatch.setenv("UV_OFFLINE", "1")
    monkeypatch.setenv("UV_CACHE_DIR", str(tmp_path / "uv-cache"))
    monkeypatch.setenv("XDG_CACHE_HOME", str(tmp_path / "cache"))
    monkeypatch.setenv("STEREODYN_IN_PROCESS", "1")
    return tmp_path


# What `stereodyn run` leaves, written by a stand-in run in the environment's own Python (the fast test): the toy's
# version read from the environment's installed metadata, recorded as a run records its plug-in, and an attitude error
# 1e4 x larger under 2.0 (rk4_naive's against rk4's, as the real runs measure).
STAND_IN = """
import json, sys
from importlib.metadata import version
from pathlib import Path

out = Path(sys.argv[1])
v = version("stereodyn-mtoy")
err = 2e-9 * (1e4 if v == "2.0" else 1.0)
head = "case,engine,formulation,integrator,precision,dt,status,message,energy_drift,attitude_err,us_per_step"
rows = [f"free-asymmetric,mtoy,,rk4,float64,{dt},ok,,1e-10,{err * k},2.0" for dt, k in ((0.01, 16), (0.005, 1))]
(out / "results.csv").write_text("\\n".join([head, *rows]) + "\\n")
env = {"python": "3.11", "stereodyn-mtoy": f"{v} (plug-in: engine mtoy)", "date": "2026-11-26T10:00:00+00:00"}
(out / "runs.json").write_text(json.dumps({"format": 1, "environment": env, "code": {}, "runs": [],
                                           "complete": True}))
try:
    other = version("stereodyn-mother")
except Exception:
    other = "absent"
print("stand-in run", v, other)
"""


def test_two_toy_versions_are_installed_cached_and_lined_up(offline, monkeypatch, capsys):
    """The machinery, fast: uv builds an environment per version of the toy engine from the local wheels (1.0, 2.0;
    9.9 has no wheel: a row saying why), each environment's Python sees its own version (a stand-in for `stereodyn
    run` reads it), the history over them flags 2.0's attitude error, worse, and compare 1 -> 2 is written. A second
    call builds nothing and runs nothing again: the same environment folders, their marks untouched, rows cached and
    reused."""
    from stereodyn.harness.cli import matrix

    monkeypatch.setattr(matrix, "command", lambda python, argv, folder: [str(python), "-c", STAND_IN, str(folder)])
    out = offline / "out"
    argv = ["matrix", f"{DIST}==1.0", f"{DIST}==2.0 {OTHER}==1.0", f"{DIST}==9.9", "--overlay", "--out", str(out),
            "--", *RUN]
    assert cli.main(argv) == 0
    printed = capsys.readouterr().out
    rows = pd.read_csv(out / "matrix.csv", keep_default_na=False)
    assert rows["status"].tolist() == ["ok", "ok", "install failed"], rows
    assert "9.9" in rows["reason"][2] and rows["reason"][:2].tolist() == ["", ""] and "install failed" in printed
    assert rows["cached"].tolist() == [False, False, False]
    envs = [Path(p) for p in rows["path"][:2]]
    assert all(p.parent == offline / "cache" / "stereodyn" / "matrix" for p in envs) and envs[0] != envs[1]
    logs = [path.read_text().strip() for path in sorted((out / "runs").glob("*.log"))]
    assert logs == ["stand-in run 1.0 absent", "stand-in run 2.0 1.0"]  # two packages vary at once in the second
    steps = pd.read_csv(out / "history_steps.csv", keep_default_na=False)
    assert set(zip(steps["quantity"], steps["label"], steps["direction"])) == {
        ("attitude_err", f"{DIST}==2.0 {OTHER}==1.0", "worse")}, steps
    assert (out / "compare" / "1-2" / "compare.md").is_file() and (out / "history.html").is_file()
    marks = [(p / "stereodyn-matrix.json").stat().st_mtime_ns for p in envs]

    assert cli.main(argv) == 0
    again = pd.read_csv(out / "matrix.csv", keep_default_na=False)
    assert again["cached"].tolist() == [True, True, False] and again["reused"][:2].tolist() == ["True", "True"]
    assert [(p / "stereodyn-matrix.json").stat().st_mtime_ns for p in envs] == marks
    assert again["path"].tolist() == rows["path"].tolist()


@pytest.mark.slow  # two real `stereodyn run` subprocesses (~8 s of CPU each: imports, the truth, the report's
# figures), twice the default suite's budget for a test file; the fast test above covers the machinery
def test_two_versions_of_a_toy_engine_run_line_up_and_are_cached(offline, capsys):
    """Three specifications: 1.0 and 2.0 install and run, 9.9 (no such wheel) is a row saying why. The history over
    1.0 -> 2.0 flags the toy rk4's attitude error as worse at 2.0 (rk4_naive's error at dt 1e-2 over 1 s is ~1e4 x
    rk4's); compare 1 -> 2 is written. A second call builds nothing and reruns nothing: same environment folders
    (their marks untouched), rows marked cached and reused."""
    out = offline / "out"
    argv = ["matrix", f"{DIST}==1.0", f"{DIST}==2.0", f"{DIST}==9.9", "--overlay", "--out", str(out), "--", *RUN]
    assert cli.main(argv) == 0
    printed = capsys.readouterr().out
    rows = pd.read_csv(out / "matrix.csv", keep_default_na=False)
    assert rows["status"].tolist() == ["ok", "ok", "install failed"], rows
    assert "9.9" in rows["reason"][2] and rows["reason"][:2].tolist() == ["", ""]
    assert rows["cached"].tolist() == [False, False, False]
    envs = [Path(p) for p in rows["path"][:2]]
    assert all(p.parent == offline / "cache" / "stereodyn" / "matrix" for p in envs)
    runs = [json.loads((Path(r) / "runs.json").read_text())["environment"] for r in rows["results"][:2]]
    assert [env.get(DIST, "").split()[0] for env in runs] == ["1.0", "2.0"]  # as each run recorded its plug-in
    steps = pd.read_csv(out / "history_steps.csv", keep_default_na=False)
    worse = steps[(steps["engine"] == "mtoy") & (steps["quantity"] == "attitude_err")]
    assert set(worse["label"]) == {f"{DIST}==2.0"} and set(worse["direction"]) == {"worse"}, steps
    assert (out / "compare" / "1-2" / "compare.md").is_file() and (out / "history.html").is_file()
    assert "install failed" in printed
    marks = [(p / "stereodyn-matrix.json").stat().st_mtime_ns for p in envs]

    assert cli.main(argv) == 0
    again = pd.read_csv(out / "matrix.csv", keep_default_na=False)
    assert again["cached"].tolist() == [True, True, False] and again["reused"][:2].tolist() == ["True", "True"]
    assert [(p / "stereodyn-matrix.json").stat().st_mtime_ns for p in envs] == marks
    assert again["path"].tolist() == rows["path"].tolist()


@pytest.mark.parametrize("argv, words", [
    (["mujoco=3"], "matrix: SPEC 'mujoco=3': 'mujoco=3' is not a requirement"),
    (["mujoco==3.3.7 pin==3.4", "--cross"], "matrix --cross: SPEC 'mujoco==3.3.7 pin==3.4': one requirement"),
    (["mujoco==4.0.0", "--", "free-asymmetric", "--out", "x"], "matrix: --out after --"),
    (["mujoco==4.0.0", "mujoco==4.0.0"], "given twice"),
])
def test_bad_input_is_one_line_and_exit_2(tmp_path, capsys, argv, words):
    specs = [a for a in argv[:2] if a.startswith("mujoco")]
    assert cli.main(["matrix", *specs, "--out", str(tmp_path / "o"), *argv[len(specs):]]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and words in err, err


def test_cross_product_of_two_packages():
    from stereodyn.harness.cli.matrix import environments

    got = environments(["mujoco==3.3.7", "mujoco==4.0.0", "pin==3.4.0", "pin==4.1.0"], cross=True)
    assert [label for label, _ in got] == ["mujoco==3.3.7 pin==3.4.0", "mujoco==3.3.7 pin==4.1.0",
                                           "mujoco==4.0.0 pin==3.4.0", "mujoco==4.0.0 pin==4.1.0"]
    assert environments(["mujoco==4.0.0 pin==4.1.0"], cross=False) == [("mujoco==4.0.0 pin==4.1.0",
                                                                         ("mujoco==4.0.0", "pin==4.1.0"))]


@pytest.mark.slow  # builds two isolated environments from the registry (network; ~1 min each the first time, cached
# after) and runs a case in each (~20 s)
def test_two_real_mujoco_releases(tmp_path, capsys):
    """MuJoCo 3.3.7 and 4.0.0 from the registry, each in an isolated environment with stereodyn: the lagrange top's
    rk4 fits order 2 under 3.x (its RK4 is 2nd order on a ball joint) and 4 under 4.0 (measured 2.001 and 3.998 on
    the quick suite, whose dt list this is); the history flags the step, better. A second call builds nothing."""
    argv = ["matrix", "mujoco==3.3.7", "mujoco==4.0.0", "--out", str(tmp_path / "out"), "--", "lagrange-top",
            "--engines", "mujoco", "--integrators", "rk4", "--t-end", "2", "--dt", "1e-2,3e-3", "--no-certify",
            "--jobs", "1", "--quiet"]
    assert cli.main(argv) == 0
    printed = capsys.readouterr().out
    assert "lagrange-top mujoco rk4 (declared 4): mujoco==3.3.7 2.00, mujoco==4.0.0 4.00" in printed, printed
    orders = pd.read_csv(tmp_path / "out" / "orders.csv")
    rk4 = orders[(orders["case"] == "lagrange-top") & (orders["integrator"] == "rk4")].iloc[0]
    assert abs(rk4["mujoco==3.3.7"] - 2.0) < 0.2 and abs(rk4["mujoco==4.0.0"] - 4.0) < 0.2, rk4
    steps = pd.read_csv(tmp_path / "out" / "history_steps.csv", keep_default_na=False)
    order = steps[steps["quantity"] == "order"]
    assert order[["label", "direction"]].values.tolist() == [["mujoco==4.0.0", "better"]]
    assert cli.main(argv) == 0
    again = pd.read_csv(tmp_path / "out" / "matrix.csv")
    assert again["cached"].tolist() == [True, True] and again["status"].tolist() == ["ok", "ok"]


def test_a_bug_in_an_environments_run_is_exit_3_not_a_row(offline, monkeypatch, capsys):
    """A run that ends with exit 3 (a bug in stereodyn, harness/errors.py) ends the matrix with exit 3 and the run's
    traceback; exit 2 there (that environment refused the run arguments, e.g. an engine it lacks) is a row."""
    from stereodyn.harness.cli import matrix

    bug = "import sys; print('Traceback (most recent call last):\\nKeyError: x'); sys.exit({code})"
    out = offline / "out"
    argv = ["matrix", f"{DIST}==1.0", "--overlay", "--out", str(out), "--", *RUN]
    monkeypatch.setattr(matrix, "command", lambda python, argv, folder: [str(python), "-c", bug.format(code=3)])
    assert cli.main(argv) == 3
    err = capsys.readouterr().err
    assert "KeyError: x" in err and "stereodyn: internal error" in err and "ended with exit 3" in err
    monkeypatch.setattr(matrix, "command", lambda python, argv, folder: [str(python), "-c", bug.format(code=2)])
    assert cli.main(argv) == 0
    row = pd.read_csv(out / "matrix.csv", keep_default_na=False).iloc[0]
    assert row["status"] == "run failed" and row["reason"].startswith("stereodyn run exited 2: KeyError: x")
