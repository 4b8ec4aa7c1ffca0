"""Isolated Python environments for `stereodyn matrix`: one per package specification, built with uv, with stereodyn
installed in each, cached in the user's cache folder and reused while the specification, the Python and stereodyn's
source are the same.

A failed install is data (Environment.reason), as a failed run is: the matrix shows it as a row.
"""
from __future__ import annotations

import functools
import hashlib
import json
import os
import shutil
import signal
import subprocess
import sys
from collections.abc import Iterator
from contextlib import contextmanager
from dataclasses import dataclass
from pathlib import Path

try:
    import fcntl
except ImportError:  # not on this platform: no lock (as harness.run.store)
    fcntl = None

from .. import environment as env_info
from ..atomic import write_atomic

MARK = "stereodyn-matrix.json"   # written last: an environment without it is half built and is built again
# an install resolving and downloading engines' wheels (MuJoCo, Pinocchio, heyoka: ~200 MB) takes minutes the first
# time; past this it is a failed install, not a hung command
INSTALL_TIMEOUT_S = 1800


class UvMissing(RuntimeError):
    """uv is neither installed as the `uv` package nor on PATH: bad input (exit 2), naming the install command."""


@dataclass(frozen=True)
class Environment:
    """One built (or failed) environment. python: its interpreter (None when the install failed); reason: why the
    install failed ("" when it did not); cached: reused from an earlier matrix."""

    requirements: tuple[str, ...]
    path: Path
    python: Path | None
    cached: bool
    reason: str = ""


def uv_binary() -> str:
    """The uv executable: the `uv` package's (pip install 'stereodyn[matrix]'), else one on PATH."""
    try:
        from uv import find_uv_bin

        return find_uv_bin()
    except (ImportError, FileNotFoundError):
        found = shutil.which("uv")
        if found:
            return found
    raise UvMissing("matrix: needs uv (pip install 'stereodyn[matrix]', or uv on PATH)")


def cache_root() -> Path:
    """The user's cache folder for the matrix's environments ($XDG_CACHE_HOME or ~/.cache, then stereodyn/matrix)."""
    return env_info.user_cache("matrix")


def stereodyn_source() -> str:
    """What to install as stereodyn: this checkout (the folder holding pyproject.toml above the running package) or,
    for an installed wheel, its version from the registry."""
    import stereodyn

    root = Path(stereodyn.__file__).resolve().parent.parent
    if (root / "pyproject.toml").is_file() and (root / "harness").is_dir():
        return str(root)
    return f"stereodyn=={stereodyn.__version__}"


def key(requirements: tuple[str, ...], stereodyn: str, overlay: bool) -> str:
    """The cache key: the requirements, the Python, what stereodyn is (a checkout: its source fingerprint and its
    pyproject.toml, which holds the dependency ranges) and the overlay's base (its site folders, and the source of
    the plug-ins there: an edited plug-in is another environment, whose runs are run again)."""
    import site

    source = stereodyn
    if Path(stereodyn).is_dir():
        source = env_info.source_fingerprint() + hashlib.sha256(
            (Path(stereodyn) / "pyproject.toml").read_bytes()).hexdigest()[:16]
    text = json.dumps({"requirements": sorted(requirements), "python": sys.version, "executable": sys.executable,
                       "stereodyn": source,
                       "overlay": [site.getsitepackages(), env_info.plugin_sources()] if overlay else None},
                      sort_keys=True)
    return hashlib.sha256(text.encode()).hexdigest()[:20]


def _python(path: Path) -> Path:
    return path / ("Scripts/python.exe" if os.name == "nt" else "bin/python")


def _reason(done: subprocess.CompletedProcess) -> str:
    """uv's error as one line: its lines joined (uv explains a conflict over several), at most 400 characters."""
    lines = [line.strip() for line in (done.stderr or done.stdout or "").splitlines() if line.strip()]
    text = " ".join(line for line in lines if not line.startswith(("Using ", "Resolved ", "Prepared ", "Installed ",
                                                                     "Audited ", "Uninstalled ", " + ", " - ")))
    return (text or f"uv exited with {done.returncode}")[:400]


def _running_versions(uv: str, requirements: tuple[str, ...]) -> str:
    """The running environment's packages as constraints (name==version), those the requirements name left out: an
    overlay's requirements bring their own dependencies, at the versions the packages it shares were built with."""
    from packaging.requirements import Requirement
    from packaging.utils import canonicalize_name

    named = {canonicalize_name(Requirement(r).name) for r in requirements}
    done = _uv(uv, "pip", "freeze", "--python", sys.executable)
    pins = [line for line in done.stdout.splitlines() if "==" in line and not line.startswith("-")
            and " @ " not in line and canonicalize_name(line.split("==")[0]) not in named]
    return "\n".join(pins) + "\n"


def _tie_to_parent(signum: int) -> None:
    """In the child, before it executes: the kernel sends it signum the moment the matrix dies, even by SIGKILL
    (Linux PR_SET_PDEATHSIG; a run's own workers are tied to the run the same way, harness/run/processes.py)."""
    from .processes import parent_death_signal

    parent_death_signal(signum)


# After SIGTERM, how long an owned process group gets to end before SIGKILL.
STOP_GRACE_S = 5.0


def owned(argv: list[str], timeout: float | None = None, death_signal: int = signal.SIGKILL,
          **options) -> subprocess.CompletedProcess:
    """subprocess.run for the matrix's children (uv, an environment's `stereodyn run`): each in a process group of its
    own and tied to the matrix by the parent-death signal (death_signal), so that nothing it started outlives the
    matrix. Whatever ends the wait (Ctrl-C or SIGTERM of the matrix, which raise KeyboardInterrupt here:
    harness/cli/matrix.py; the timeout) ends the whole group first: SIGTERM, then SIGKILL after STOP_GRACE_S. A
    SIGKILLed matrix ends its child by the parent-death signal: SIGKILL (uv), or for a run SIGTERM, which the run
    takes as the user's, ending its workers and what they started (SIGKILL left a plug-in's daemons to init)."""
    process = subprocess.Popen(argv, process_group=0, preexec_fn=functools.partial(_tie_to_parent, death_signal),
                               **options)
    try:
        out, err = process.communicate(timeout=timeout)
    except BaseException:
        stop_group(process)
        raise
    return subprocess.CompletedProcess(argv, process.returncode, out, err)


def stop_group(process: subprocess.Popen) -> None:
    """End an owned process and its group: SIGTERM, SIGKILL past STOP_GRACE_S; waited for."""
    for sig in (signal.SIGTERM, signal.SIGKILL):
        try:
            os.killpg(process.pid, sig)
        except (ProcessLookupError, PermissionError):
            break
        try:
            process.wait(timeout=STOP_GRACE_S)
            break
        except subprocess.TimeoutExpired:
            continue
    try:  # the group's other members (a worker of the run) are gone with SIGKILL, or by their own parent-death tie
        os.killpg(process.pid, signal.SIGKILL)
    except (ProcessLookupError, PermissionError):
        pass
    process.wait()


def _uv(uv: str, *argv: str) -> subprocess.CompletedProcess:
    try:
        return owned([uv, *argv], timeout=INSTALL_TIMEOUT_S, stdout=subprocess.PIPE, stderr=subprocess.PIPE,
                     text=True)
    except subprocess.TimeoutExpired:
        return subprocess.CompletedProcess([uv, *argv], 1, "", f"uv {argv[0]} took more than {INSTALL_TIMEOUT_S} s")


def build(requirements: tuple[str, ...], stereodyn: str | None = None, overlay: bool = False,
          root: Path | None = None) -> Environment:
    """The environment of `requirements` (pip requirement strings), built or reused from the cache.

    Isolated (the default): `uv venv` with this Python, then stereodyn (`stereodyn`, default stereodyn_source()) and
    the requirements installed together, so that the resolver holds them to stereodyn's declared ranges. overlay:
    only the requirements, without their dependencies, over the running environment's packages (a .pth adds its
    site folders after the environment's own, so what the requirements install shadows them): seconds instead of
    minutes, but not isolated."""
    uv = uv_binary()
    stereodyn = stereodyn or stereodyn_source()
    path = (root or cache_root()) / key(requirements, stereodyn, overlay)
    python = _python(path)
    if (path / MARK).is_file() and python.exists():
        return Environment(requirements, path, python, cached=True)
    path.parent.mkdir(parents=True, exist_ok=True)
    with _building(path):  # another matrix building it meanwhile: waited for, never deleted under it
        if (path / MARK).is_file() and python.exists():
            return Environment(requirements, path, python, cached=True)
        return _build(requirements, stereodyn, overlay, path, python, uv)


@contextmanager
def _building(path: Path) -> Iterator[None]:
    """Hold the exclusive lock of an environment's folder (PATH.lock beside it) while it is built."""
    fd = os.open(f"{path}.lock", os.O_RDWR | os.O_CREAT, 0o644)
    try:
        if fcntl is not None:
            fcntl.flock(fd, fcntl.LOCK_EX)
        yield
    finally:
        os.close(fd)  # releases the lock


def _build(requirements: tuple[str, ...], stereodyn: str, overlay: bool, path: Path, python: Path,
           uv: str) -> Environment:
    import site

    if path.exists():  # half built (killed, or a failed install): built again from nothing
        shutil.rmtree(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    done = _uv(uv, "venv", "--quiet", "--python", sys.executable, str(path))
    if done.returncode == 0 and overlay:
        folders = [p for p in site.getsitepackages() if os.path.isdir(p)]
        own = owned([str(python), "-c", "import sysconfig; print(sysconfig.get_paths()['purelib'])"],
                    stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True).stdout.strip()
        write_atomic(Path(own) / "_stereodyn_matrix_overlay.pth",
                     "".join(f"import site; site.addsitedir({folder!r})\n" for folder in folders))
        constraints = path / "overlay-constraints.txt"
        write_atomic(constraints, _running_versions(uv, requirements))
        done = _uv(uv, "pip", "install", "--python", str(python), "--constraint", str(constraints), *requirements)
    elif done.returncode == 0:
        done = _uv(uv, "pip", "install", "--python", str(python), stereodyn, *requirements)
    if done.returncode != 0:
        reason = _reason(done)
        shutil.rmtree(path, ignore_errors=True)
        return Environment(requirements, path, None, cached=False, reason=reason)
    write_atomic(path / MARK, json.dumps({"requirements": list(requirements), "stereodyn": stereodyn,
                                          "overlay": overlay}, indent=1) + "\n")
    return Environment(requirements, path, python, cached=False)
