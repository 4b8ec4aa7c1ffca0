"""The environment a sweep ran in: library versions and code fingerprints (part of every result's store key), CPU,
date, git commit; and where stereodyn's caches live on this machine (user_cache)."""
from __future__ import annotations

import datetime
import functools
import hashlib
import importlib
import inspect
import os
import platform
import sys
from importlib import metadata
from pathlib import Path

from .words import clipped

# The libraries whose version can change any result (heyoka: the truth); each engine adds its own (About.packages). A
# result is keyed by all of them (harness.run.store).
CORE_PACKAGES = ("numpy", "scipy")
TRUTH_PACKAGES = ("heyoka", "stereodyn")


def user_cache(*parts: str) -> Path:
    """A folder of stereodyn's in the user's cache folder: $XDG_CACHE_HOME/stereodyn/*parts, else
    ~/.cache/stereodyn/*parts (the matrix's environments; JAX's compilation cache for MJX)."""
    base = os.environ.get("XDG_CACHE_HOME") or os.path.join(os.path.expanduser("~"), ".cache")
    return Path(base, "stereodyn", *parts)


def packages() -> tuple[str, ...]:
    """CORE_PACKAGES, every registered engine's packages, then TRUTH_PACKAGES; each once."""
    from .engines import EngineError, engine_names, get_engine

    names = list(CORE_PACKAGES)
    for name in engine_names():
        try:
            names += get_engine(name).about.packages
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


def engine_version(engine: str) -> str:
    """The engine's packages (About.packages) as installed, "mujoco 4.0.0" ("jax 0.6.2, mujoco-mjx 3.17.0" for
    several): the version a result or a verdict of the engine was judged under. "" for an engine not registered."""
    from .engines import EngineError, get_engine

    try:
        names = get_engine(engine).about.packages
    except (EngineError, KeyError):
        return ""
    return ", ".join(f"{name} {_version(name)}" for name in names)


# The import packages whose files make up stereodyn (pyproject.toml maps each to its own folder, so walking the top
# package alone would miss them in an editable install).
SOURCE_PACKAGES = ("stereodyn", "stereodyn.harness", "stereodyn.reference", "stereodyn.cases")
# Files of those folders that are not code a row depends on alone: caches, and the case files (*.toml under
# stereodyn.cases), whose content is in each run's key already (harness.run.store.case_content); hashing them here would
# redo every case's runs when one case changes.
_IGNORED_SUFFIXES = (".pyc", ".pyo")


def source_roots() -> list[tuple[str, Path]]:
    """(package name, folder) of each of SOURCE_PACKAGES as imported, i.e. the installed copy that runs."""
    roots = []
    for name in SOURCE_PACKAGES:
        for folder in importlib.import_module(name).__path__:
            roots.append((name, Path(folder).resolve()))
    return roots


def _tree_files(roots: list[tuple[str, Path]]) -> dict[str, Path]:
    """{label: file} of every file under the roots but caches and case files; a file under two roots (a wheel nests
    the subpackages in stereodyn/) is labelled from the deepest, so an editable and a wheel install agree."""
    files: dict[Path, tuple[str, Path]] = {}
    for name, root in sorted(roots, key=lambda item: len(item[1].parts)):
        for path in root.rglob("*"):
            if (not path.is_file() or "__pycache__" in path.parts or path.suffix in _IGNORED_SUFFIXES
                    or (name.startswith("stereodyn.cases") and path.suffix == ".toml")):
                continue
            files[path] = (name, root)  # the deeper root, sorted last, wins
    return {f"{name}/{path.relative_to(root).as_posix()}": path for path, (name, root) in files.items()}


def _hash_files(files: dict[str, Path]) -> str:
    digest = hashlib.sha256()
    for label in sorted(files):
        digest.update(label.encode() + b"\0" + files[label].read_bytes() + b"\0")
    return digest.hexdigest()[:24]


@functools.cache
def _source_fingerprint(roots: tuple[tuple[str, Path], ...]) -> str:
    return _hash_files(_tree_files(list(roots)))


def source_fingerprint() -> str:
    """sha256 (24 hex digits) of every source and data file of the running stereodyn (SOURCE_PACKAGES, case files
    excepted), so a result is keyed by the code that computed it, not only by its version string. Computed once per
    process (~70 files, a few ms)."""
    return _source_fingerprint(tuple(source_roots()))


@functools.cache
def _distributions() -> dict[str, list[str]]:
    return metadata.packages_distributions()


@functools.cache
def _module_tree_hash(top: str) -> str:
    """sha256 of the .py files of a top-level module or package (its folder), or of its one file."""
    module = sys.modules.get(top) or importlib.import_module(top)
    paths = [Path(p).resolve() for p in getattr(module, "__path__", ())]
    if paths:
        files = {f"{top}/{f.relative_to(root).as_posix()}": f for root in paths for f in root.rglob("*.py")
                 if "__pycache__" not in f.parts}
    else:
        file = getattr(module, "__file__", None)
        files = {top: Path(file)} if file else {}
    if not files:  # no file to read (built in, or made at run time): what inspect can still see
        return hashlib.sha256(repr(sorted(vars(module))).encode()).hexdigest()[:24]
    return _hash_files(files)


PLUGIN_GROUPS = ("stereodyn.engines", "stereodyn.integrators", "stereodyn.scenes", "stereodyn.report_sections",
                 "stereodyn.torque_models")


def plugin_sources() -> str:
    """One hash of the .py files of every plug-in module this environment's entry points name (stereodyn's own
    left out: its source fingerprint covers them), found without importing them (importlib.util.find_spec of the
    top-level module; a module that cannot be found counts by its name alone). The matrix's overlay key holds it: an
    edited plug-in gave "runs reused" with the old code's rows (issue 46's eleventh attack, F7)."""
    import importlib.util

    files: dict[str, Path] = {}
    names = set()
    for group in PLUGIN_GROUPS:
        for entry in metadata.entry_points(group=group):
            top = entry.value.split(":")[0].split(".")[0].strip()
            if top and top != "stereodyn":
                names.add(top)
    for top in sorted(names):
        try:
            spec = importlib.util.find_spec(top)
        except (ImportError, ValueError):
            spec = None
        roots = [Path(p) for p in (spec.submodule_search_locations or ())] if spec is not None else []
        if roots:
            files.update({f"{top}/{f.relative_to(root).as_posix()}": f for root in roots for f in root.rglob("*.py")
                          if "__pycache__" not in f.parts and f.is_file()})
        elif spec is not None and spec.origin and Path(spec.origin).is_file():
            files[top] = Path(spec.origin)
    return hashlib.sha256((",".join(sorted(names)) + _hash_files(files)).encode()).hexdigest()[:24]


def code_origin(cls: type) -> dict[str, str]:
    """Where a class (a plug-in integrator or engine) comes from: {"distribution", "version", "source"}.

    distribution and version: the installed distribution that provides the class's top-level module ("none" and "" for
    a module on sys.path that no distribution owns); source: a hash of that top-level module's .py files, so a change
    to a plug-in's code without a new version still changes every key that uses it. stereodyn's own classes get its
    source_fingerprint().
    """
    top = cls.__module__.split(".")[0]
    if top == "stereodyn":
        return {"distribution": "stereodyn", "version": _version("stereodyn"), "source": source_fingerprint()}
    names = _distributions().get(top) or []
    distribution = names[0] if names else "none"
    version = _version(distribution) if names else ""
    try:
        source = _module_tree_hash(top)
    except ImportError:  # e.g. a class defined in __main__ of another process
        source = hashlib.sha256(inspect.getsource(cls).encode()).hexdigest()[:24]
    return {"distribution": distribution, "version": version, "source": source}


def clear_fingerprints() -> None:
    """Forget the fingerprints computed so far (what a new process would see); for tests."""
    _source_fingerprint.cache_clear()
    _module_tree_hash.cache_clear()
    _distributions.cache_clear()


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


OWN_DISTRIBUTION = "stereodyn"


def entry_distribution(entry) -> tuple[str, str]:
    """(name, version) of the distribution that registers an entry point ("", "") where none does."""
    dist = getattr(entry, "dist", None)
    if dist is None:
        return "", ""
    name = dist.metadata["Name"] or ""
    return name, dist.version or ""


def plugin_distributions() -> dict[str, str]:
    """{distribution: "VERSION (engine NAME, ...; integrators)"} of every installed distribution other than stereodyn
    that registers an engine or integrator plug-in (read from the entry points; nothing is imported): the sweep's
    environment, so the report and `compare` show them."""
    from importlib.metadata import entry_points

    found: dict[str, list[str]] = {}
    versions: dict[str, str] = {}
    for group, what in (("stereodyn.engines", "engine"), ("stereodyn.integrators", "integrators")):
        for entry in entry_points(group=group):
            dist, dist_version = entry_distribution(entry)
            if not dist or dist.lower() == OWN_DISTRIBUTION:
                continue
            versions[dist] = dist_version
            found.setdefault(dist, []).append(f"{what} {entry.name}")
    return {dist: f"{versions[dist]} (plug-in: {', '.join(found[dist])})" for dist in sorted(found)}


def environment() -> dict[str, str]:
    """Everything a report's footer states about where the numbers came from: the libraries, every installed plug-in
    distribution (engines and integrators: plugin_distributions), the machine."""
    found = {**library_versions(), "pandas": _version("pandas"), **plugin_distributions(), "cpu": cpu_name(),
             "machine": platform.machine(),
             "platform": platform.platform(), "date": datetime.datetime.now().astimezone().isoformat(timespec="seconds"),
             "git commit": git_commit()}
    return {clipped(name): clipped(value) for name, value in found.items()}  # a plug-in distribution's is any text


# runs.json's environment keys of the machine's load when the timing phase starts and ends (harness.run.sweep): the
# timings are taken on whatever else the machine runs, and this says how busy it was.
TIMING_START, TIMING_END = "load at timing start", "load at timing end"


# What a result folder's or baseline's environment records is of two kinds, and every reader (check, compare,
# history) tells them apart by this one rule (differences). The environment: what can change a number (library
# versions, the CPU model, the platform, plug-ins and code hashes); two runs in the same environment agree bit for
# bit. The measurement context: when and under what load the numbers were made (the date, the commit checked out, the
# load at the start and end of timing, when the report was rendered); it differs on every run and changes no number
# (the code a commit holds is in the environment, as its source hash).
CONTEXT = ("date", "git commit", "report rendered", TIMING_START, TIMING_END)
# The hash of stereodyn's own source, in a result folder's environment (runs.json's code); a baseline keeps none (the
# gate does not compare it: it changes with every commit), so a baseline's lack of it is no difference.
OWN_SOURCE = "stereodyn source"


def is_context(name: str) -> bool:
    """Whether an environment entry is measurement context (CONTEXT), not environment."""
    return name in CONTEXT


def differences(a: dict, b: dict) -> list[str]:
    """The environment entries that differ between two recorded environments, in first-seen order: context never
    (is_context), OWN_SOURCE only where both record it; an entry one side lacks reads as "-" there."""
    names = list(dict.fromkeys([*a, *b]))
    return [name for name in names if not is_context(name)
            and not (name == OWN_SOURCE and (name not in a or name not in b))
            and str(a.get(name, "-")) != str(b.get(name, "-"))]


def load_snapshot() -> str:
    """The load average (1, 5, 15 min), the number of CPUs, the CPU model and the time: one line for the report's
    Environment section."""
    try:
        load = ", ".join(f"{x:.2f}" for x in os.getloadavg())
    except (OSError, AttributeError):  # not on this platform
        load = "unknown"
    now = datetime.datetime.now().astimezone().isoformat(timespec="seconds")
    return f"load average {load} (1, 5, 15 min) on {os.cpu_count()} CPUs, {cpu_name()}, at {now}"


def _version(package: str) -> str:
    try:
        return metadata.version(package)
    except metadata.PackageNotFoundError:
        return "absent"
