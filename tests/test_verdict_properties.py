"""The verdicts on bodies nobody here chose (issue 45): random physical bodies (principal moments about the
centre of mass that satisfy the triangle inequality, any orientation of the principal axes, the centre of mass up to
0.2 m off the fixed point, |omega| from 0.5 to 30 rad/s, gravity on or off) and ladders of 6 dt over 16-64x placed
anywhere from |omega| dt ~ 2 down to the round-off floor or the steps cap. On each body:

- the order verdict of a correct method never fails: the reference's rk4 and euler on the group (the Lie-group
  integrators on the reference's equations), Pinocchio's rk4, MuJoCo's rk4 and euler;
- a false claim fails wherever its ladder judged a settled range (fitting.MIN_POINTS points): Heun declared 4, rk4
  declared 5, rk4_naive declared 4;
- the declared properties' rules (analysis.claims) hold on the body: no symplectic, symmetric, geometric or
  casimir-preserving method is failed, and rk4 claiming any of them is (its stages too, counted on the body).

The default run draws SEED's bodies from numpy's seeded generator (the same in every process: CI is deterministic);
Hypothesis draws the slow runs' (its edge values too): `VERDICT_BODIES=500 VERDICT_SEED=7 pytest -m slow
tests/test_verdict_properties.py` runs many more with a seed of one's choosing. A failing example is printed as a
case file and a `stereodyn run` command a person can run.
"""
from __future__ import annotations

import math
import os
import tempfile
from pathlib import Path
from typing import Callable

import numpy as np
import pandas as pd
import pytest
from hypothesis import HealthCheck, Phase, given, note, seed, settings
from hypothesis.control import currently_in_test_context
from hypothesis import strategies as st

from stereodyn.harness.analysis import claims, fitting, verdicts
from stereodyn.harness.integrators import properties, registry
from stereodyn.harness.integrators.lie import ExplicitRK
from stereodyn.harness.integrators.tableau import ButcherTableau
from stereodyn.harness.pipeline import dt_ladders
from stereodyn.harness.run.spec import Family
from stereodyn.harness.scenes.cases import load_case

SEED = 45
BODIES = int(os.environ.get("VERDICT_BODIES", "500"))  # the slow variant's count
SLOW_SEED = int(os.environ.get("VERDICT_SEED", str(SEED)))
SAMPLES = 4  # error samples after t = 0 (every dt's steps a multiple of SAMPLES)
# Steps of a ladder's finest point: the Python steppers (the reference's and Pinocchio's) at most PY_STEPS, MuJoCo's
# at most MJ_STEPS. Where the cap clips a ladder it slides up whole (its ratio kept).
PY_STEPS, MJ_STEPS = 2400, 16000
# No shrinking: a failing body is printed as drawn (shrinking a ladder of runs took over five minutes, and its
# simplest body, a spin about a principal axis, is a special motion rather than the finding); no example database.
SETTINGS = dict(deadline=None, database=None, suppress_health_check=list(HealthCheck),
                phases=(Phase.explicit, Phase.reuse, Phase.generate))


class Heun(ExplicitRK):
    """Heun's method on the group (order 2) declaring 4: a false claim."""

    name = "heun_declared_4"
    order = 4
    tableau = ButcherTableau(a=((0.0, 0.0), (1.0, 0.0)), b=(0.5, 0.5), c=(0.0, 1.0))
    description = "Heun's method (explicit trapezoid) on the group, second order, declaring 4"


def body_of(uniform: Callable[[float, float], float], coin: Callable[[], bool]) -> dict:
    """A physical body as a case's numbers, from a source of uniform floats in [lo, hi] and of coin flips: principal
    moments about the centre of mass (a, b, c) with c strictly between |a - b| and a + b, rotated by a random
    quaternion, a point mass's term added for the offset centre of mass (so the triangle inequality holds about O
    too); attitude and omega direction random."""
    def direction():
        v = np.array([uniform(-1.0, 1.0) for _ in range(3)]) + np.array([1e-3, 0, 0])
        return v / np.linalg.norm(v)

    def quaternion():
        q = np.array([uniform(-1.0, 1.0) for _ in range(4)]) + np.array([1e-3, 0, 0, 0])
        return q / np.linalg.norm(q)

    a, b = uniform(0.05, 2.0), uniform(0.05, 2.0)
    c = abs(a - b) + uniform(0.02, 0.98) * (a + b - abs(a - b))
    mass = uniform(0.2, 3.0)
    q = quaternion()
    w, x, y, z = q
    rot = np.array([[1 - 2 * (y * y + z * z), 2 * (x * y - w * z), 2 * (x * z + w * y)],
                    [2 * (x * y + w * z), 1 - 2 * (x * x + z * z), 2 * (y * z - w * x)],
                    [2 * (x * z - w * y), 2 * (y * z + w * x), 1 - 2 * (x * x + y * y)]])
    com = direction() * uniform(0.0, 0.2)
    inertia = rot @ np.diag([a, b, c]) @ rot.T + mass * (com @ com * np.eye(3) - np.outer(com, com))
    speed = math.exp(uniform(math.log(0.5), math.log(30.0)))
    gravity = coin()
    omega = direction() * speed
    # the fastest rate of the motion: the spin, or gravity's pendulum frequency about O
    rate = speed + (math.sqrt(mass * 9.81 * np.linalg.norm(com) / min(np.linalg.eigvalsh(inertia))) if gravity else 0)
    turns = math.exp(uniform(math.log(2.0), math.log(80.0)))  # rad of motion over the span (issue 45: 75)
    t_end = min(3.0, max(0.05, turns / rate))
    return dict(mass=mass, com=com, inertia=0.5 * (inertia + inertia.T), gravity=gravity, quat0=quaternion(),
                omega=omega, rate=rate, t_end=float(f"{t_end:.3g}"))


def ladder_of(uniform: Callable[[float, float], float]) -> tuple[float, float]:
    """(top, ratio): the coarsest step as a fraction of 1/rate (|omega| dt from ~2 down to 3e-3), and finest/coarsest
    (16 to 64x); the finest point may reach the round-off floor (rk4: |omega| dt ~ 1e-3) or the steps cap."""
    return 10.0 ** uniform(-2.5, 0.3), 2.0 ** uniform(4.0, 6.0)


@st.composite
def bodies(draw) -> dict:
    """body_of, drawn by Hypothesis (the slow runs: its edge values, and the literals of the modules it has seen)."""
    return body_of(lambda lo, hi: draw(st.floats(lo, hi)), lambda: draw(st.booleans()))


@st.composite
def ladders(draw) -> tuple[float, float]:
    return ladder_of(lambda lo, hi: draw(st.floats(lo, hi)))


def seeded(examples: int, chosen_seed: int) -> list[tuple[dict, tuple[float, float]]]:
    """`examples` (body, ladder) pairs from numpy's generator seeded with chosen_seed: the default tests' draw, the
    same in every process. Not Hypothesis there: since 6.131 it draws, 5 % of the time, a literal of the modules the
    process has imported, so a seeded draw depended on which test files an xdist worker ran first (CI, 2026-12-02:
    the same seed gave euler's ladders 2 settled of 20 where a process of this file alone gives 12)."""
    rng = np.random.default_rng(chosen_seed)
    uniform, coin = (lambda lo, hi: float(rng.uniform(lo, hi))), (lambda: bool(rng.integers(2)))
    return [(body_of(uniform, coin), ladder_of(uniform)) for _ in range(examples)]


def toml(body: dict, dts=()) -> str:
    """The body as a case file a person can run (docs/DESIGN.md §3)."""
    def vec(v):
        return "[" + ", ".join(repr(float(x)) for x in v) + "]"

    rows = ",\n           ".join(vec(r) for r in body["inertia"])
    return (f'description = "a random body of tests/test_verdict_properties.py"\n[body]\nmass = {body["mass"]!r}\n'
            f'com = {vec(body["com"])}\ninertia = [{rows}]\n'
            + ("[gravity]\ng = 9.81\n" if body["gravity"] else "")
            + f'[initial]\nattitude = {{ quaternion = {vec(body["quat0"])} }}\nomega = {vec(body["omega"])}\n'
            f'[run]\nt_end = {body["t_end"]!r}\ndt = {vec(dts) if len(dts) else "[0.01]"}\nsamples = {SAMPLES + 1}\n')


def case_of(body: dict, dts=()):
    with tempfile.TemporaryDirectory() as folder:
        path = Path(folder) / "random-body.toml"
        path.write_text(toml(body, dts))
        return load_case(path)


def ladder_steps(body: dict, top: float, ratio: float, cap: int) -> list[int]:
    """Six step counts, coarse to fine, multiples of SAMPLES: dt from top / rate down by `ratio`, slid up where the
    finest would pass `cap` steps."""
    dts = np.geomspace(top / body["rate"], top / body["rate"] / ratio, 6)
    steps = [max(SAMPLES, SAMPLES * round(body["t_end"] / dt / SAMPLES)) for dt in dts]
    if steps[-1] > cap:
        steps = [max(SAMPLES, SAMPLES * round(s * cap / steps[-1] / SAMPLES)) for s in steps]
    return sorted(set(steps))


def ladder_points(case, engine: str, formulation: str, integrator: str, steps: list[int]) -> pd.DataFrame:
    """The ladder of an engine's integrator through the ladders' one measure path (pipeline.dt_ladders.measure: the
    state error against the truth, harness.scenes.metrics.state_err)."""
    family = Family(case, engine, formulation, integrator)
    rows = [dt_ladders.measure(family, case.t_end / n, timed=False) for n in steps]
    return pd.DataFrame(rows)[["dt", "steps", "status", "state_err"]]


def verdict_of(points: pd.DataFrame, declared: float) -> tuple[verdicts.Verdict, dict]:
    row = {"case": "random-body", "engine": "e", "formulation": "", "integrator": "m", "precision": "float64",
           "stable_dt_max": math.nan, "source": "dt_list", **fitting.fit(points, declared)}
    (verdict,) = verdicts.order_verdicts(pd.DataFrame([row]))
    return verdict, row


# (engine, formulation, integrator, declared order): correct claims, then false ones. The reference's on the group:
# its quaternion formulation (properties.GROUP_FORMULATION). Heun (order 2) runs in Pinocchio as a plug-in would.
CORRECT = (("reference", "quaternion", "rk4", 4.0), ("reference", "quaternion", "euler", 1.0),
           ("pinocchio", "", "rk4", 4.0), ("mujoco", "", "rk4", 4.0), ("mujoco", "", "euler", 1.0))
FALSE = (("pinocchio", "", Heun.name, 4.0), ("pinocchio", "", "rk4", 5.0), ("pinocchio", "", "rk4_naive", 4.0))
# The steps cap of a ladder's finest point: MuJoCo steps in C (~1 us), the others in Python (~20-60 us a step).
CAPS = {"mujoco": MJ_STEPS}


def judge_body(body: dict, ladder: tuple[float, float], tally: dict, wrong: list | None = None) -> None:
    """Every method's ladder on one body: a correct method's order verdict is never FAIL; a false claim's is FAIL
    wherever its range settled. tally counts the outcomes per claim (the tests check they are not vacuous); with
    `wrong` a list, a false failure or a false pass is appended to it (its case file and why) instead of raised, so
    that a long run measures the rates over all its bodies."""
    case = case_of(body)
    for engine, formulation, integrator, declared, correct in [(*m, True) for m in CORRECT] + [(*m, False)
                                                                                           for m in FALSE]:
        steps = ladder_steps(body, *ladder, CAPS.get(engine, PY_STEPS))
        points = ladder_points(case, engine, formulation, integrator, steps)
        verdict, row = verdict_of(points, declared)
        name = " ".join(x for x in (engine, formulation, integrator) if x) + f" declared {declared:g}"
        dts = [float(f"{body['t_end'] / n:.6g}") for n in steps]
        where = (f"{name}: {verdict.status}: {verdict.detail}\n--- the body, as a case file (random-body.toml):\n"
                 f"{toml(body, dts)}--- run it: stereodyn run --case-file random-body.toml --engines {engine} "
                 f"--integrators {integrator} --no-ladder\n(errors "
                 + ", ".join(f"{e:.3g}" for e in points["state_err"]) + ")")
        if currently_in_test_context():  # a Hypothesis draw prints it with its failing example
            note(where)
        settled = row["points"] >= fitting.MIN_POINTS
        tally.setdefault(name, []).append((verdict.status, settled))
        bad = verdict.status == verdicts.FAIL if correct else settled and verdict.status != verdicts.FAIL
        if bad and wrong is not None:
            wrong.append(where)
        else:
            assert not bad, where


def run_bodies(examples: int, chosen_seed: int, wrong: list | None = None, drawn_by_hypothesis: bool = False) -> dict:
    """judge_body on `examples` bodies drawn with chosen_seed (numpy's generator: seeded; with drawn_by_hypothesis,
    Hypothesis's); the tally of outcomes per claim."""
    tally: dict = {}

    @seed(chosen_seed)
    @settings(max_examples=examples, **SETTINGS)
    @given(body=bodies(), ladder=ladders())
    def check(body, ladder):
        judge_body(body, ladder, tally, wrong)

    saved = dict(registry._registry)
    registry.register(Heun)
    try:
        if drawn_by_hypothesis:
            check()
        else:
            for body, ladder in seeded(examples, chosen_seed):
                judge_body(body, ladder, tally, wrong)
    finally:
        registry._registry.clear()
        registry._registry.update(saved)
    return tally


def _rates(tally: dict) -> str:
    """Per claim: ladders, those with a settled range, verdicts by status; then the false-failure rate (a correct
    claim failed, over its ladders) and the false-pass rate (a false claim not failed, over its settled ladders)."""
    lines, false_fail, correct_n, false_pass, settled_false = [], 0, 0, 0, 0
    wrong_names = {" ".join(x for x in m[:3] if x) + f" declared {m[3]:g}" for m in FALSE}
    for name, outcomes in tally.items():
        statuses = pd.Series([s for s, _ in outcomes]).value_counts().to_dict()
        settled = sum(1 for _, s in outcomes if s)
        lines.append(f"{name}: {len(outcomes)} ladders, {settled} settled: {statuses}")
        if name in wrong_names:
            settled_false += settled
            false_pass += sum(1 for status, s in outcomes if s and status != verdicts.FAIL)
        else:
            correct_n += len(outcomes)
            false_fail += sum(1 for status, _ in outcomes if status == verdicts.FAIL)
    lines.append(f"false failures {false_fail} of {correct_n} correct ladders; false passes {false_pass} of "
                 f"{settled_false} settled false-claim ladders")
    return "\n".join(lines)


# default: SEED's 20 bodies (seeded), every claim on each: 160 ladders, ~22 s on one core of the 2-core machine (00:40
# UTC 2026-12-02, other helpers running)
def test_order_verdicts_on_random_bodies():
    tally = run_bodies(20, SEED)
    print(_rates(tally))
    for name, outcomes in tally.items():
        assert len(outcomes) >= 20, name
        # not vacuous: ladders judge a settled range (measured with SEED's numpy draw, the same in every process:
        # 7 of 20 for the reference's euler, whose error ~ |omega| dt |omega| t lies above the range on the coarse
        # ladders more often, 14 for MuJoCo's rk4 and euler, 19-20 for the others; at least 5, a margin for a ladder or
        # two that settles on one machine's round-off and not another's), and the false claims fail on those
        assert sum(1 for _, s in outcomes if s) >= 5, (name, outcomes)


@pytest.mark.slow
def test_order_verdicts_on_many_random_bodies():
    """VERDICT_BODIES bodies (500) drawn with VERDICT_SEED: every false failure and false pass is collected, the
    rates printed (-s), and the test fails if either is not 0, showing the first few as case files."""
    wrong: list = []
    tally = run_bodies(BODIES, SLOW_SEED, wrong, drawn_by_hypothesis=True)
    print(f"seed {SLOW_SEED}, {BODIES} bodies\n" + _rates(tally))
    assert not wrong, f"{len(wrong)} wrong verdicts; the first:\n" + "\n\n".join(wrong[:3])


# ------------------------------------------------------------------------------------------------ the properties

# The claims' rules on the random bodies, at steps scaled to each body: |omega| h as on claims.CHECK_CASE (|omega0| =
# 2.3 rad/s) at its h, so a body spinning at 30 rad/s is checked at the same rotation a step.
CHECK_RATE = 2.3

# (state space, name): the built-ins that declare properties, and rk4 / euler, which declare none of symplectic,
# symmetric and casimir_preserving (the vector rk4 nor geometric): each such claim, planted, must fail.
METHODS = (("lie", "strang_free_flow"), ("lie", "moser_veselov"), ("lie", "implicit_midpoint"),
           ("vector", "implicit_midpoint"), ("lie", "rk4"), ("lie", "euler"), ("vector", "rk4"))
PLANTED = {("lie", "rk4"): ("symplectic", "symmetric", "casimir_preserving"),
           ("lie", "euler"): ("symplectic", "symmetric", "casimir_preserving"),
           ("vector", "rk4"): ("symplectic", "symmetric", "geometric", "casimir_preserving")}
# The symplectic defect's central differences (properties.jacobian, FD_STEP 1e-3 in momenta scaled by |sigma v0|) are
# noisy on a body far from round: moments 0.05, 0.05, 0.002 about O (ratio 25), |omega| 1 about a long axis: Moser-
# Veselov's defect 2.4e-8 at h = 0.2 (5e-8 at the scaled h), 2.9e-10, 1.3e-9, 6.1e-9, 3.6e-12 at FD steps 1e-3 ... 3e-5:
# not C h^(p+1), rounding over the step divided by the FD step. The run's verdict measures on claims.CHECK_CASE
# (ratio 1.9) only, so no run fails for it; a declared symplectic claim is checked here up to ratio 4 (issue 45's
# report: the defect's scaling per axis is left to do).
SYMPLECTIC_RATIO_MAX = 4.0
LIMITS = {"symplectic": claims.SYMPLECTIC_DEFECT_MAX, "symmetric": claims.REVERSAL_MAX,
          "geometric": claims.GROUP_DRIFT_MAX, "casimir_preserving": claims.CASIMIR_DRIFT_MAX}


def _cls(space: str, name: str):
    from stereodyn.harness import integrators

    return integrators.get(name, space)


def figure(cls, claim: str, case, free, scale: float) -> float:
    """The figure analysis.claims.check reads for `claim`, measured on this body (the torque-free one for the Casimir,
    or where the method refuses gravity), at the claim's steps times scale."""
    def on(start, measure):
        try:
            return measure(start.body, start.quat0, start.omega0)
        except (ValueError, TypeError):  # claims._on_check_case: a method that refuses gravity
            return measure(free.body, free.quat0, free.omega0)

    if claim == "symplectic":
        return on(case, lambda *a: max(properties.symplectic_defect(cls, *a, h * scale)
                                       for h in claims.SYMPLECTIC_STEPS))
    if claim == "symmetric":
        return on(case, lambda *a: max(properties.reversal_error(cls, *a, h * scale) for h in claims.REVERSAL_STEPS))
    if claim == "geometric":
        return on(case, lambda *a: properties.group_drift(cls, *a, claims.GROUP_STEP * scale, claims.GROUP_STEPS))
    return properties.casimir_drift(cls, free.body, free.quat0, free.omega0, claims.GROUP_STEP * scale,
                                    claims.GROUP_STEPS)


def general(inertia: np.ndarray, omega: np.ndarray) -> bool:
    """Whether the torque-free part of the motion is far from a steady rotation: |omega x sigma omega| >= GENERAL of
    |omega| |sigma omega|. Near one (a spin close to a principal axis, or a body close to round) omega hardly changes
    and every method is nearly exact, so a planted claim has nothing to be caught on: Hypothesis found rk4's Casimir
    drift 1.3e-13 (under CASIMIR_DRIFT_MAX) on moments 0.28-0.33 spinning within 0.03 rad of an axis."""
    momentum = inertia @ omega
    return float(np.linalg.norm(np.cross(omega, momentum))) >= GENERAL * np.linalg.norm(omega) * np.linalg.norm(
        momentum)


GENERAL = 0.05



def stages_counted(cls, start, h: float) -> float:
    """The right-hand-side calls a step of cls from the case's start at h, or at h / 4, h / 16 where its step does not
    solve at h: Moser-Veselov's fixed-point iteration converges for h |omega| I_max / I_min below ~1, so on a rod
    (moments 0.05, 1.79, 1.80; seed 7's 500 bodies) it raises NotConverged at h = 0.115 s, a failed row in a run."""
    for k in range(3):
        try:
            return properties.rhs_evals_per_step(cls, start.body, start.quat0, start.omega0, h / 4 ** k,
                                                 claims.STAGE_STEPS)
        except ArithmeticError:
            if k == 2:
                raise

def judge_properties(body: dict) -> None:
    """Each declared property's rule passes on the body; each planted false claim fails where the motion is general;
    the stages are counted."""
    case = case_of(body)
    centred = body["inertia"] - body["mass"] * (body["com"] @ body["com"] * np.eye(3) - np.outer(body["com"],
                                                                                                  body["com"]))
    free = case_of(dict(body, gravity=False, com=np.zeros(3), inertia=centred))
    heavy = case if body["gravity"] and body["com"] @ body["com"] > 1e-6 else case_of(
        dict(body, gravity=True, com=np.array([0.05, -0.03, 0.1]), inertia=centred + 0.1 * np.eye(3)))
    scale = CHECK_RATE / np.linalg.norm(body["omega"])
    moments = np.linalg.eigvalsh(body["inertia"])
    ratio = moments[-1] / moments[0]
    for space, name in METHODS:
        cls = _cls(space, name)
        for claim, limit in LIMITS.items():
            declared, planted = getattr(cls, claim, False) is True, claim in PLANTED.get((space, name), ())
            moving = general(centred if claim == "casimir_preserving" else body["inertia"], body["omega"])
            if not (declared or planted and moving):
                continue
            if declared and claim == "symplectic" and ratio > SYMPLECTIC_RATIO_MAX:
                continue  # SYMPLECTIC_RATIO_MAX's comment: the defect's own noise, not the method
            try:
                value = figure(cls, claim, case, free, scale)
            except ArithmeticError:  # the Gibbs chart of the canonical coordinates is singular near this attitude
                continue
            where = f"{space} {name} {claim} ({'declared' if declared else 'planted'}): {value:.2e} vs {limit:g}"
            where += "\n" + toml(body)
            if currently_in_test_context():
                note(where)
            assert (value <= limit) == declared, where
        # counted with a torque, as on claims.CHECK_CASE (strang_free_flow calls it only for the torque's kick: 0
        # a step on a free body), or torque-free where the method refuses one
        start = free if name == "moser_veselov" else heavy
        counted = stages_counted(cls, start, claims.STAGE_STEP * scale)
        assert counted >= cls.stages if getattr(cls, "iterative", False) else counted == cls.stages, (
            name, counted, toml(body))


@pytest.mark.parametrize("index", range(5))
def test_property_rules_on_random_bodies(index):
    body, _ = seeded(5, SEED)[index]
    judge_properties(body)


@pytest.mark.slow
def test_property_rules_on_many_random_bodies():
    @seed(SLOW_SEED)
    @settings(max_examples=BODIES, **SETTINGS)
    @given(body=bodies())
    def check(body):
        judge_properties(body)

    check()
