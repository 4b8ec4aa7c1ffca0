"""The distribution: one import package, stereodyn, built from the repository's top-level folders (pyproject.toml
package-dir). A user's folders named cases/, harness.py or reference/ can neither shadow it nor be shadowed by it."""
from __future__ import annotations

import os
import subprocess
import sys
import tomllib
import zipfile
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
FOLDERS = {"stereodyn": "stereodyn", "harness": "stereodyn.harness", "reference": "stereodyn.reference",
           "cases": "stereodyn.cases"}


def _tree_packages() -> set[str]:
    """The import names of every folder under the mapped folders that holds an __init__.py."""
    found = set()
    for folder, package in FOLDERS.items():
        for init in (ROOT / folder).rglob("__init__.py"):
            relative = init.parent.relative_to(ROOT / folder).parts
            found.add(".".join((package, *relative)))
    return found


@pytest.fixture(scope="module")
def wheel(tmp_path_factory) -> Path:
    out = tmp_path_factory.mktemp("wheel")
    result = subprocess.run([sys.executable, "-m", "pip", "wheel", "--quiet", "--no-deps",
                             "--wheel-dir", str(out), str(ROOT)], capture_output=True, text=True, cwd=out)
    if result.returncode != 0:
        pytest.fail(f"pip wheel failed: {result.stderr[-2000:]}")
    return next(out.glob("stereodyn-*.whl"))


@pytest.fixture(scope="module")
def site(wheel, tmp_path_factory) -> Path:
    """The wheel installed into a target folder (not into the venv, which holds the editable checkout)."""
    target = tmp_path_factory.mktemp("site")
    subprocess.run([sys.executable, "-m", "pip", "install", "--quiet", "--no-deps", "--target", str(target),
                    str(wheel)], check=True, capture_output=True)
    return target


def test_the_declared_packages_are_the_folders_with_an_init():
    declared = set(tomllib.loads((ROOT / "pyproject.toml").read_text())["tool"]["setuptools"]["packages"])
    assert declared == _tree_packages()


def test_the_wheel_holds_stereodyn_only_and_every_package(wheel):
    names = zipfile.ZipFile(wheel).namelist()
    top = {name.split("/")[0] for name in names if not name.split("/")[0].endswith((".dist-info", ".data"))}
    assert top == {"stereodyn"}
    shipped = {str(Path(name).parent).replace("/", ".") for name in names if name.endswith("/__init__.py")}
    assert shipped == _tree_packages()
    assert "stereodyn/cases/kovalevskaya.toml" in names and "stereodyn/cases/extreme/fast-spin.toml" in names


def _python(site: Path, cwd: Path, code: str) -> subprocess.CompletedProcess:
    env = dict(os.environ, PYTHONPATH=str(site))  # the installed copy comes before the venv's editable checkout
    return subprocess.run([sys.executable, "-c", code], cwd=cwd, env=env, capture_output=True, text=True, timeout=120)


def test_installed_package_imports_from_anywhere_and_bare_names_fail(site, tmp_path):
    result = _python(site, tmp_path, "import stereodyn.harness.cli, stereodyn.reference.truth, stereodyn; "
                                     "print(stereodyn.__file__)")
    assert result.returncode == 0, result.stderr
    assert Path(result.stdout.strip()).is_relative_to(site)
    for bare in ("harness", "reference", "cases"):
        result = _python(site, tmp_path, f"import {bare}")
        assert result.returncode != 0 and "ModuleNotFoundError" in result.stderr, bare


def test_a_users_folders_do_not_shadow_the_suite(site, tmp_path):
    """cases/__init__.py, harness.py and reference/ in the working directory: `stereodyn cases` lists the suite."""
    (tmp_path / "cases").mkdir()
    (tmp_path / "cases" / "__init__.py").write_text("")
    (tmp_path / "harness.py").write_text("raise SystemExit('the user harness.py was imported')\n")
    (tmp_path / "reference").mkdir()
    (tmp_path / "reference" / "rotations.py").write_text("raise SystemExit('the user rotations.py was imported')\n")
    result = _python(site, tmp_path, "from stereodyn.harness.cli import main; main(['cases'])")
    assert result.returncode == 0, result.stderr
    listed = {line.split()[0] for line in result.stdout.splitlines() if line.strip()}
    assert {path.stem for path in (ROOT / "cases").glob("*.toml")} <= listed


def test_the_checkouts_folders_refuse_their_bare_names():
    """From the repository root a bare `import harness` finds the folder itself: it must say what to do instead."""
    for bare in ("harness", "reference", "cases"):
        result = subprocess.run([sys.executable, "-c", f"import {bare}"], cwd=ROOT, capture_output=True, text=True)
        assert result.returncode != 0 and f"stereodyn.{bare}" in result.stderr.splitlines()[-1], bare


def test_python_dash_m_stereodyn_is_the_command(tmp_path):
    result = subprocess.run([sys.executable, "-m", "stereodyn", "cases"], cwd=tmp_path, capture_output=True,
                            text=True, timeout=120)
    assert result.returncode == 0 and "kovalevskaya" in result.stdout


def test_ci_installs_and_tests_exactly_as_the_readme_says():
    """The README's second command (install, then the test command) is what .ci/run runs."""
    readme, ci = (ROOT / "README.md").read_text(), (ROOT / ".ci" / "run").read_text()
    blocks = [block.split("```", 1)[0].strip() for block in readme.split("```sh\n")[1:3]]
    install, test = blocks[1].split(" && ")
    assert install.startswith("pip install -e ")  # editable: pytest tests the checkout, not a stale copy
    ci_lines = [line.split("#")[0].strip() for line in ci.splitlines()]
    assert install in ci_lines and test in ci_lines
    assert ci_lines.index(install) < ci_lines.index(test)
    assert blocks[0].endswith("stereodyn run")
