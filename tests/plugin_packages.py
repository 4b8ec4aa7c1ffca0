"""Plug-in packages for the tests: written to a temporary folder and pip-installed into a target folder (the venv
is not touched), offline. tests/test_engine_plugins.py, test_plugin.py and test_readme_plugin.py share it."""
import os
import subprocess
import sys
from pathlib import Path

import pytest

# A PEP 517 backend in the package's own tree (backend-path): it zips the packages that [tool.setuptools] names, with
# the project's metadata and entry points, so building needs neither network (build isolation) nor a setuptools with
# bdist_wheel in the venv.
ZIP_BACKEND = '''
import base64, hashlib, tomllib, zipfile
from pathlib import Path


def get_requires_for_build_wheel(config_settings=None):
    return []


def build_wheel(wheel_directory, config_settings=None, metadata_directory=None):
    meta = tomllib.loads(Path("pyproject.toml").read_text())
    project, packages = meta["project"], meta["tool"]["setuptools"]["packages"]
    stem = project["name"].replace("-", "_")
    dist_info = f"{stem}-{project['version']}.dist-info"
    entries = "".join(f"[{group}]\\n" + "".join(f"{k} = {v}\\n" for k, v in points.items())
                      for group, points in project.get("entry-points", {}).items())
    files = {f"{dist_info}/METADATA":
             f"Metadata-Version: 2.1\\nName: {project['name']}\\nVersion: {project['version']}\\n",
             f"{dist_info}/WHEEL":
             "Wheel-Version: 1.0\\nGenerator: fallback\\nRoot-Is-Purelib: true\\nTag: py3-none-any\\n",
             f"{dist_info}/entry_points.txt": entries}
    for package in packages:
        for path in Path(package).rglob("*.py"):
            files[path.as_posix()] = path.read_text()
    name = f"{stem}-{project['version']}-py3-none-any.whl"
    record = []
    with zipfile.ZipFile(Path(wheel_directory) / name, "w") as wheel:
        for path, text in files.items():
            data = text.encode()
            wheel.writestr(path, data)
            digest = base64.urlsafe_b64encode(hashlib.sha256(data).digest()).rstrip(b"=").decode()
            record.append(f"{path},sha256={digest},{len(data)}")
        record.append(f"{dist_info}/RECORD,,")
        wheel.writestr(f"{dist_info}/RECORD", "\\n".join(record) + "\\n")
    return name
'''

# The [build-system] table that selects ZIP_BACKEND (written as zip_backend.py beside pyproject.toml by install()).
BUILD_SYSTEM = '[build-system]\nrequires = []\nbuild-backend = "zip_backend"\nbackend-path = ["."]\n'


def pyproject(package: str, entry_points: dict[str, dict[str, str]]) -> str:
    """A pyproject.toml for ZIP_BACKEND: project `package` (dashes for underscores) 0.1.0 with one import package."""
    groups = "".join(f'\n[project.entry-points."{group}"]\n' + "".join(f'{k} = "{v}"\n' for k, v in points.items())
                     for group, points in entry_points.items())
    return (f'{BUILD_SYSTEM}\n[project]\nname = "{package.replace("_", "-")}"\nversion = "0.1.0"\n{groups}'
            f'\n[tool.setuptools]\npackages = ["{package}"]\n')


def install(root: Path, files: dict[str, str]) -> Path:
    """Write files ({relative path: text}) under root/src, pip-install that project into root/site; returns root/site.
    A project whose pyproject.toml uses ZIP_BACKEND gets zip_backend.py written beside it."""
    source = root / "src"
    for path, text in files.items():
        (source / path).parent.mkdir(parents=True, exist_ok=True)
        (source / path).write_text(text)
    if 'build-backend = "zip_backend"' in files.get("pyproject.toml", ""):
        (source / "zip_backend.py").write_text(ZIP_BACKEND)
    target = root / "site"
    result = subprocess.run([sys.executable, "-m", "pip", "install", "--quiet", "--no-build-isolation", "--no-deps",
                             "--target", str(target), str(source)], capture_output=True, text=True, cwd=root)
    if result.returncode != 0:
        pytest.fail(f"pip install failed: {result.stderr[-2000:]}")
    return target


def env_with(target: Path) -> dict:
    """os.environ with target first on PYTHONPATH, for a subprocess that sees the installed package."""
    env = dict(os.environ)
    env["PYTHONPATH"] = os.pathsep.join([str(target), env.get("PYTHONPATH", "")]).rstrip(os.pathsep)
    return env
