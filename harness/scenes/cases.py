"""Case files (DESIGN §3): loading, validation, the suite shipped in the `cases` package."""
from __future__ import annotations

import dataclasses
import math
from contextlib import contextmanager
from dataclasses import dataclass
from importlib.resources import files
from pathlib import Path
from typing import Any, Iterable, Sequence

import numpy as np

from ...reference import plugins
from .base import kinds, scene
from .case import RIGID_BODY, Case
from ...reference.exact import ORACLES as EXACT_SOLUTIONS
from ...reference.sliding_ladder import Ladder
from ...reference.torque_models import TorqueModelError, load_plugins, models
from ..readers import ReadError, read_toml

# The exact solutions a case may name in [expect] oracle (DESIGN §3; each lives in reference/exact).
ORACLES = ("euler_poinsot", "euler_poinsot_separatrix", "lagrange_precession", "staude_rotation",
           "grioli_precession", "hess_grioli", "mlodzejowski", "self_excited_spinup", "self_excited_uniform")
# The oracles whose exact solutions model a torque (their checks see it through Case.body; TorqueModel.oracles).
TORQUE_ORACLES = tuple(dict.fromkeys(oracle for model in models() for oracle in model.oracles))
# Scene kinds (top-level `kind`): a rigid body with a fixed point (default, RIGID_BODY: harness.scenes.case), and the
# sliding ladder (FORMULARY T5).
SLIDING_LADDER = "sliding_ladder"

DEFAULT_SAMPLES = 1000
UNIT_TOL = 1e-9            # |v| within this of 1 is normalised, further off is an error (DESIGN §3)
SYMMETRY_RTOL = 1e-12      # relative to the largest inertia entry
TRIANGLE_RTOL = 1e-12      # relative to the largest principal moment at O: round-off of Huygens–Steiner, planar bodies
# The numeric ranges a double computation of one body carries (docs/limits.md). Every number of a case file has
# |x| <= MAX_MAGNITUDE; the scales (mass, principal moments about O, lengths, the field's mu and radius, t_end, dt,
# horizon) are >= MIN_SCALE. Within these the worst products of the equations (I ω × ω ~ 1e18, 3 μ / r³ ~ 1e33, the
# inverse inertia ~ 1e9 times a torque ~ 1e18) stay ~1e270 below overflow and their squares far above underflow; what
# such a body does (a truth of too many steps, a run that diverges) is then data, not an exception.
MAX_MAGNITUDE = 1e6
MIN_SCALE = 1e-9
MAX_SAMPLES = 100_000      # recorded states per run
MAX_STEPS = 10_000_000     # t_end / dt per run: 10x the extremes' long horizon (1e6 steps)
# A case's name is in every row of results.csv and checks.csv, in each store record and in the report's tables: a
# 100 000-character name made a 38 MB results.csv and a 2 MB one hung the report (issue 22); 200 characters is a few
# times the longest a report table shows on one line.
MAX_NAME = 200
MAX_DTS = 32               # steps in one dt list: the truth samples the union of their grids, <= 3.2e6 states (180 MB)

_TABLES: dict[str, tuple[frozenset[str], frozenset[str]]] = {
    # table: (allowed keys, required keys)
    # and the torque models' tables (reference.torque_models: each model's key and schema)
    "": (frozenset({"name", "description", "tags", "kind", "body", "gravity", "initial", "run", "expect"}),
         frozenset({"body", "initial", "run"})),
    "body": (frozenset({"mass", "com", "inertia", "principal_moments", "physical"}), frozenset({"mass", "com"})),
    "gravity": (frozenset({"g", "direction"}), frozenset({"g"})),
    "initial": (frozenset({"attitude", "omega"}), frozenset({"attitude", "omega"})),
    "initial.attitude": (frozenset({"quaternion", "euler_zxz", "gibbs"}), frozenset()),
    "run": (frozenset({"t_end", "dt", "samples"}), frozenset({"t_end", "dt"})),
    "expect": (frozenset({"oracle", "horizon"}), frozenset()),
}


class CaseError(ValueError):
    """Bad input in a case file. str() is one line: 'FILE: KEY: RULE'."""

    def __init__(self, path: str | Path, key: str, rule: str):
        self.path, self.key, self.rule = str(path), key, rule
        super().__init__(f"{path}: {key}: {rule}")


# Tags of cases whose error grows exponentially (a chaotic motion, or one on an unstable manifold): their fitted orders
# are not held against the declared ones (analysis.verdicts), and a short ladder that finds none says so (dt_ladders).
CHAOTIC_TAGS = ("chaotic", "unstable")


@dataclass(frozen=True, eq=False)
class LadderCase:
    """A sliding-ladder scene (kind "sliding_ladder", FORMULARY T5): a planar, constrained one-degree-of-freedom
    rod, not a body with a fixed point; harness.scenes.sliding_ladder runs it.
    ladder: reference.sliding_ladder.Ladder."""

    name: str
    description: str
    tags: tuple[str, ...]
    ladder: Ladder
    t_end: float
    dt: tuple[float, ...]
    samples: int
    path: Path | None = None
    kind: str = SLIDING_LADDER
    oracle: None = None
    horizon: None = None

    @property
    def source(self) -> str:
        return str(self.path) if self.path is not None else self.name


# ---------------------------------------------------------------------------------------------------------- loading

def load_case(path: str | Path) -> Case | LadderCase:
    """Read and validate one case file. Bad input raises CaseError naming the file, the key and the rule; a torque
    model plug-in that cannot be used, TorqueModelError naming it."""
    path = Path(path)
    try:
        data = read_toml(path)
    except FileNotFoundError:
        raise CaseError(path, "-", "file not found") from None
    except OSError as exc:
        raise CaseError(path, "-", f"cannot read file ({exc.strerror or exc})") from None
    except ReadError as exc:  # too large (/dev/zero), not UTF-8, not TOML, nested too deep, a 5000-digit integer
        raise CaseError(path, "-", str(exc)) from None
    # torque models of other distributions (their tables may be in this file): one that does not load, or whose key
    # is a case file's own table (it broke every case file, unnamed), is TorqueModelError naming the plug-in, not
    # this file (the same for every file)
    load_plugins()
    for model in models():
        if model.key in _TABLES[""][0]:
            where = plugins.describe_class(model, f"torque model plug-in {model.key!r}")
            raise TorqueModelError(f"{where}: key {model.key!r} is a case file's own table; a torque model takes "
                                   "one of its own")
    return _Parser(path).case(data)


def suite_dir() -> Path:
    """The folder of the suite's case files (package data of `cases`, so an installed copy finds it)."""
    return Path(str(files("stereodyn.cases")))


def load_suite(directory: str | Path | None = None) -> list[Case]:
    """Every *.toml in the suite folder (or `directory`), sorted by case name. Duplicate names are an error."""
    directory = suite_dir() if directory is None else Path(directory)
    by_name: dict[str, Case] = {}
    for file in sorted(directory.glob("*.toml")):
        case = load_case(file)
        if case.name in by_name:
            raise CaseError(file, "name", f"duplicate case name {case.name!r} (also in {by_name[case.name].path})")
        by_name[case.name] = case
    return [by_name[name] for name in sorted(by_name)]


def find_case(name_or_path: str | Path, suite: Sequence[Case] | None = None) -> Case:
    """A suite case by name, or the case file at a path (anything ending in .toml, or anything but a folder there: a
    FIFO is refused by load_case, not taken for a name)."""
    candidate = Path(name_or_path)
    if candidate.suffix == ".toml" or (candidate.exists() and not candidate.is_dir()):
        return load_case(candidate)
    suite = load_suite() if suite is None else suite
    for case in suite:
        if case.name == str(name_or_path):
            return case
    available = ", ".join(sorted(case.name for case in suite)) or "none"
    raise CaseError(suite_dir(), str(name_or_path), f"no such case in the suite (available: {available})")


def with_overrides(case: Case, *, t_end: float | None = None, dt: float | Iterable[float] | None = None) -> Case:
    """The case with another span and/or steps (command-line overrides), validated like the file's [run];
    a horizon beyond the new t_end is clipped to it."""
    if t_end is None and dt is None:
        return case
    parser = _Parser(case.source)
    new_t_end = case.t_end if t_end is None else parser.positive(t_end, "run.t_end")
    if dt is None:
        new_dt = parser.steps(list(case.dt), "run.dt", new_t_end)
    else:
        new_dt = parser.steps(dt if isinstance(dt, (int, float)) else list(dt), "run.dt", new_t_end)
    horizon = None if case.horizon is None else min(case.horizon, new_t_end)
    return dataclasses.replace(case, t_end=new_t_end, dt=new_dt, horizon=horizon)


def triangle_broken(moments: np.ndarray, scale: float) -> str | None:
    """How principal moments break the triangle inequality A_i + A_j >= A_k (to TRIANGLE_RTOL * scale), or None."""
    a1, a2, a3 = np.sort(moments)   # the only inequality that can fail is the smallest two against the largest
    if a1 + a2 < a3 - TRIANGLE_RTOL * scale:
        return f"principal moments {_fmt(np.array([a1, a2, a3]))}: {a1 + a2:.6g} < {a3:.6g}"
    return None


def inertia_about_com(inertia: np.ndarray, mass: float, com: np.ndarray) -> np.ndarray:
    """(3, 3) kg m^2 about the centre of mass from the inertia about O (Huygens–Steiner, FORMULARY T2)."""
    return inertia - mass * (com @ com * np.eye(3) - np.outer(com, com))


def unphysical_inertia(case: Case) -> str | None:
    """Why a case's body is no mass distribution (the triangle inequality broken about O or about the centre of
    mass; only a case with [body] physical = false has one), or None. An engine that builds a physical body skips
    such a case with this reason."""
    if getattr(case, "physical", True):
        return None
    scale = float(np.linalg.eigvalsh(case.inertia)[-1])
    for where, inertia in (("about O", case.inertia),
                           ("about the centre of mass", inertia_about_com(case.inertia, case.mass, case.com))):
        broken = triangle_broken(np.linalg.eigvalsh(inertia), scale)
        if broken:
            return (f"[body] physical = false: the inertia {where} breaks the triangle inequality A_i + A_j >= A_k "
                    f"({broken}), which this engine's body requires")
    return None


# ----------------------------------------------------------------------------------------------------- validation

class _Parser:
    """Validation of one file's contents; every failure is a CaseError for self.path."""

    def __init__(self, path: str | Path):
        self.path = path

    def fail(self, key: str, rule: str) -> CaseError:
        return CaseError(self.path, key, rule)

    @contextmanager
    def plugin(self, cls: type, key: str, what: str):
        """Run a plug-in's hook on the file (a torque model's parse and check, a scene's parse; cls: its class, what:
        "torque model plug-in 'KEY'"): its failure (any Exception, SystemExit, GeneratorExit or os._exit but the
        CaseError it may raise through fail(), reference.plugins' guard) refuses the file, one line naming the key,
        the plug-in and the error. stereodyn's own run unguarded: a bug of ours is a traceback."""
        if plugins.own(cls):
            yield
            return
        try:
            with plugins.guard(plugins.describe_class(cls, what) + " failed", passing=(CaseError,)):
                yield
        except plugins.PluginError as exc:
            raise self.fail(key, str(exc)) from None

    # --- shapes and types

    def table(self, data: Any, key: str, schema: tuple[frozenset[str], frozenset[str]] | None = None) -> dict:
        """data, checked to be a table with only allowed keys and every required one: schema (allowed, required),
        default the case format's own for the key."""
        allowed, required = _TABLES[key] if schema is None else schema
        if not isinstance(data, dict):
            raise self.fail(key, "must be a table")
        prefix = f"{key}." if key else ""
        for name in data:
            if name not in allowed:
                raise self.fail(prefix + name, f"unknown key (allowed here: {', '.join(sorted(allowed))})")
        for name in sorted(required):
            if name not in data:
                raise self.fail(prefix + name, "required key missing")
        return data

    def number(self, value: Any, key: str) -> float:
        # bool is an int subclass in Python, but `true` is never a number in a case file
        if isinstance(value, bool) or not isinstance(value, (int, float)):
            raise self.fail(key, f"must be a number, got {_describe(value)}")
        try:
            result = float(value)
        except OverflowError:
            result = math.inf
        if not math.isfinite(result):
            raise self.fail(key, f"must be finite, got {_short(value)}")
        if abs(result) > MAX_MAGNITUDE:
            raise self.fail(key, f"must be within +-{MAX_MAGNITUDE:g} (docs/limits.md), got {result:g}")
        return result

    def positive(self, value: Any, key: str) -> float:
        """A scale: > 0, and >= MIN_SCALE so that its inverse and square stay far from overflow and underflow."""
        result = self.number(value, key)
        if result <= 0.0:
            raise self.fail(key, f"must be > 0, got {result:g}")
        if result < MIN_SCALE:
            raise self.fail(key, f"must be >= {MIN_SCALE:g} (docs/limits.md), got {result:g}")
        return result

    def vector(self, value: Any, key: str, n: int) -> np.ndarray:
        if not isinstance(value, list) or len(value) != n:
            raise self.fail(key, f"must be a list of {n} numbers, got {_describe(value)}")
        return np.array([self.number(item, f"{key}[{i}]") for i, item in enumerate(value)])

    def unit(self, value: Any, key: str, n: int, noun: str, symbol: str) -> np.ndarray:
        vec = self.vector(value, key, n)
        norm = float(np.linalg.norm(vec))
        if abs(norm - 1.0) > UNIT_TOL:
            raise self.fail(key, f"{noun} must have unit length (|{symbol}| = {norm:.12g}; "
                                 f"within {UNIT_TOL:g} of 1 is normalised)")
        return vec / norm

    def string(self, value: Any, key: str) -> str:
        if not isinstance(value, str):
            raise self.fail(key, f"must be a string, got {_describe(value)}")
        return value

    def steps(self, value: Any, key: str, t_end: float) -> tuple[float, ...]:
        if isinstance(value, list):
            if not value:
                raise self.fail(key, "must not be empty")
            if len(value) > MAX_DTS:
                raise self.fail(key, f"must hold at most {MAX_DTS} steps, got {len(value)}")
            keys = [f"{key}[{i}]" for i in range(len(value))]
        else:
            value, keys = [value], [key]
        result = []
        for item, item_key in zip(value, keys):
            step = self.positive(item, item_key)
            if step > t_end:
                raise self.fail(item_key, f"dt must be <= t_end ({step:g} > {t_end:g})")
            if t_end / step > MAX_STEPS:
                raise self.fail(item_key, f"t_end / dt must be <= {MAX_STEPS:.0e} steps (docs/limits.md), "
                                          f"got {t_end / step:.3g}")
            if step in result:  # the same runs twice: rows with one key
                raise self.fail(item_key, f"{step:g} given twice")
            result.append(step)
        return tuple(result)

    # --- the file

    def case(self, data: dict):
        """The case of a file's TOML, parsed by the scene its `kind` names (harness.scenes.base; default the rigid
        body)."""
        kind = RIGID_BODY
        if isinstance(data, dict) and "kind" in data:
            kind = self.string(data["kind"], "kind")
            if kind not in kinds():
                raise self.fail("kind", f"unknown scene kind {kind!r} (known: {', '.join(kinds())})")
        parser = scene(kind)
        with self.plugin(type(parser), "kind", f"scene plug-in {kind!r}"):
            return parser.parse(self, data)

    def rigid_body(self, data: dict) -> Case:
        """A rigid body with a fixed point (DESIGN §3)."""
        allowed, required = _TABLES[""]
        self.table(data, "", (allowed | {model.key for model in models()}, required))
        name, description, tags = self.words(data)
        mass, com, inertia, physical = self.body(data["body"])
        gravity, gravity_direction = 0.0, np.array([0.0, 0.0, -1.0])
        if "gravity" in data:
            gravity, gravity_direction = self.gravity(data["gravity"])
        terms = []
        for model in models():  # each torque model parses and checks its own table (reference.torque_models)
            if model.key in data:
                with self.plugin(model, model.key, f"torque model plug-in {model.key!r}"):
                    term = model.parse(self, data[model.key])
                    term.check(self, data, inertia, com)
                terms.append(term)
        quat0, omega0 = self.initial(data["initial"])
        t_end, dt, samples = self.run(data["run"])
        oracle, horizon = self.expect(data["expect"], t_end) if "expect" in data else (None, None)

        for array in (com, inertia, gravity_direction, quat0, omega0):
            array.setflags(write=False)
        case = Case(name=name, description=description, tags=tags, mass=mass, com=com, inertia=inertia,
                    gravity=gravity, gravity_direction=gravity_direction, quat0=quat0, omega0=omega0, t_end=t_end,
                    dt=dt, samples=samples, oracle=oracle, horizon=horizon, path=Path(self.path),
                    physical=physical, torques=tuple(terms))
        if oracle is not None:
            self.oracle_applies(case)
        return case

    def words(self, data: dict) -> tuple[str, str, tuple[str, ...]]:
        """name (default: the file stem), description, tags."""
        name = self.string(data["name"], "name") if "name" in data else Path(self.path).stem
        if not name.strip():
            raise self.fail("name", "must not be empty")
        if not name.isprintable():  # XML (MJCF, URDF) cannot carry control characters, and a table row breaks on them
            raise self.fail("name", f"must hold printable characters only, got {_short(name)}")
        if plugins.markup_problem(name):  # shown as itself in every table and heading of the report
            raise self.fail("name", f"{plugins.markup_problem(name)}, got {_short(name)}")
        if len(name) > MAX_NAME:
            raise self.fail("name", f"must be at most {MAX_NAME} characters (it is in every row and table), got "
                                    f"{len(name)}")
        description = self.string(data.get("description", ""), "description")
        tags = data.get("tags", [])
        if not isinstance(tags, list):
            raise self.fail("tags", f"must be a list of strings, got {_describe(tags)}")
        return name, description, tuple(self.string(tag, f"tags[{i}]") for i, tag in enumerate(tags))

    def body(self, data: Any) -> tuple[float, np.ndarray, np.ndarray, bool]:
        """mass, com, inertia about O, physical. physical = false (Euler's equations only, not a mass distribution:
        e.g. Hairer–Lubich–Wanner's I = (2, 1, 2/3)) lifts the triangle inequalities; every other rule holds."""
        self.table(data, "body")
        physical = data.get("physical", True)
        if not isinstance(physical, bool):
            raise self.fail("body.physical", f"must be true or false, got {_describe(physical)}")
        mass = self.positive(data["mass"], "body.mass")
        com = self.vector(data["com"], "body.com", 3)
        if ("inertia" in data) == ("principal_moments" in data):
            raise self.fail("body.inertia", "give exactly one of inertia (3x3) or principal_moments (3 numbers)"
                            + (", not both" if "inertia" in data else ""))
        if "inertia" in data:
            key = "body.inertia"
            inertia = self.inertia_matrix(data["inertia"], key)
        else:
            key = "body.principal_moments"
            moments = data["principal_moments"]
            if not isinstance(moments, list) or len(moments) != 3:
                raise self.fail(key, f"must be a list of 3 numbers, got {_describe(moments)}")
            inertia = np.diag([self.positive(x, f"{key}[{i}]") for i, x in enumerate(moments)])
        moments_o = np.linalg.eigvalsh(inertia)
        if moments_o[0] <= 0.0:
            raise self.fail(key, f"inertia must be positive definite (eigenvalues {_fmt(moments_o)})")
        if moments_o[0] < MIN_SCALE:
            raise self.fail(key, f"principal moments about O must be >= {MIN_SCALE:g} (docs/limits.md; eigenvalues "
                                 f"{_fmt(moments_o)})")
        if physical:
            scale = float(moments_o[-1])
            self.triangle(moments_o, scale, key, "about O")
            self.triangle(np.linalg.eigvalsh(inertia_about_com(inertia, mass, com)), scale, key,
                          "about the centre of mass (Huygens–Steiner with body.mass and body.com)")
        return mass, com, inertia, physical

    def inertia_matrix(self, value: Any, key: str) -> np.ndarray:
        if not isinstance(value, list) or len(value) != 3 or not all(isinstance(r, list) and len(r) == 3 for r in value):
            raise self.fail(key, f"must be a 3x3 array of numbers, got {_describe(value)}")
        matrix = np.array([[self.number(x, f"{key}[{i}][{j}]") for j, x in enumerate(row)]
                           for i, row in enumerate(value)])
        asymmetry = float(np.max(np.abs(matrix - matrix.T)))
        if asymmetry > SYMMETRY_RTOL * float(np.max(np.abs(matrix))):
            raise self.fail(key, f"inertia must be symmetric (max |I - I^T| = {asymmetry:.3g})")
        return 0.5 * (matrix + matrix.T)

    def triangle(self, moments: np.ndarray, scale: float, key: str, where: str) -> None:
        broken = triangle_broken(moments, scale)
        if broken:
            raise self.fail(key, f"inertia {where} must satisfy the triangle inequality A_i + A_j >= A_k ({broken}; "
                                 f"body.physical = false allows it for Euler's equations)")

    def gravity(self, data: Any) -> tuple[float, np.ndarray]:
        self.table(data, "gravity")
        g = self.number(data["g"], "gravity.g")
        if g < 0.0:
            raise self.fail("gravity.g", f"must be >= 0, got {g:g}")
        direction = np.array([0.0, 0.0, -1.0])
        if "direction" in data:
            direction = self.unit(data["direction"], "gravity.direction", 3, "direction", "d")
        return g, direction

    def initial(self, data: Any) -> tuple[np.ndarray, np.ndarray]:
        self.table(data, "initial")
        attitude = self.table(data["attitude"], "initial.attitude")
        if len(attitude) != 1:
            raise self.fail("initial.attitude", "give exactly one of quaternion, euler_zxz or gibbs"
                            + (f", got {', '.join(sorted(attitude))}" if attitude else ""))
        (chart, value), = attitude.items()
        key = f"initial.attitude.{chart}"
        if chart == "quaternion":
            quat = self.unit(value, key, 4, "quaternion", "q")
        elif chart == "euler_zxz":
            quat = _zxz_to_quat(*self.vector(value, key, 3))
        else:
            gibbs = self.vector(value, key, 3)
            quat = np.concatenate(([1.0], gibbs)) / math.sqrt(1.0 + gibbs @ gibbs)
        return quat, self.vector(data["omega"], "initial.omega", 3)

    def run(self, data: Any) -> tuple[float, tuple[float, ...], int]:
        self.table(data, "run")
        t_end = self.positive(data["t_end"], "run.t_end")
        dt = self.steps(data["dt"], "run.dt", t_end)
        samples = data.get("samples", DEFAULT_SAMPLES)
        if isinstance(samples, bool) or not isinstance(samples, int):
            raise self.fail("run.samples", f"must be an integer, got {_describe(samples)}")
        if samples < 2:
            raise self.fail("run.samples", f"must be >= 2 (t = 0 and t_end), got {_short(samples)}")
        if samples > MAX_SAMPLES:
            raise self.fail("run.samples", f"must be <= {MAX_SAMPLES} (docs/limits.md), got {_short(samples)}")
        return t_end, dt, samples

    def expect(self, data: Any, t_end: float) -> tuple[str | None, float | None]:
        self.table(data, "expect")
        oracle = None
        if "oracle" in data:
            oracle = self.string(data["oracle"], "expect.oracle")
            if oracle not in ORACLES:
                raise self.fail("expect.oracle", f"unknown oracle {oracle!r} (known: {', '.join(ORACLES)})")
            if oracle not in EXACT_SOLUTIONS:
                raise self.fail("expect.oracle", f"oracle {oracle!r} is not available yet (no exact solution in "
                                                 f"stereodyn.reference.exact; available: {', '.join(EXACT_SOLUTIONS)})")
        horizon = None
        if "horizon" in data:
            horizon = self.positive(data["horizon"], "expect.horizon")
            if horizon > t_end:
                raise self.fail("expect.horizon", f"must be <= run.t_end ({horizon:g} > {t_end:g})")
        return oracle, horizon

    def oracle_applies(self, case: Case) -> None:
        """The case's state must be on its oracle's motion (reference.exact's check, to its tolerance)."""
        for term in case.torques:
            if case.oracle not in term.oracles:
                # the oracles' checks see only the body, gravity and initial state: an extra torque would pass them
                raise self.fail("expect.oracle", f"no exact solution here models [{term.key}]; remove the oracle or "
                                                 f"the table")
        reason = EXACT_SOLUTIONS[case.oracle].check(case.body, case.quat0, case.omega0)
        if reason is not None:
            raise self.fail("expect.oracle", f"the case does not meet the conditions of {case.oracle!r}: {reason}")


# -------------------------------------------------------------------------------------------------------- helpers

def _zxz_to_quat(phi: float, theta: float, psi: float) -> np.ndarray:
    """Quaternion (scalar first) of R = Rz(phi) Rx(theta) Rz(psi), body -> world (FORMULARY C1)."""
    half_sum, half_diff, half_theta = 0.5 * (phi + psi), 0.5 * (phi - psi), 0.5 * theta
    return np.array([math.cos(half_theta) * math.cos(half_sum), math.sin(half_theta) * math.cos(half_diff),
                     math.sin(half_theta) * math.sin(half_diff), math.cos(half_theta) * math.sin(half_sum)])


def _describe(value: Any) -> str:
    text = repr(value)
    if len(text) > 40:
        text = text[:37] + "..."
    return f"{type(value).__name__} {text}"


def _short(value: Any) -> str:
    """A value for a message, at most 40 characters (a 10^5-digit integer must not become a 10^5-character line)."""
    if isinstance(value, int) and abs(value) >= 10 ** 30:  # float() overflows and repr() refuses > 4300 digits
        return f"{'-' if value < 0 else ''}an integer of {int(math.log10(abs(value))) + 1} digits"
    text = repr(value)
    return text if len(text) <= 40 else text[:37] + "..."


def _fmt(values: np.ndarray) -> str:
    return "[" + ", ".join(f"{v:.6g}" for v in values) + "]"
