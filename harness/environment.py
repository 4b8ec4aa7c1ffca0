"""The environment a sweep ran in: library versions (part of every result's store key), CPU, date, git commit."""
from __future__ import annotations

import datetime
import platform
from importlib import metadata
from pathlib import Path

# The libraries whose version can change any result (heyoka: the truth); each engine adds its own (Engine.packages). A
# result is keyed by all of them (harness.store).
CORE_PACKAGES = ("numpy", "scipy")
TRUTH_PACKAGES = ("heyoka", "stereodyn")


def packages() -> tuple[str, ...]:
    """CORE_PACKAGES, every registered engine's packages, then TRUTH_PACKAGES; each once."""
    from stereodyn.harness.engines import EngineError, engine_names, get_engine

    names = list(CORE_PACKAGES)
    for name in engine_names():
        try:
            names += get_engine(name).packages
        except EngineError:  # a broken plug-in fails where it is used, not in every sweep
            continue
    return tuple(dict.fromkeys(names + list(TRUTH_PACKAGES)))


def library_versions() -> dict[str, str]:
    """{"python": ..., package: version or "absent"} for packages()."""
    versions = {"python": platform.python_version()}
    for package in packages():
        try:
            versions[package] = metadata.version(package)
        except metadata.PackageNotFoundError:
            versions[package] = "absent"
    return versions


def cpu_name() -> str:
    """The CPU model (Linux /proc/cpuinfo), else what platform knows."""
    try:
        for line in Path("/proc/cpuinfo").read_text(errors="replace").splitlines():
            if line.lower().startswith(("model name", "hardware", "cpu model")):
                return line.split(":", 1)[1].strip()
    except OSError:
        pass
    return platform.processor() or platform.machine()


def _git_dir(start: Path) -> Path | None:
    for folder in (start, *start.parents):
        candidate = folder / ".git"
        if candidate.is_dir():
            return candidate
        if candidate.is_file():  # a worktree or submodule: "gitdir: PATH"
            text = candidate.read_text(errors="replace").strip()
            if text.startswith("gitdir:"):
                target = Path(text.split(":", 1)[1].strip())
                return target if target.is_absolute() else folder / target
    return None


def git_commit(start: Path | None = None) -> str:
    """The checked-out commit of the repository holding `start` (default: this package, then the working folder).

    Read from .git directly (HEAD, loose refs, packed-refs), so it needs no git executable; "unknown" outside a
    repository, e.g. for an installed copy run elsewhere.
    """
    starts = [start] if start is not None else [Path(__file__).resolve().parent, Path.cwd().resolve()]
    for begin in starts:
        git = _git_dir(begin)
        if git is None:
            continue
        try:
            head = (git / "HEAD").read_text().strip()
            if not head.startswith("ref:"):
                return head
            ref = head.split(":", 1)[1].strip()
            common = git
            if (git / "commondir").is_file():
                common = (git / (git / "commondir").read_text().strip()).resolve()
            for root in (git, common):
                if (root / ref).is_file():
                    return (root / ref).read_text().strip()
                packed = root / "packed-refs"
                if packed.is_file():
                    for line in packed.read_text().splitlines():
                        if line.endswith(" " + ref):
                            return line.split()[0]
            return f"none yet (on {ref})"
        except OSError:
            continue
    return "unknown"


def environment() -> dict[str, str]:
    """Everything a report's footer states about where the numbers came from."""
    return {**library_versions(), "pandas": _version("pandas"), "cpu": cpu_name(), "machine": platform.machine(),
            "platform": platform.platform(), "date": datetime.datetime.now().astimezone().isoformat(timespec="seconds"),
            "git commit": git_commit()}


def _version(package: str) -> str:
    try:
        return metadata.version(package)
    except metadata.PackageNotFoundError:
        return "absent"
