"""The plug-in guide (docs/integrators.md; in the README before issue 32) is a working package: its blocks (each
opening with `# <project>/PATH`) are extracted, built, pip-installed into a target folder, listed by `stereodyn
integrators`, run by `stereodyn run --integrators kutta3`, and its own tests pass."""
import importlib.metadata
import re
import subprocess
import sys
import tomllib
from pathlib import Path

import pandas as pd
import plugin_packages
import pytest

README = Path(__file__).resolve().parents[1] / "docs" / "integrators.md"  # the guide's page
SECTION = "### Writing one: a complete plug-in package"

def readme_files() -> dict[str, str]:
    """{path: text} of the fenced blocks in the plug-in guide whose first line is `# <project>/PATH`."""
    text = README.read_text(encoding="utf-8")
    section = text.split(SECTION, 1)[1].split("\n## ", 1)[0].split("\n### ", 1)[0]
    files = {}
    for block in re.findall(r"```[a-z]*\n(.*?)```", section, flags=re.S):
        first, _, rest = block.partition("\n")
        match = re.fullmatch(r"# <project>/([\w./-]+\.(?:py|toml))", first.strip())
        if match:
            files[match.group(1)] = rest if match.group(1).endswith(".toml") else block
    return files


def _can_build_with_setuptools() -> bool:
    # The version from the distribution's metadata, not `import setuptools`: where an engine SDK has imported the
    # standard library's distutils first (seen with every extra installed), importing setuptools in this process
    # fails, while the build itself runs in a fresh process.
    try:
        version = importlib.metadata.version("setuptools")
    except importlib.metadata.PackageNotFoundError:
        return False
    major, minor = (int(x) for x in version.split(".")[:2])
    if (major, minor) >= (70, 1):
        return True
    try:
        importlib.metadata.version("wheel")
    except importlib.metadata.PackageNotFoundError:
        return False
    return True


@pytest.fixture(scope="module")
def installed(tmp_path_factory) -> tuple[Path, Path]:
    root = tmp_path_factory.mktemp("readme-plugin")
    files = readme_files()
    # the package's module and its test, by folder and name (written whole, the docs test reads them as citations)
    assert sorted((Path(p).parent.name, Path(p).name) for p in files) == [
        ("", "pyproject.toml"), ("stereodyn_kutta3", "__init__.py"), ("tests", "test_kutta3.py")]
    meta = tomllib.loads(files["pyproject.toml"])
    assert meta["project"]["entry-points"]["stereodyn.integrators"] == {"kutta3": "stereodyn_kutta3:INTEGRATORS"}
    if not _can_build_with_setuptools():
        # setuptools < 70.1 builds wheels only with the `wheel` package installed: the stand-in backend zips the
        # package the guide's [tool.setuptools] names, with the guide's metadata; the files installed are the guide's
        pyproject = files["pyproject.toml"].replace(
            'requires = ["setuptools>=61"]\nbuild-backend = "setuptools.build_meta"',
            'requires = []\nbuild-backend = "zip_backend"\nbackend-path = ["."]')
        assert pyproject != files["pyproject.toml"]
        files = {**files, "pyproject.toml": pyproject}
    return plugin_packages.install(root, files), root / "src"


_env = plugin_packages.env_with


@pytest.mark.slow  # since 2026-12-02, ~23 s; by default the README example's own tests and test_engine_example.py (the default suite's 8 minutes)
def test_the_readme_example_is_listed_and_runs_by_its_class_name(installed, tmp_path):
    target, _ = installed
    listing = subprocess.run([sys.executable, "-m", "stereodyn.harness.cli", "integrators"], capture_output=True,
                             text=True, env=_env(target), cwd=tmp_path)
    assert listing.returncode == 0, listing.stderr
    rows = [line.split() for line in listing.stdout.splitlines() if line.startswith("kutta3 ")]
    assert [row[:4] for row in rows] == [["kutta3", "lie", "3", "3"], ["kutta3", "vector", "3", "3"]]
    assert all("plug-in from stereodyn-kutta3" in " ".join(row) for row in rows)
    out = tmp_path / "out"
    result = subprocess.run([sys.executable, "-m", "stereodyn.harness.cli", "run", "free-asymmetric", "--engines",
                             "pinocchio,reference", "--integrators", "kutta3", "--t-end", "1", "--dt", "0.02,0.01",
                             "--out", str(out), "--quiet", "--jobs", "1"],
                            capture_output=True, text=True, env=_env(target), cwd=tmp_path)
    assert result.returncode == 0, result.stderr[-3000:]
    df = pd.read_csv(out / "results.csv").fillna({"formulation": ""})
    rows = df[df["integrator"] == "kutta3"]
    assert set(rows["engine"]) == {"pinocchio", "reference"} and (rows["status"] == "ok").all()
    assert (rows["attitude_err"] < 1e-4).all()  # 3rd order at dt <= 0.02 over 1 s: ~1e-6 rad
    assert "| kutta3 | plug-in from stereodyn-kutta3 | 3 |" in (out / "report.md").read_text()


def test_the_readme_examples_own_tests_pass(installed):
    target, source = installed
    result = subprocess.run([sys.executable, "-m", "pytest", "-q", "-p", "no:cacheprovider", "tests"],
                            capture_output=True, text=True, env=_env(target), cwd=source)
    assert result.returncode == 0, result.stdout[-3000:] + result.stderr[-2000:]
    assert "2 passed" in result.stdout
