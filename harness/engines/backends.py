"""What MuJoCo's accelerated back-ends (MJX: mjx.py, MuJoCo Warp: warp.py) declare alike, once: MuJoCo's scene of the
case (harness.engines.mujoco.scene_state), its integrators' documented orders and methods, a default sweep of the
general cases (stepping.DEFAULT_CASES) and a constant torque only (no per-stage callback). No SDK is imported here."""
from __future__ import annotations

import math
from typing import Callable

from ..scenes.cases import Case, unphysical_inertia
from . import offered
from .base import FLOAT64, RIGID_BODY, Engine, KnownDeviation, Offer, RigidBodyModel, singular_torque
from .mujoco import torque_mode
from .stepping import DEFAULT_CASES, coarse_dts


class BackendRigidBody(RigidBodyModel):
    """The rigid body on a MuJoCo back-end: its torque enters as MuJoCo's; a case whose torque the back-end cannot
    apply exactly is absent from a default sweep (named, it is a skipped row), as are the special cases."""

    engine: "MujocoBackend"

    def unsupported_run(self, case: Case, variant: str, integrator: str) -> str | None:
        return self.engine.torque_refusal(case)

    def default_run(self, case: Case, variant: str, integrator: str) -> bool:
        return case.name in DEFAULT_CASES and self.engine.torque_refusal(case) is None

    def default_dts(self, case: Case, integrator: str, dts: tuple[float, ...]) -> tuple[float, ...]:
        return coarse_dts(dts) if self.engine.coarse_default_step else dts

    def torque_mode(self, case: Case) -> str:
        return torque_mode(case)


class MujocoBackend(Engine):
    """The declarations an accelerated MuJoCo back-end shares; a subclass sets the tables below and prepare()."""

    stages: dict[str, int] = {}             # integrator (MuJoCo's name, lower case) -> dynamics evaluations per step
    orders: dict[str, float] = {}           # the orders MuJoCo documents (what the fit compares against)
    methods: dict[str, str] = {}            # harness.engines.methods' name of each
    default_sweep: tuple[str, ...] = ()     # run by a sweep that names no integrators
    run_precisions: tuple[str, ...] = (FLOAT64,)
    deviations: dict[str, KnownDeviation] = {}
    coarse_default_step = False             # a default sweep runs one coarse step (stepping.coarse_dts)
    torque_refusal: Callable[[Case], str | None] = staticmethod(lambda case: None)  # why its torque cannot be applied
    # where the SDK declares its integrators: (module, enum class), read from its source without importing it
    # (offered.enum_members); the members, lower case, are the harness names
    sdk_enum: tuple[str, str] = ("", "")
    not_modelled: dict[str, str] = {}       # SDK integrators the adapter knows and does not run, with why

    def offered(self) -> tuple[str, ...]:
        """The integrators the installed SDK offers (its enum's members, lower case); the adapter's own when the
        enum cannot be read (no Python source: said so by the test that compares them, tests/test_engine_sdk.py)."""
        members = offered.enum_members(*self.sdk_enum) if self.sdk_enum[0] else None
        return tuple(self.stages) if members is None else tuple(m.lower() for m in members)

    def integrators(self) -> tuple[str, ...]:
        return offered.names(self.offered(), tuple(self.stages))

    def offer(self, integrator: str) -> Offer:
        reason = offered.unmodelled(integrator, self.offered(), self.stages, self.not_modelled,
                                    f"{self.sdk_enum[0]}.{self.sdk_enum[1]}")
        return Offer(order=self.orders.get(integrator, math.nan), method=self.methods.get(integrator, ""),
                     default_sweep=integrator in self.default_sweep or bool(reason), precisions=self.run_precisions,
                     deviation=self.deviations.get(integrator), unmodelled=reason)

    def unsupported(self, case: Case) -> str | None:
        return unphysical_inertia(case) or singular_torque(case)  # MuJoCo's compiler refuses the first

    def models(self) -> dict:
        return {**super().models(), RIGID_BODY: BackendRigidBody(self)}
