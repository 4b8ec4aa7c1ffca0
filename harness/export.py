"""`stereodyn export`: the engine model of a case, to open in the engines' own tools.

mjcf: the MuJoCo adapter's scene (harness.engines.mujoco.mjcf), with an integrator and a timestep in its <option>.
urdf: the Pinocchio adapter's body (harness.engines.pinocchio.urdf), its ball joint as a three-joint gimbal.
"""
from __future__ import annotations

import importlib

from stereodyn.harness.cases import Case

FORMATS = ("mjcf", "urdf")
DEFAULT_MJCF_INTEGRATOR = "rk4"


class ExportError(ValueError):
    """The case cannot be exported in that format (its adapter cannot model it, or its SDK is missing): exit 2."""


def export(case: Case, fmt: str, integrator: str | None = None, dt: float | None = None) -> str:
    """The model text. integrator and dt (default rk4 and the case's first dt) only go into MJCF's <option>."""
    if fmt not in FORMATS:
        raise ExportError(f"--format: unknown format {fmt!r}; valid: {', '.join(FORMATS)}")
    module = {"mjcf": "stereodyn.harness.engines.mujoco", "urdf": "stereodyn.harness.engines.pinocchio"}[fmt]
    try:
        adapter = importlib.import_module(module)
    except ImportError as exc:
        raise ExportError(f"{fmt} export needs the engine's SDK: {exc}") from None
    try:
        if fmt == "mjcf":
            return adapter.mjcf(case, integrator or DEFAULT_MJCF_INTEGRATOR, case.dt[0] if dt is None else dt)
        return adapter.urdf(case)
    except (KeyError, ValueError) as exc:
        raise ExportError(str(exc).strip("'\"")) from None
