"""docs/ENGINE_PLUGIN.md's engine plug-in is a working package: its blocks (each opening with `# <project>/PATH`) are
extracted, built, pip-installed into a target folder, listed by `stereodyn engines` with its distribution and version,
run in a sweep beside MuJoCo (the same Euler map: its rows agree to round-off), named in the report's environment and
in `compare`, and its own tests pass."""
import re
import subprocess
import sys
import tomllib
from pathlib import Path

import pandas as pd
import plugin_packages
import pytest

GUIDE = Path(__file__).resolve().parents[1] / "docs" / "ENGINE_PLUGIN.md"
DISTRIBUTION = "stereodyn-toy-engine"


def guide_files() -> dict[str, str]:
    """{path: text} of the guide's fenced blocks whose first line is `# <project>/PATH`."""
    files = {}
    for block in re.findall(r"```[a-z]*\n(.*?)```", GUIDE.read_text(encoding="utf-8"), flags=re.S):
        first, _, rest = block.partition("\n")
        match = re.fullmatch(r"# <project>/([\w./-]+\.(?:py|toml))", first.strip())
        if match:
            files[match.group(1)] = rest if match.group(1).endswith(".toml") else block
    return files


@pytest.fixture(scope="module")
def installed(tmp_path_factory) -> tuple[Path, Path]:
    root = tmp_path_factory.mktemp("engine-example")
    files = guide_files()
    # the package's module and its test, by folder and name
    assert sorted((Path(p).parent.name, Path(p).name) for p in files) == [
        ("", "pyproject.toml"), ("stereodyn_toy_engine", "__init__.py"), ("tests", "test_toy_engine.py")]
    meta = tomllib.loads(files["pyproject.toml"])
    assert meta["project"]["entry-points"]["stereodyn.engines"] == {"toy_euler": "stereodyn_toy_engine:ToyEngine"}
    # built by the stand-in backend (tests/plugin_packages.py: no network, no wheel package needed) from the guide's
    # own metadata, entry points and files
    pyproject = files["pyproject.toml"].replace(
        'requires = ["setuptools>=61"]\nbuild-backend = "setuptools.build_meta"',
        'requires = []\nbuild-backend = "zip_backend"\nbackend-path = ["."]')
    assert pyproject != files["pyproject.toml"]
    return plugin_packages.install(root, {**files, "pyproject.toml": pyproject}), root / "src"


def _cli(target: Path, cwd: Path, *argv: str) -> subprocess.CompletedProcess:
    return subprocess.run([sys.executable, "-m", "stereodyn", *argv], capture_output=True, text=True,
                          env=plugin_packages.env_with(target), cwd=cwd, timeout=600)


# slow (issue 28: the default suite within 8 min on 2 idle cores): 20-80 s at load ~6; `pytest -m slow` runs it
@pytest.mark.slow
def test_listed_run_and_named_in_the_environment_and_compare(installed, tmp_path):
    target, _ = installed
    listing = _cli(target, tmp_path, "engines")
    assert listing.returncode == 0, listing.stderr[-3000:]
    assert f"toy_euler: plug-in from {DISTRIBUTION} 0.1.0; installed ({DISTRIBUTION} 0.1.0)" in listing.stdout
    assert "integrators (* in the default sweep): semi_implicit_euler*" in listing.stdout
    runs = []
    for name in ("a", "b"):
        out = tmp_path / name
        result = _cli(target, tmp_path, "run", "lagrange-top", "heavy-asymmetric", "central-field-fixed",
                      "--engines", "toy_euler,mujoco", "--t-end", "1", "--dt", "0.01", "--out", str(out), "--quiet",
                      "--jobs", "1", "--no-ladder")
        assert result.returncode == 0, result.stderr[-3000:]
        runs.append(out)
    df = pd.read_csv(runs[0] / "results.csv")
    toy = df[df["engine"] == "toy_euler"].set_index("case")
    assert (toy.loc[["lagrange-top", "heavy-asymmetric"], "status"] == "ok").all()
    # the central field is a torque the example declares unsupported: a skipped row with its reason
    assert toy.loc["central-field-fixed", "status"] == "skipped"
    assert "gravity only" in toy.loc["central-field-fixed", "message"]
    # MuJoCo's euler is the same map: the errors against the truth agree to round-off (measured equal to 1e-15)
    mujoco = df[(df["engine"] == "mujoco") & (df["integrator"] == "euler")].set_index("case")
    for case in ("lagrange-top", "heavy-asymmetric"):
        assert abs(toy.loc[case, "attitude_err"] - mujoco.loc[case, "attitude_err"]) < 1e-12
    report = (runs[0] / "report.md").read_text()
    assert f"- {DISTRIBUTION}: 0.1.0 (plug-in: engine toy_euler)" in report
    compared = _cli(target, tmp_path, "compare", str(runs[0]), str(runs[1]))
    assert compared.returncode == 0, compared.stderr[-3000:]
    assert DISTRIBUTION in (runs[1] / "compare.md").read_text()


@pytest.mark.slow  # since 2026-12-02, ~10 s; by default the README example's own tests (the default suite's 8 minutes)
def test_the_examples_own_tests_pass(installed):
    target, source = installed
    result = subprocess.run([sys.executable, "-m", "pytest", "-q", "-p", "no:cacheprovider", "tests"],
                            capture_output=True, text=True, env=plugin_packages.env_with(target), cwd=source,
                            timeout=600)
    assert result.returncode == 0, result.stdout[-3000:] + result.stderr[-2000:]
    assert "2 passed" in result.stdout
