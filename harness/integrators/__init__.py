"""The integrator registry: (state space, name) -> Integrator classes, built-ins first, then third-party plug-ins.

A name means the same method in every state space ("rk4" is the classical tableau on the group, "lie", and on a
formulation's coordinates, "vector"); names(state_space) says which integrators apply to a state space, and an engine
asks for the ones of the space it works in.

A plug-in is an Integrator subclass advertised in the entry-point group "stereodyn.integrators", e.g. in its
pyproject.toml: [project.entry-points."stereodyn.integrators"] my_rk = "my_package.module:MyRK" (the object may also be
a list or tuple of classes: one method in both state spaces, "lie" and "vector"). Plug-ins are loaded
the first time the registry is consulted, behind the plug-in guard (reference.plugins: any Exception or SystemExit,
never Ctrl-C); one that fails to load, or offers a class the registry refuses, is skipped with a PluginWarning naming
it, never breaking a sweep; `--integrators NAME` for it is refused with that line (failed_plugin). A plug-in runs
where it is named, and in default sweeps only when its package opts in (joins_default_sweep).
"""
from __future__ import annotations

from .base import Integrator, LieSystem, check_step_signature  # noqa: F401 (this API)
# The table and its lookups (registry.py: engines.base reads them there, without the methods' modules below).
from .registry import (ENTRY_POINT_GROUP, failed_plugin, get, in_default_sweep, joins_default_sweep,  # noqa: F401
                       names, register, stages, state_spaces)
from .geometric import GEOMETRIC
from .lie import RK4, Euler, ExplicitRK, RK4Naive, SymplecticEuler
from .tableau import ButcherTableau
from .vector import VectorEuler, VectorRK, VectorRK4, VectorSystem

__all__ = ["ENTRY_POINT_GROUP", "ButcherTableau", "ExplicitRK", "Integrator", "LieSystem", "VectorRK", "VectorSystem",
           "failed_plugin", "get", "in_default_sweep", "joins_default_sweep", "names", "register", "state_spaces"]

for _cls in (Euler, SymplecticEuler, RK4, RK4Naive, VectorEuler, VectorRK4, *GEOMETRIC):
    register(_cls)
