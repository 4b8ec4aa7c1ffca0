"""What a run is, once (harness.run.spec): RunKey's label, grid and truth flag, and the one run -> row path
(harness.run.measure) as the sweep and the ladders use it."""
import math
import os
import sys

import pytest

import numpy as np

from stereodyn.harness.pipeline import tolerance_ladders
from stereodyn.harness.engines.base import Engine, Offer, RigidBodyModel
from stereodyn.harness.run import plan as planning
from stereodyn.harness.run.measure import measure
from stereodyn.harness.run.spec import Family, RunKey, RunSpec, base_row
from stereodyn.harness.scenes.cases import find_case, with_overrides


def test_labels_and_grids():
    case = with_overrides(find_case("free-asymmetric"), t_end=2.0)
    key = RunKey(case, "reference", "rk4", 1e-2, "quaternion")
    assert key.label == "free-asymmetric reference quaternion rk4 dt=0.01"
    assert RunKey(case, "mujoco", "rk4", 1e-2).label == "free-asymmetric mujoco rk4 dt=0.01"
    assert Family(case, "reference", "quaternion", "scipy_dop853").run(tolerance=1e-6).label == \
        "free-asymmetric reference quaternion scipy_dop853 tol=1e-06"
    assert key.grid.steps == 200 and key.grid.times[-1] == 2.0
    adaptive = RunKey(case, "reference", "taylor", None, "quaternion").grid  # the case's samples over [0, t_end]
    assert adaptive.times.size == case.samples and math.isclose(adaptive.times[-1], 2.0)
    # a RunSpec is a RunKey with the ranks that order its row
    spec = RunSpec(case, "mujoco", "rk4", 1e-2, engine_rank=1, integrator_rank=2)
    assert spec.label == "free-asymmetric mujoco rk4 dt=0.01"
    assert base_row(spec, spec.grid)["_engine_rank"] == 1 and "_engine_rank" not in base_row(key, key.grid)


def test_the_truth_is_only_the_truths_own_row():
    case = find_case("free-asymmetric")
    assert RunKey(case, "reference", "taylor", None, "quaternion").is_truth
    assert not RunKey(case, "reference", "taylor", None, "quaternion", tolerance=1e-6).is_truth
    assert not RunKey(case, "reference", "taylor", None, "gibbs").is_truth


def test_a_tolerance_point_of_the_truths_method_has_its_errors():
    """A tolerance ladder of the reference quaternion formulation's taylor is measured against the truth like any other
    run (a RunKey that took it for the truth's row left state_err NaN). Measured: 1.9e-5 at 1e-3, 5.7e-8 at 1e-6."""
    case = with_overrides(find_case("free-asymmetric"), t_end=2.0)
    points = tolerance_ladders.run_ladder(tolerance_ladders.AdaptiveFamily(case, "reference", "quaternion", "taylor"),
                                          (1e-3, 1e-6))
    errors = [p["state_err"] for p in points]
    assert 1e-6 < errors[0] < 1e-4 and 1e-9 < errors[1] < 1e-6


def test_the_same_path_gives_the_sweep_its_extras_and_the_ladders_their_columns():
    case = with_overrides(find_case("lagrange-top"), t_end=1.0, dt=[1e-2])
    key = RunKey(case, "mujoco", "rk4", 1e-2)
    from stereodyn.harness.run.truth import case_truth
    truth = case_truth(case, certify=False)
    full, lean = measure(key, truth, full=True), measure(key, truth, full=False)
    assert full["status"] == lean["status"] == "ok"
    for column in ("energy_drift", "momentum_drift", "attitude_err", "omega_err"):
        assert full[column] == lean[column]  # one computation, whatever the caller keeps
    assert "checks" in full and "_series" in full and "checks" not in lean and "oracle_err" not in lean
    assert math.isnan(full["truth_err"])  # the truth was not certified: no bound


class _Coarse(RigidBodyModel):
    def default_dts(self, case, integrator, dts):
        return (max(dts),)

    def default_run(self, case, variant, integrator):
        return case.name != "lagrange-top"


class CoarseByDefault(Engine):
    """euler and rk4, rk4 alone in the default sweep, at the coarsest dt only, and not on the Lagrange top."""

    name = "coarse_by_default"

    def integrators(self):
        return ("euler", "rk4")

    def offer(self, integrator):
        return Offer(default_sweep=integrator == "rk4")

    def models(self):
        return {**super().models(), "rigid_body": _Coarse(self)}

    def unsupported(self, case):
        return None


def test_the_plan_resolves_no_integrators_to_each_engines_default_sweep_once(monkeypatch):
    """integrators None: the engine's default sweep (Selection.default) with its default steps and pairs; named: those
    names, at every dt of the case, on every case."""
    engine = CoarseByDefault()
    monkeypatch.setattr(planning, "get_engine", lambda name: engine)
    assert planning.Selection.of(engine, None) == planning.Selection(("rk4",), True)
    assert planning.Selection.of(engine, ["rk4", "euler", "other"]) == planning.Selection(("euler", "rk4"), False)
    cases = [with_overrides(find_case(name), dt=[1e-2, 5e-3]) for name in ("free-asymmetric", "lagrange-top")]
    default, _ = planning.plan(cases, ["coarse_by_default"], None)
    assert sorted((s.case.name, s.integrator, s.dt) for s in default) == [("free-asymmetric", "rk4", 1e-2)]
    named, _ = planning.plan(cases, ["coarse_by_default"], ["rk4"])
    assert sorted((s.case.name, s.integrator, s.dt) for s in named) == [
        ("free-asymmetric", "rk4", 5e-3), ("free-asymmetric", "rk4", 1e-2),
        ("lagrange-top", "rk4", 5e-3), ("lagrange-top", "rk4", 1e-2)]


class RaisingUnsupported(CoarseByDefault):
    name = "raising_unsupported"

    def unsupported(self, case):
        raise ValueError("no idea")


def test_an_engine_whose_unsupported_raises_gives_failed_rows_naming_it(monkeypatch):
    """Issue 46's re-attack: a plug-in's unsupported(case) that raised was a traceback of the plan (exit 1, no rows).
    Its rows are failed with the reason (skipped until the thirteenth attack), the sweep goes on; break-checked: calling model.unsupported directly again
    fails here with the ValueError."""
    engine = RaisingUnsupported()
    monkeypatch.setattr(planning, "get_engine", lambda name: engine)
    specs, skipped = planning.plan([find_case("free-asymmetric")], ["raising_unsupported"], ["rk4"])
    assert specs == [] and skipped
    assert all(r["status"] == "failed" and "unsupported(case) raised ValueError: no idea" in r["message"]
               for r in skipped)


class _Ends(BaseException):
    """A plug-in's bare BaseException (neither Exception nor SystemExit)."""


@pytest.mark.parametrize("ending, words", [
    (lambda: sys.exit(0), "raised SystemExit: 0"), (lambda: sys.exit(3), "raised SystemExit: 3"),
    (lambda: (_ for _ in ()).throw(GeneratorExit("g")), "raised GeneratorExit: g"),
    (lambda: os._exit(0), "raised ProcessExit: called os._exit(0)"), (lambda: _raise(_Ends("bare")), "_Ends: bare"),
], ids=["exit 0", "exit 3", "generator exit", "os._exit", "bare BaseException"])
def test_an_engine_whose_unsupported_ends_the_process_gives_failed_rows(monkeypatch, ending, words):
    """Issue 46's fourth attack, F2: unsupported(case) runs in the command's process and was guarded for Exception
    only: sys.exit(0) there ended `run` with exit 0 and no rows at all (MuJoCo's lost too), sys.exit(3) read "a bug in
    stereodyn", GeneratorExit a traceback. Now behind the plug-in guard: rows naming it, failed since the thirteenth
    attack (skipped says the engine cannot model the case). Break-checked: catching Exception only again lets each
    through."""
    engine = RaisingUnsupported()
    monkeypatch.setattr(type(engine), "unsupported", lambda self, case: ending())
    monkeypatch.setattr(planning, "get_engine", lambda name: engine)
    specs, skipped = planning.plan([find_case("free-asymmetric")], ["raising_unsupported"], ["rk4"])
    assert specs == [] and skipped
    assert all(r["status"] == "failed" and words in r["message"] for r in skipped), skipped[0]["message"]


def _raise(exc):
    raise exc
