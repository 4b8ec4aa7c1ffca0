"""Engine hooks of issue 23's gaps: an engine whose precision is process-global (Genesis's gs.init releases the models
of the other precision) gets every ok row timed, in the sweep's and the ladders' timing phases
(Timing.process_global_precision, harness.run.timing.groups); an engine whose first preparation compiles for minutes
declares a longer prepare budget (Timing.prepare_budget_s, harness.run.measure.prepare_budget); an integrator that is
another method on another model declares its order there (Offer.orders). A toy engine stands in for
Genesis: it keeps one precision per process and wraps MuJoCo's euler."""
from __future__ import annotations

import dataclasses
import math
import time

import pytest

from stereodyn.harness import budget, engines
from stereodyn.harness.engines.base import FLOAT32, FLOAT64, About, Engine, Offer, RigidBodyModel, Timing
from stereodyn.harness.run import measure, sweep, timing
from stereodyn.harness.run.spec import RunKey
from stereodyn.harness.grid import time_grid
from stereodyn.harness.scenes.cases import find_case

NAME = "global_precision_toy"
_PROCESS = {"precision": None, "generation": 0}  # the toy's "process-global" state, as Genesis's _context


class ToySimulation:
    def __init__(self, case, dt, precision):
        if _PROCESS["precision"] != precision:  # re-initialise: every model built before is released
            _PROCESS["precision"] = precision
            _PROCESS["generation"] += 1
        self.generation = _PROCESS["generation"]
        self.inner = engines.get_engine("mujoco").prepare(case, "euler", dt)
        time.sleep(ToyEngine.prepare_s)

    def run(self, grid):
        if self.generation != _PROCESS["generation"]:
            raise RuntimeError("released: the process was re-initialised at the other precision")
        return self.inner.run(grid)


class _ToyBody(RigidBodyModel):
    def variants(self):
        return ("ball", "free")


class ToyEngine(Engine):
    name = NAME
    about = About(state_space="lie")
    timing = Timing(process_global_precision=True)
    prepare_s = 0.0  # how long a prepare sleeps

    def integrators(self):
        return ("euler",)

    def unsupported(self, case):
        return None

    def offer(self, integrator):  # order 2 on "free", the registry's elsewhere
        return Offer(precisions=(FLOAT64, FLOAT32), orders=(("free", 2.0),))

    def models(self):
        return {**super().models(), "rigid_body": _ToyBody(self)}

    def prepare(self, case, integrator, dt, precision=FLOAT64, formulation="ball"):
        return ToySimulation(case, dt, precision)


class _Entry:
    name, value = NAME, f"{__name__}:ToyEngine"

    def load(self):
        return ToyEngine


@pytest.fixture
def toy(monkeypatch):
    registered = engines._entry_points()
    monkeypatch.setattr(engines, "_entry_points", lambda: {**registered, NAME: _Entry()})
    engines.get_engine.cache_clear()
    yield engines.get_engine(NAME)
    engines.get_engine.cache_clear()


CASE = dataclasses.replace(find_case("free-asymmetric"), t_end=0.5, dt=(1e-2, 5e-3), samples=11)


@pytest.mark.parametrize("process_global, startup_s", [(True, 0.0), (False, 0.0), (True, 5.0)])
def test_every_ok_row_of_an_engine_with_a_process_global_precision_is_timed(toy, tmp_path, monkeypatch,
                                                                            process_global, startup_s):
    """Four runs (2 dts x float64, float32) in one process, each timed once in its worker, then all four with repeats
    (no decides: sweep.run_sweep's default): grouped by precision, all four are timed with repeats; without the
    declaration the timing phase prepares all four first, and each switch of precision releases the models built
    before it (their repeats fail and they keep their single time: what e2 saw with Genesis, 7 of 8 rows untimed
    before the single time in the worker). With a start-up declared, the timing phase reuses the models kept from
    the accuracy runs (pool.prepare_kept), never one that a switch of precision released."""
    monkeypatch.setattr(ToyEngine, "timing", dataclasses.replace(ToyEngine.timing, startup_s=startup_s,
                                                                 process_global_precision=process_global))
    table = sweep.run_sweep([CASE], sweep.SweepOptions([NAME], tmp_path / "out", jobs=1, certify=False))
    rows = table[table.engine == NAME]
    rows = rows[rows.formulation == "ball"]
    assert list(rows.status) == ["ok"] * 4 and set(rows.precision) == {FLOAT64, FLOAT32}
    assert (rows.us_per_step > 0).all()  # every one has at least its single time
    timed = {p: int(rows[rows.precision == p].timing.str.startswith("best of").sum()) for p in (FLOAT64, FLOAT32)}
    if process_global:
        assert timed == {FLOAT64: 2, FLOAT32: 2}
    else:  # only the runs prepared after the last switch of precision survive (here 1)
        assert sum(timed.values()) < 4


def test_timing_groups_keep_the_other_engines_together(toy):
    keys = [("mujoco", FLOAT64), (NAME, FLOAT64), ("pinocchio", FLOAT64), (NAME, FLOAT32), (NAME, FLOAT64),
            ("not-an-engine", FLOAT32)]
    # the toy's precision met last first: the sweep ran it last, so its workers still hold it (and its models)
    assert timing.groups(keys) == [[0, 2, 5], [3], [1, 4]]
    assert timing.groups([(NAME, FLOAT32)]) == [[0]]


def test_the_ladders_timing_phase_times_one_precision_at_a_time(toy):
    grid_of = {dt: RunKey(CASE, NAME, "euler", dt).grid for dt in CASE.dt}
    points = [{"status": "ok", "engine": NAME, "precision": p, "dt": dt} for dt in CASE.dt for p in (FLOAT64, FLOAT32)]
    points.append({"status": "failed", "engine": NAME, "precision": FLOAT64, "dt": 1e-2})

    def prepare(point):
        return ToySimulation(CASE, point["dt"], point["precision"]), grid_of[point["dt"]]

    timing.time_points(points, prepare, 2, 0.0)
    assert all(p["us_per_sim_s"] > 0 for p in points[:4]) and "us_per_sim_s" not in points[4]


@pytest.mark.parametrize("declared, status", [(None, "failed"), (30.0, "ok")])
def test_an_engine_declares_a_longer_prepare_budget(toy, monkeypatch, declared, status):
    """A prepare of 0.3 s against the sweep's 0.1 s budget: failed naming the budget, unless the engine declares a
    longer one (the larger of the two holds); the message names the budget that held."""
    monkeypatch.setattr(ToyEngine, "prepare_s", 0.3)
    monkeypatch.setattr(ToyEngine, "timing", dataclasses.replace(ToyEngine.timing, prepare_budget_s=declared))
    budgets = budget.Budgets(prepare_s=0.1)
    run = RunKey(CASE, NAME, "euler", 1e-2, precision=FLOAT32)
    assert measure.prepare_budget(run, budgets) == (0.1 if declared is None else declared)
    assert measure.prepare_budget(RunKey(CASE, "mujoco", "euler", 1e-2), budgets) == 0.1
    row = measure.measure(run, None, full=False, budgets=budgets)
    assert row["status"] == status, row.get("message")
    if status == "failed":
        assert row["message"].startswith("prepare budget exceeded: stopped after 0.1 s")
        assert row["_budget"] == {"what": "prepare", "seconds": 0.1}
    else:
        assert math.isfinite(row["_accuracy_s"])


def test_an_integrator_declares_its_order_on_each_model(toy, tmp_path):
    """convergence.csv's declared_order (what the order verdict judges) is the engine's order on the family's model:
    the toy's euler is 1 on `ball` and declares 2 on `free` (as Genesis's implicitfast, the implicit midpoint rule on
    a free body); an engine that does not override the hook declares declared_order on every model."""
    from stereodyn.harness.analysis import fitting

    assert fitting.declared_order(NAME, "euler", "ball") == 1.0 == fitting.declared_order(NAME, "euler")
    assert fitting.declared_order(NAME, "euler", "free") == 2.0
    assert fitting.declared_order("mujoco", "rk4", "anything") == 4.0
    table = sweep.run_sweep([CASE], sweep.SweepOptions([NAME], tmp_path / "out", jobs=1, certify=False))
    declared = {(row["formulation"], row["precision"]): row["declared_order"]
                for row in fitting.sweep_orders(table[table.engine == NAME], set())}
    assert declared == {("ball", FLOAT64): 1.0, ("ball", FLOAT32): 1.0, ("free", FLOAT64): 2.0, ("free", FLOAT32): 2.0}


class _Recorder:
    """A simulation that records the grids it is run on."""

    def __init__(self):
        self.grids = []

    def run(self, grid):
        self.grids.append(grid)


@pytest.mark.parametrize("short", [False, True])
def test_a_run_is_warmed_up_whole_unless_its_engine_declares_a_short_warm_up(toy, monkeypatch, short):
    monkeypatch.setattr(ToyEngine, "timing", dataclasses.replace(ToyEngine.timing, short_warm_up=short))
    grid = time_grid(1.0, 1e-4, 101)  # 10000 steps, a sample every 100
    sim = _Recorder()
    timing.warm_up(sim, grid, NAME)
    (warm,) = sim.grids
    if not short:
        assert warm is grid
        return
    # to the first sample at or past WARM_UP_STEPS (256): step 300, same dt and sample times
    assert (warm.dt, warm.steps, warm.sample_steps.tolist()) == (grid.dt, 300, [0, 100, 200, 300])
    assert warm.times.tolist() == grid.times[:4].tolist()
    # a grid shorter than the warm-up is warmed up whole, and a sparse one on its first sample
    assert timing.first_steps(time_grid(0.01, 1e-4, 11), timing.WARM_UP_STEPS).steps == 100
    assert timing.first_steps(time_grid(1.0, 1e-4, 3), timing.WARM_UP_STEPS).sample_steps.tolist() == [0, 5000]


# The built-in engines that declare a short warm-up run every kind of their runs on a grid's first steps.
SHORT = [("free-asymmetric", "reference", "quaternion", "rk4"), ("free-asymmetric", "reference", "gibbs", "taylor"),
         ("free-asymmetric", "reference", "quaternion", "scipy_rk45"), ("heavy-asymmetric", "pinocchio", "", "rk4"),
         ("central-field-turning", "reference", "euler_zxz", "rk4"), ("sliding-ladder", "pinocchio", "bilateral",
         "rk4"),
         ("sliding-ladder", "reference", "theta", "taylor")]


@pytest.mark.parametrize("name, engine, formulation, integrator", SHORT)
def test_a_short_warm_up_runs_the_first_steps_of_the_run(name, engine, formulation, integrator):
    assert engines.get_engine(engine).timing.short_warm_up
    case = find_case(name)
    run = RunKey(case, engine, integrator, 1e-3 if integrator in ("rk4",) else None, formulation=formulation)
    sim, grid = measure.prepare(run)
    part = timing.first_steps(grid, timing.WARM_UP_STEPS)
    trajectory = sim.run(part)
    assert trajectory.status.value == "ok" and 0 < part.t_end <= grid.t_end  # the theta equation's 160 steps: whole
    assert trajectory.times.tolist() == part.times.tolist()
