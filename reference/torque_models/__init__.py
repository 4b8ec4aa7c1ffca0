"""The external torques beyond uniform gravity as terms: one module per torque model (FORMULARY G12–G15), each a
frozen dataclass of its parameters derived from base.TorqueModel that declares its case table, its parameter block
in the truth, its formula, its potential or work and its metrics (DESIGN §7: adding a torque model is one such
module, registered). A RigidBody (reference.body) holds a tuple of terms; reference.torques sums them (numpy, the
engines' per-stage closure, energies and work), reference.truth concatenates their parameter blocks.

    body_torque.py     BodyTorque: (a + b |ω|²) u, u fixed in the body (G12)
    central_field.py   CentralField: the gravity-gradient torque of a Newtonian centre (G15)
    precession.py      PrecessionTorque: Grioli's torque (41) (G14)

The built-ins register in this order (the order of the truth's parameter blocks), then every other module of this
folder in name order: a new model is its file, nothing else. reference.body imports this package and nothing else
of the torques, so the body and the torque sums (reference.torques) do not import each other. 0.2.0's names (the
three dataclasses and their *_components formulas) stay importable from here.
"""
from __future__ import annotations

import importlib
import pkgutil
from importlib.metadata import entry_points

from .. import plugins
from .base import TORQUES, At, TorqueModel, merged, models, ordered, register  # noqa: F401
from .body_torque import BodyTorque, body_torque_components  # noqa: F401
from .central_field import CentralField, gravity_gradient_components  # noqa: F401
from .precession import PrecessionTorque, precession_components  # noqa: F401

for _module in sorted(info.name for info in pkgutil.iter_modules(__path__)):
    importlib.import_module(f"{__name__}.{_module}")  # registers its model

# Torque models of other distributions: a module named under this entry-point group registers its models on import.
ENTRY_POINT_GROUP = "stereodyn.torque_models"


class TorqueModelError(ImportError):
    """A torque-model plug-in does not import; str() is one line naming it."""


def load_plugins() -> None:
    """Import every module named under ENTRY_POINT_GROUP (each registers its models; importing again is a no-op);
    TorqueModelError naming the plug-in when one does not import (reference.plugins' guard: any Exception or
    SystemExit). The case parser calls it before reading a file."""
    for entry in entry_points(group=ENTRY_POINT_GROUP):
        try:
            plugins.load(entry, "torque model plug-in")
        except plugins.PluginError as exc:  # a plug-in's own bug: name it, never a traceback from inside the parser
            raise TorqueModelError(str(exc)) from None
