"""The check runs the verdicts need (harness.analysis.verdicts judges; this module runs): per integrator of the run that
declares a bounded energy error, its long-run energy check (harness.testing), and per declared property its claim's
check (harness.analysis.claims), each on the engine of the integrator's state space. One verdict each, a check run that
breaks a failed one with its reason.
"""
from __future__ import annotations

import pandas as pd

from .. import integrators as registry
from .. import testing
from ..analysis import claims
from ..analysis.verdicts import ENERGY_CASE, ENERGY_DT, ENERGY_RATIO, ENERGY_STEPS, FAIL, PASS, Verdict
from ..engines import engine_for_state_space, get_engine
from ..run.processes import raise_unless_data


def checked_verdicts(results: pd.DataFrame) -> list[Verdict]:
    """The energy_bounded verdicts, then the declared properties' (analysis.verdicts.evaluate's `checked`)."""
    return energy_verdicts(results) + property_verdicts(results)


def energy_verdicts(results: pd.DataFrame) -> list[Verdict]:
    """For each integrator of the run that declares energy_bounded: the long-run energy check (harness.testing), on
    the engine of its state space (Pinocchio for "lie", the reference's quaternion formulation for "vector")."""

    ran = set(results.loc[results["status"] == "ok", "integrator"].astype(str))
    long_steps = ENERGY_STEPS * ENERGY_RATIO
    noise = testing.energy_noise(long_steps)
    rule = (f"energy error over {long_steps} steps <= {testing.ENERGY_GROWTH:g}x that over {ENERGY_STEPS} (dt "
            f"{ENERGY_DT:g}, {ENERGY_CASE}), both floored at round-off: {noise:.1e} = (8 + n/4) eps, n the steps")
    out = []
    for space in registry.state_spaces():
        for name in registry.names(space):
            cls = registry.get(name, space)
            if name not in ran or not getattr(cls, "energy_bounded", False):
                continue
            runner_engine = engine_for_state_space(space)  # where harness.testing runs the integrator
            engine, formulation = runner_engine.name, runner_engine.about.formulation
            base = dict(engine=engine, formulation=formulation, integrator=name, rule=rule)
            try:
                short = testing.energy_error(cls, ENERGY_CASE, ENERGY_DT, ENERGY_STEPS, space,
                                             formulation or None)
                long = testing.energy_error(cls, ENERGY_CASE, ENERGY_DT, ENERGY_STEPS * ENERGY_RATIO, space,
                                            formulation or None)
            except Exception as exc:  # a run that breaks is a failed claim, with its reason
                raise_unless_data(exc)
                out.append(Verdict("energy_bounded", **base, status=FAIL,
                                   detail=f"declares a bounded energy error; the check run failed: {exc}"))
                continue
            growth = long / max(short, testing.ENERGY_NOISE)
            ok = testing.energy_bounded(short, long, long_steps)
            at_round_off = " (round-off)" if max(short, long) <= noise else ""
            out.append(Verdict("energy_bounded", **base, status=PASS if ok else FAIL,
                               detail=f"declares a bounded energy error: {short:.2e} after {ENERGY_STEPS} steps, "
                                      f"{long:.2e} after {long_steps} ({growth:.1f}x){at_round_off}"))
    return out


def property_verdicts(results: pd.DataFrame) -> list[Verdict]:
    """For each registered integrator that ran ok on an engine of its state space (any engine, for a table without an
    engine column): every property it declares and its stages (harness.analysis.claims: measured on a few short steps
    of one or two bodies, not on the runs), one verdict each, named by the claim. MuJoCo's own rk4 is no run of the
    registry's."""

    ok = results[results["status"] == "ok"]
    spaces = {}
    for engine in (ok["engine"].astype(str).unique() if "engine" in ok else ()):
        try:
            spaces[engine] = get_engine(engine).about.state_space
        except (KeyError, ValueError):  # an engine no longer registered: its rows are no run of ours
            spaces[engine] = None
    ran = ({(spaces[e], i) for e, i in zip(ok["engine"].astype(str), ok["integrator"].astype(str))} if "engine" in ok
           else {(space, i) for space in registry.state_spaces() for i in ok["integrator"].astype(str)})
    out = []
    for space in registry.state_spaces():
        for name in registry.names(space):
            if (space, name) not in ran:
                continue
            cls = registry.get(name, space)
            runner_engine = engine_for_state_space(space)
            base = dict(engine=runner_engine.name, formulation=runner_engine.about.formulation, integrator=name)
            for claim in claims.claimed(cls):
                try:
                    found = claims.check(cls, claim)
                except Exception as exc:  # a check run that breaks is a failed claim, with its reason
                    raise_unless_data(exc)
                    out.append(Verdict(claim, **base, status=FAIL, rule=f"the {claim} check runs",
                                       detail=f"declares {claim}; the check run failed: {type(exc).__name__}: {exc}"))
                    continue
                out.append(Verdict(claim, **base, case=found.case, status=PASS if found.passed else FAIL,
                                   detail=found.detail, rule=found.rule))
    return out
