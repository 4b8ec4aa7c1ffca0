"""The lean engine protocol (issue 29): an author knows Engine.PROTOCOL (the required methods and the groups), and
Engine has no other public name but PROTOCOL itself, at most 12 in all (issue 47): what the harness derives from the
groups lives in harness.engines.declared; an engine written against 0.2.0 (its hooks and attributes of the old names)
is refused, naming the first old name and its spelling since 0.3.0 (issue 47)."""
import ast
import dataclasses
import math
from pathlib import Path

import pytest

from stereodyn.harness.engines import base
from stereodyn.harness.engines.base import About, Engine, KnownDeviation, Offer, RigidBodyModel, Timing
from stereodyn.harness.engines.declared import (declared_order, formulation_order, formulations, in_default_sweep,
                                                 known_deviations, method, rigid_body)
from stereodyn.harness.scenes.cases import load_suite

ROOT = Path(__file__).resolve().parents[1]
# The readers Engine derived from the groups until issue 47 (harness.engines.declared, the groups' fields now)
REMOVED = {"formulations", "default_run", "default_dts", "unsupported_run", "torque_mode", "export",
           "prepare_ensemble", "in_default_sweep", "precisions", "method", "adaptive", "declared_order",
           "formulation_order", "known_deviations", "pass_us", "startup_s", "short_warm_up",
           "process_global_precision", "prepare_budget_s", "packages", "linestyle", "export_formats", "state_space",
           "default_formulation"}


def test_an_author_knows_at_most_12_names():
    public = {name for name in dir(Engine) if not name.startswith("_")}
    assert len(public) <= 12, sorted(public)
    assert len(set(Engine.PROTOCOL)) == len(Engine.PROTOCOL)
    assert public == set(Engine.PROTOCOL) | {"PROTOCOL"}  # one spelling: the protocol's names, nothing derived
    for group in (Offer, Timing, About):
        assert dataclasses.is_dataclass(group) and group.__dataclass_params__.frozen


def _adapter_classes() -> list[tuple[str, ast.ClassDef]]:
    """(file, class) of every class in harness/engines/ derived, by its bases' names, from Engine or a built-in
    engine base (MujocoBackend)."""
    found = []
    for path in sorted((ROOT / "harness" / "engines").glob("*.py")):
        for node in ast.parse(path.read_text()).body:
            if isinstance(node, ast.ClassDef) and any(getattr(b, "id", "") in ("Engine", "MujocoBackend")
                                                      for b in node.bases):
                found.append((path.name, node))
    return found


def test_no_built_in_adapter_defines_a_removed_reader():
    """The built-ins declare through the protocol only: the groups are enough for nine engines."""
    classes = _adapter_classes()
    assert len(classes) >= 10  # the nine adapters, MujocoBackend and the registry's stand-ins
    for file, cls in classes:
        defined = {node.name for node in cls.body if isinstance(node, (ast.FunctionDef, ast.AsyncFunctionDef))}
        defined |= {target.id for node in cls.body if isinstance(node, (ast.Assign, ast.AnnAssign))
                    for target in (node.targets if isinstance(node, ast.Assign) else [node.target])
                    if isinstance(target, ast.Name)}
        assert not defined & REMOVED, (file, cls.name, defined & REMOVED)


class Lean(Engine):
    """The same declarations through the protocol."""

    name = "lean"
    timing = Timing(pass_us=3.0, short_warm_up=True, startup_s=12.5)
    about = About(packages=("numpy",), linestyle="-", state_space="lie", formulation="b")

    class RigidBody(RigidBodyModel):
        def variants(self):
            return ("a", "b")

        def default_run(self, case, variant, integrator):
            return variant == "a"

        def default_dts(self, case, integrator, dts):
            return dts[:1]

        def unsupported_run(self, case, variant, integrator):
            return "not b" if variant == "b" else None

        def torque_mode(self, case):
            return "legacy"

    def integrators(self):
        return ("rk4", "euler")

    def offer(self, integrator):
        deviation = KnownDeviation("rk4", "order", 2.0, 0.3, "upstream") if integrator == "rk4" else None
        return Offer(order=7.0, precisions=("float64", "float32"), deviation=deviation)

    def unsupported(self, case):
        return None

    def prepare(self, case, integrator, dt, **options):
        return ("prepared", integrator, dt, options)

    def models(self):
        return {**super().models(), base.RIGID_BODY: self.RigidBody(self)}


def _readings(engine: Engine, case) -> dict:
    model = rigid_body(engine)
    return {
        "timing": (engine.timing.pass_us, engine.timing.short_warm_up),
        "about": (engine.about.packages, engine.about.linestyle, engine.about.state_space, engine.about.formulation),
        "integrators": [(engine.offer(i).precisions, declared_order(engine, i), formulation_order(engine, "a", i),
                         engine.offer(i).adaptive, in_default_sweep(engine, i), method(engine, i))
                        for i in ("rk4", "euler")],
        "deviations": known_deviations(engine),
        "runs": (formulations(engine), type(model).__name__, model.default_run(case, "a", "rk4"),
                 model.default_run(case, "b", "rk4"), model.default_dts(case, "rk4", (0.1, 0.01)),
                 model.unsupported_run(case, "b", "rk4"), model.torque_mode(case), model.precisions("rk4")),
        "prepare": model.prepare(case, "b", "rk4", 0.01, precision="float32"),
    }


def test_the_protocol_engine_reads_through_the_groups():
    case = load_suite()[0]
    lean = _readings(Lean(), case)
    assert lean["timing"] == (3.0, True)
    assert lean["about"] == (("numpy",), "-", "lie", "b")
    assert lean["integrators"][0] == (("float64", "float32"), 7.0, 7.0, False, True, "rk4")
    assert lean["deviations"] == (KnownDeviation("rk4", "order", 2.0, 0.3, "upstream"),)
    assert lean["runs"] == (("a", "b"), "RigidBody", True, False, (0.1,), "not b", "legacy", ("float64", "float32"))
    assert lean["prepare"] == ("prepared", "rk4", 0.01, {"formulation": "b", "precision": "float32"})


@pytest.mark.parametrize("old", sorted(base.OLD_NAMES))
def test_a_0_2_0_name_is_refused_naming_its_new_spelling(old):
    """Every reader, and the sliding ladder's four 0.2.0 hooks, defined by a plug-in's class: a TypeError when the
    class is made (the registry's guard makes it one line), naming the first old name and what to write instead."""
    with pytest.raises(TypeError) as refused:
        type("Old", (Engine,), {"__module__": "plugin", "name": "old", old: 3.0, "pass_us": 1.0})
    first = old if old != "pass_us" else "pass_us"
    assert str(refused.value) == (f"engine plugin.Old defines {first!r}, a name of stereodyn 0.2.0's engine protocol: "
                                  f"since 0.3.0 declare {base.OLD_NAMES[first]} (docs/ENGINE_PLUGIN.md)")
    assert REMOVED <= set(base.OLD_NAMES)  # a plug-in that defines a removed reader is refused, naming its spelling


def test_the_start_up_cost_is_a_timing_declaration():
    """harness.run.pool reads engine.timing.startup_s: 0.0 where none is declared."""
    assert Lean().timing.startup_s == 12.5 and Engine().timing.startup_s == 0.0
    from stereodyn.harness.engines import get_engine
    assert get_engine("mujoco").timing.startup_s == 0.0 and get_engine("mujoco").timing.pass_us == 1.5


def test_the_defaults_of_an_engine_that_declares_nothing():
    class Minimal(Engine):
        name = "minimal"

    engine = Minimal()
    assert engine.offer("rk4") == Offer() and math.isnan(Offer().order)
    assert declared_order(engine, "rk4") == 4.0 and method(engine, "rk4") == "rk4"  # the registry's
    assert not in_default_sweep(engine, "implicit_midpoint")  # the registry's rule: a geometric method runs when named
    assert engine.timing == Timing() and engine.about == About() and known_deviations(engine) == ()
    assert type(rigid_body(engine)) is RigidBodyModel and formulations(engine) == ()
    with pytest.raises(NotImplementedError, match="exports no format"):
        rigid_body(engine).export(None, "mjcf", None, None)
