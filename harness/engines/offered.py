"""What an engine's SDK offers against what its adapter models: the integrators are read from the installed SDK at run
time (MuJoCo's mjtIntegrator, Drake's GetIntegrationSchemes(), MJX's and MuJoCo Warp's IntegratorType), so that an
integrator a newer release adds is named as not modelled, never silently left out (issue 48).

An adapter keeps what it knows of each integrator (its order, method, stages) and, for an integrator of its SDK it
does not run, why; `integrators()` is then `names(...)` and `offer(i)` carries `unmodelled(...)` in Offer.unmodelled.
Such an integrator gives one skipped row per case (harness.run.plan) and a line of `stereodyn engines`.
"""
from __future__ import annotations

import ast
import importlib.util
from pathlib import Path
from typing import Iterable, Mapping, Sequence

NOT_MODELLED = "not modelled by stereodyn's adapter"


def names(offered: Iterable[str], modelled: Sequence[str]) -> tuple[str, ...]:
    """The engine's integrators in report order: the adapter's own (modelled, in its order) that the SDK offers, then
    the SDK's others in the SDK's order. An adapter's name the SDK lacks (an older release) is not offered."""
    offered = tuple(dict.fromkeys(offered))
    return tuple(m for m in modelled if m in offered) + tuple(o for o in offered if o not in modelled)


def unmodelled(integrator: str, offered: Iterable[str], modelled: Iterable[str], reasons: Mapping[str, str],
               sdk: str) -> str:
    """Why the adapter does not run an integrator its SDK offers ("" when it runs it, or when the SDK does not offer
    it): the adapter's stated reason, else that the release is newer than what the adapter declares (sdk: what offers
    it, e.g. "mujoco 4.1.0's mjtIntegrator")."""
    if integrator in modelled or integrator not in offered:
        return ""
    reason = reasons.get(integrator) or (f"{sdk} offers it, and the adapter declares no order nor method for it: "
                                         f"a release newer than the adapter")
    return f"{NOT_MODELLED}: {reason}"


def enum_members(module: str, enum: str) -> tuple[str, ...] | None:
    """The member names of class `enum` in an installed module's source, read without importing it (MJX's and MuJoCo
    Warp's modules import jax or warp, seconds a process); None when the module or the class is absent."""
    top, *rest = module.split(".")
    try:  # a top-level name is found without importing it; a dotted one would import its parents (jax, warp)
        spec = importlib.util.find_spec(top)
    except (ImportError, ValueError):
        return None
    if spec is None or not rest or not spec.submodule_search_locations:
        return None
    files = [Path(folder, *rest[:-1], rest[-1] + ".py") for folder in spec.submodule_search_locations]
    found = next((f for f in files if f.is_file()), None)
    try:
        tree = ast.parse(found.read_text(encoding="utf-8")) if found else None
    except (OSError, SyntaxError, UnicodeDecodeError):
        return None
    if tree is None:
        return None
    for node in ast.walk(tree):
        if isinstance(node, ast.ClassDef) and node.name == enum:
            return tuple(target.id for item in node.body if isinstance(item, (ast.Assign, ast.AnnAssign))
                         for target in (item.targets if isinstance(item, ast.Assign) else [item.target])
                         if isinstance(target, ast.Name) and target.id.isupper())
    return None
