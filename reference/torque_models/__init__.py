"""The external torques beyond uniform gravity as terms: one module per torque model (FORMULARY G12–G15), each a
frozen dataclass of its parameters derived from base.TorqueModel that declares its case table, its parameter block
in the truth, its formula, its potential or work and its metrics (DESIGN §7: adding a torque model is one such
module, registered). A RigidBody (reference.body) holds a tuple of terms; reference.torques sums them (numpy, the
engines' per-stage closure, energies and work), reference.truth concatenates their parameter blocks.

    body_torque.py     BodyTorque: (a + b |ω|²) u, u fixed in the body (G12)
    central_field.py   CentralField: the gravity-gradient torque of a Newtonian centre (G15)
    precession.py      PrecessionTorque: Grioli's torque (41) (G14)

The built-ins register in this order (the order of the truth's parameter blocks), then every other module of this
folder in name order: a new model is its file, nothing else. reference.body imports the base module (the order rule)
and nothing else of the torques, so the body and the torque sums (reference.torques) do not import each other. The
built-ins' dataclasses and their *_components formulas are importable from here.
"""
from __future__ import annotations

import pkgutil

from typing import Any, Sequence

from .. import plugins
from ..registry import Registry
from .base import TORQUES, At, TorqueModel, models, ordered, register  # noqa: F401
from .body_torque import BodyTorque, body_torque_components  # noqa: F401
from .central_field import CentralField, gravity_gradient_components  # noqa: F401
from .precession import PrecessionTorque, precession_components  # noqa: F401

# Torque models of other distributions: a module named under this entry-point group registers its models on import.
ENTRY_POINT_GROUP = "stereodyn.torque_models"
# The built-in table: every module of this folder (the three above first, by their imports), by file name.
BUILT_IN = tuple(f"{__name__}.{info.name}" for info in sorted(pkgutil.iter_modules(__path__), key=lambda i: i.name))
TORQUE_MODELS = Registry("torque model plug-in", ENTRY_POINT_GROUP, BUILT_IN)
for _module in BUILT_IN:  # registered with the package: the results columns are the registry's at import
    __import__(_module)


def components(model: Any, p: Sequence, at: At) -> list:
    """model.components(p, at) (model: a TorqueModel class or term) where the sweep's parent evaluates it (the truth's
    equations, the metrics' torques): a plug-in's behind the guard (reference.plugins), so that its sys.exit or
    os._exit is PluginError naming it, its case's `truth failed` rows, not the end of the command. stereodyn's own
    unguarded: a bug of ours is a traceback. Not an engine's per-stage closure: that runs in a worker."""
    if plugins.own(model):
        return model.components(p, at)
    try:
        with plugins.guard("components() failed"):
            result = model.components(p, at)
            if not (isinstance(result, (list, tuple)) and len(result) == 3) \
                    or any(c is None or isinstance(c, (str, bytes)) for c in result):
                # what the truth's expressions and the numpy torques cannot sum: a TypeError in our frame, exit 3
                raise TypeError(f"returned {plugins.shown(result, 60)}, not the torque's three components")
            return list(result)
    except plugins.PluginError as exc:  # named only now: describe_class reads the installed distributions
        cls = model if isinstance(model, type) else type(model)
        where = plugins.describe_class(cls, f"torque model plug-in {getattr(cls, 'key', '?')!r}")
        raise plugins.PluginError(f"{where}: components() failed", exc.error) from exc.error


class TorqueModelError(ImportError):
    """A torque-model plug-in that cannot be used (it does not import, its key breaks a rule): bad input of every case
    file alike, so it names the plug-in, no file; str() is one line."""


def load_plugins() -> None:
    """Import every module named under ENTRY_POINT_GROUP (each registers its models; importing again is a no-op);
    TorqueModelError naming the plug-in when one does not import (reference.plugins' guard: any Exception or
    SystemExit), each time it is asked: a case file may hold its table. The case parser calls it before reading a
    file."""
    failed = TORQUE_MODELS.load()
    if failed:  # a plug-in's own bug: name it, never a traceback from inside the parser
        raise TorqueModelError(next(iter(failed.values())))
    for model in models():  # the key names a case file's table and the listings' lines: here, not in base.register,
        why = None if plugins.own(model) else plugins.name_problem("key", model.key)  # which imports nothing of ours
        if why:
            raise TorqueModelError(f"{plugins.describe_class(model, 'torque model plug-in')}: {why}")
