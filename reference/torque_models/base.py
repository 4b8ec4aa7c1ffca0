"""What a torque model declares (TorqueModel), the point it is evaluated at (At), and the registry the case parser,
the truth, the engines' per-stage closure, the energies and the metrics iterate (models(), register()).

A torque model is a frozen dataclass of its parameters, derived from TorqueModel, in a module of its own under
reference/torque_models/ (DESIGN §7). Its formula, components(p, at), is plain arithmetic on its parameter block p
and the point `at`, so that one definition serves floats (reference.torques.torque_function, an engine's stage),
numpy arrays (reference.torques' vectorised forms) and heyoka expressions (reference.truth's equations, where p are
runtime parameters: one compiled integrator serves every body).
"""
from __future__ import annotations

from typing import Any, Callable, ClassVar, NamedTuple, Sequence

import numpy as np


class At(NamedTuple):
    """Where a torque is evaluated, in one arithmetic (floats, numpy arrays or heyoka expressions).

    t: s (heyoka: hy.time). omega: 3 body components, rad/s. sigma: 3 rows of the inertia about O, body frame, kg m².
    body(v): the body components Rᵀ v of the 3 components v of a vector given in the world (in a chart's
    reference frame for the charted formulations: a term's parameters(frame) are in that frame).
    sqrt, cos, sin: that arithmetic's functions. A named tuple: an engine builds one at every stage.
    """

    t: Any
    omega: Sequence
    sigma: Sequence
    body: Callable[[Sequence], Sequence]
    sqrt: Callable
    cos: Callable
    sin: Callable


class TorqueModel:
    """Base of a torque model (a frozen dataclass of its parameters); every declaration in one place:

    key: the case file's table (DESIGN §3) and the registry's name. schema: (allowed, required) keys of that table.
    parameter_count: the runtime parameters of its block in the truth (reference.truth concatenates the blocks of
    every registered model, in registry order; a body without the model gets absent()).
    potential: True when the torque has a potential energy (potential_energy; the energy, or the Jacobi integral,
    is conserved), False when it does work (reference.torques.work: the energy balance).
    columns: results.csv columns it measures (metrics), NaN for a body without it.
    oracles: the exact solutions (reference.exact) that model it; a case naming another oracle may not have it.
    """

    key: ClassVar[str]
    schema: ClassVar[tuple[frozenset[str], frozenset[str]]]
    parameter_count: ClassVar[int]
    potential: ClassVar[bool] = False
    energy_name: ClassVar[str] = ""     # its term in reference.torques.energy_terms when potential
    columns: ClassVar[tuple[str, ...]] = ()
    oracles: ClassVar[tuple[str, ...]] = ()

    # --- the case file

    @classmethod
    def parse(cls, reader, data: Any) -> "TorqueModel":
        """The term of a case file's table. reader: harness.scenes.cases' parser (table, number, positive, unit,
        fail -> the CaseError 'FILE: KEY: RULE' to raise); reference/ never imports it."""
        raise NotImplementedError

    def check(self, reader, tables: dict, inertia: np.ndarray, com: np.ndarray) -> None:
        """Rules against the rest of the case: tables (the file's top-level tables), inertia (3, 3) about O and com
        (3,) m; raise reader.fail(key, rule). Default none."""

    # --- the formula

    @classmethod
    def absent(cls) -> tuple[float, ...]:
        """The parameter block of a body without this torque: its components must vanish (default zeros)."""
        return (0.0,) * cls.parameter_count

    def parameters(self, frame: np.ndarray | None = None) -> tuple[float, ...]:
        """Its parameter block (parameter_count floats); frame (3, 3): the coordinates' frame in the world (None:
        the world), for a vector the torque's parameters give in the world."""
        raise NotImplementedError

    @staticmethod
    def components(p: Sequence, at: At) -> list:
        """The torque's 3 body components (N m) from its parameter block p at the point at."""
        raise NotImplementedError

    # --- energy, run-time properties, metrics

    def potential_energy(self, body, times: np.ndarray, quat: np.ndarray) -> np.ndarray:
        """(n,) J, its potential at (times (n,) s, quat (n, 4)) when potential."""
        raise NotImplementedError

    @property
    def frame_rate(self) -> float:
        """rad/s about world z of the frame in which the scene is stationary (the Jacobi integral's Ω); 0."""
        return 0.0

    @property
    def constant(self) -> bool:
        """Constant in the body frame (independent of time and state): an engine may apply it once."""
        return False

    def singular(self, omega0: np.ndarray) -> str | None:
        """Why a run from omega0 (3,) rad/s body is not defined for this torque (the run is skipped), or None."""
        return None

    def metrics(self, body, quat: np.ndarray, omega: np.ndarray) -> dict[str, float]:
        """Its columns over a run's finite samples (quat (n, 4), omega (n, 3))."""
        return {}


# The registry: table key -> model, in the order of the truth's parameter blocks and of every sum of torques.
TORQUES: dict[str, type[TorqueModel]] = {}


def register(model: type[TorqueModel]) -> type[TorqueModel]:
    """Add a torque model (usable as a class decorator). Its key must be new: a second model under one key would
    make a case file ambiguous."""
    if not (isinstance(model, type) and issubclass(model, TorqueModel)):
        raise TypeError(f"a torque model must be a class derived from TorqueModel, got {model!r}")
    present = TORQUES.get(model.key)
    if present is not None and present is not model:
        raise ValueError(f"torque model key {model.key!r} is taken by {present.__module__}.{present.__qualname__}")
    TORQUES[model.key] = model
    return model


def models() -> tuple[type[TorqueModel], ...]:
    """The registered models, in registry order."""
    return tuple(TORQUES.values())


def ordered(terms) -> tuple[TorqueModel, ...]:
    """terms (each of a registered model, one per model) in registry order; ValueError otherwise."""
    order = {model: i for i, model in enumerate(TORQUES.values())}
    seen: dict[type, TorqueModel] = {}
    for term in terms:
        model = type(term)
        if model not in order:
            raise ValueError(f"{model.__qualname__} is not a registered torque model "
                             f"(stereodyn.reference.torque_models.register)")
        if model in seen and seen[model] != term:
            raise ValueError(f"two [{model.key}] torques on one body (one term per model)")
        seen[model] = term
    return tuple(sorted(seen.values(), key=lambda term: order[type(term)]))
