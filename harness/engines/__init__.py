"""Engine registry. Engines are imported lazily, so a missing SDK only makes its own runs `skipped`."""
from __future__ import annotations

import importlib
from functools import cache

from stereodyn.harness.engines.base import Engine

# name -> (module, class); the module is the only place its SDK is imported.
_ENGINES: dict[str, tuple[str, str]] = {
    "mujoco": ("stereodyn.harness.engines.mujoco", "MujocoEngine"),
    "pinocchio": ("stereodyn.harness.engines.pinocchio", "PinocchioEngine"),
    "reference": ("stereodyn.harness.engines.reference", "ReferenceEngine"),
}


def engine_names() -> tuple[str, ...]:
    return tuple(_ENGINES)


class UnavailableEngine:
    """Stands in for an engine whose SDK cannot be imported: every case is unsupported, with the reason."""

    def __init__(self, name: str, reason: str):
        self.name, self.reason = name, reason

    def integrators(self) -> tuple[str, ...]:
        return ()

    def unsupported(self, case) -> str | None:
        return self.reason

    def prepare(self, case, integrator, dt):
        raise RuntimeError(self.reason)


@cache
def get_engine(name: str) -> Engine:
    """The engine called `name`; KeyError listing the valid names if there is none."""
    if name not in _ENGINES:
        raise KeyError(f"unknown engine {name!r}; valid: {', '.join(_ENGINES)}")
    module, cls = _ENGINES[name]
    try:
        return getattr(importlib.import_module(module), cls)()
    except ImportError as exc:
        return UnavailableEngine(name, f"{name} engine unavailable: {exc}")
