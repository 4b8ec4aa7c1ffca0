"""Work–precision: step-size ladders, convergence orders, round-off floors, stability limits and the Pareto table.

For a case × engine × formulation × integrator, a ladder is LADDER_POINTS log-spaced steps from the largest stable dt
(found by bisection) down to t_end / max_steps, where the 4th-order methods reach their round-off floor. Each point is
one untimed accuracy run (errors against the truth, energy drift) and separate timed runs (harness.timing: best of N
after the accuracy run as warm-up, within a budget), costed as µs of stepping per simulated second.

The error whose order is fitted is the global error of the state, state_err = max(attitude_err, omega_err,
casimir_drift): a method's order is that of its whole state. (The attitude alone can converge faster than the method:
MuJoCo's semi-implicit Euler on a plane pendulum has the positions of Störmer–Verlet, second order, while its
velocities are first order; explicit Euler on a steady rotation has a second-order phase but a first-order |q| growth.)

From the points:
- the round-off floor: walking from large to small dt among the points below ASYMPTOTIC_MAX, the first point after
  which the error falls with a local slope below FLOOR_SLOPE while it is below FLOOR_MAX (a stall higher up is not
  round-off); floor_dt is that point's dt, floor_err the smallest error from there on;
- the order: least-squares slope of log state_err against log dt over the asymptotic range: points above the floor
  (dt > floor_dt), with ROUNDOFF_MARGIN eps steps <= state_err <= ASYMPTOTIC_MAX; at least two points;
- stable_dt_max: the largest dt whose run over t_end finishes ok with energy_drift <= STABLE_ENERGY_DRIFT, by
  doubling/halving from a start until the outcome changes, then geometric bisection to STABILITY_RTOL.

Outputs in the run folder: ladder.csv (every point), convergence.csv (one row per ladder, and per run family of the
sweep whose own dt list has two asymptotic points), pareto.csv (per case and accuracy target, the cheapest run), and
the orders as rows of checks.csv (quantity convergence_order, theory = the declared order).
"""
from __future__ import annotations

import math
import multiprocessing
import os
from concurrent.futures import ProcessPoolExecutor, as_completed
from dataclasses import dataclass
from pathlib import Path
from typing import Callable

import numpy as np
import pandas as pd

from stereodyn.harness import checks, metrics
from stereodyn.harness.cases import Case
from stereodyn.harness.engines import get_engine
from stereodyn.harness.trajectory import Status
from stereodyn.harness.grid import time_grid
from stereodyn.harness.report.markdown import markdown_table as _md, number as _num
from stereodyn.harness.results import write_atomic
from stereodyn.harness import timing

LADDER_FILE, CONVERGENCE_FILE, PARETO_FILE = "ladder.csv", "convergence.csv", "pareto.csv"
LADDER_COLUMNS = ("case", "engine", "formulation", "integrator", "dt", "t_end", "steps", "rhs_evals", "status",
                  "message", "attitude_err", "attitude_err_end", "omega_err", "casimir_drift", "energy_drift",
                  "state_err", "wall_s", "us_per_sim_s", "us_per_sim_s_spread", "rhs_per_sim_s")
CONVERGENCE_COLUMNS = ("case", "engine", "formulation", "integrator", "order", "floor_dt", "floor_err",
                       "stable_dt_max", "declared_order", "points", "source", "note")
PARETO_COLUMNS = ("case", "target", "engine", "formulation", "integrator", "dt", "attitude_err", "us_per_sim_s",
                  "us_per_sim_s_spread", "rhs_per_sim_s", "steps", "source", "ties", "not_recommended")
ORDER_QUANTITY = "convergence_order"

LADDER_POINTS = 10
FULL_MAX_STEPS = 200_000     # --dt-ladder: rk4 reaches its round-off floor on the suite's cases well before this
DEFAULT_MAX_STEPS = 40_000   # the default run's small ladder (see DEFAULT_LADDER)
# The default run ladders these cases only, on the quaternion formulation of the reference engine: one free body and
# the chaotic heavy top whose MuJoCo Euler stability limit the suite documents (cases/heavy-asymmetric.toml).
DEFAULT_LADDER = ("free-asymmetric", "heavy-asymmetric")
DEFAULT_LADDER_FORMULATIONS = ("", "quaternion")
# Left out of the default ladder (their orders still come from the dt lists): MuJoCo's implicitfast is bit-identical
# to its Euler on a ball joint (ENGINES.md), and rk4_naive is a documented contrast that costs as much as rk4.
DEFAULT_LADDER_SKIP = ("implicitfast", "rk4_naive")
TIMING_REPEATS, TIMING_BUDGET_S = 3, 0.3

# A state error above this (rad, or relative for ω) is pre-asymptotic: higher-order terms and the saturation of the
# attitude angle at π bend the curve (measured on the suite: RK4 at 5e-2 rad gives a slope of 3.6, Euler at 0.3 of 1.2).
ASYMPTOTIC_MAX = 3e-2
# Below ROUNDOFF_MARGIN × eps × steps the error is contaminated by rounding, which accumulates at most ~ eps per step
# (measured floors of the suite: 2e-14 to 5e-12 rad after 2e3 to 2e4 steps): a 30x margin keeps its share of a
# 2-point slope below 0.03.
ROUNDOFF_MARGIN = 30.0
EPS = float(np.finfo(float).eps)
FLOOR_SLOPE = 0.5            # a local slope below this: the error has stopped falling
FLOOR_MAX = 1e-6             # a stall above this is not round-off (pre-asymptotic wiggles, resonances)
STABLE_ENERGY_DRIFT = 1.0    # energy off by its whole scale: the run has blown up even if |ω| is not yet 1e6 x
STABILITY_RTOL = 0.02        # bisection stops when the bracket [stable, unstable] is this tight (relative)
MIN_STEPS = 20               # the largest dt tried is t_end / MIN_STEPS: fewer steps say nothing about stability
ACCURACY_TARGETS = tuple(10.0 ** -k for k in range(2, 13))
# Declared orders of engine-owned integrators (ENGINES.md: MuJoCo's Euler is semi-implicit, implicit/implicitfast are
# first order, RK4 on a ball joint is RKMK, 4th order in MuJoCo 4); the others come from the integrator registry.
ENGINE_ORDERS = {("mujoco", "euler"): 1, ("mujoco", "implicit"): 1, ("mujoco", "implicitfast"): 1,
                 ("mujoco", "rk4"): 4}
ENGINE_STATE_SPACE = {"pinocchio": "lie", "reference": "vector"}


def declared_order(engine: str, integrator: str) -> float:
    if (engine, integrator) in ENGINE_ORDERS:
        return float(ENGINE_ORDERS[(engine, integrator)])
    from stereodyn.harness import integrators

    try:
        return float(integrators.get(integrator, ENGINE_STATE_SPACE.get(engine, "lie")).order)
    except KeyError:
        return math.nan


@dataclass(frozen=True)
class Family:
    """Runs that differ only in dt."""

    case: Case
    engine: str
    formulation: str
    integrator: str

    @property
    def label(self) -> str:
        return " ".join(x for x in (self.case.name, self.engine, self.formulation, self.integrator) if x)


# ------------------------------------------------------------------------------------------------ one point

def _prepare(family: Family, dt: float):
    extra = {"formulation": family.formulation} if family.formulation else {}
    return get_engine(family.engine).prepare(family.case, family.integrator, dt, **extra)


def measure(family: Family, dt: float, timed: bool = True, with_truth: bool = True) -> dict:
    """One ladder point: accuracy run (errors against the truth when with_truth), then timed runs. Never raises."""
    case = family.case
    grid = time_grid(case.t_end, dt, case.samples)
    row = {"case": case.name, "engine": family.engine, "formulation": family.formulation,
           "integrator": family.integrator, "dt": float(dt), "t_end": grid.t_end, "steps": grid.steps}
    try:
        sim = _prepare(family, dt)
        traj = sim.run(grid)
        row.update(status=traj.status.value, message=traj.message, rhs_evals=traj.rhs_evals,
                   rhs_per_sim_s=traj.rhs_evals / grid.t_end if traj.rhs_evals else math.nan)
        drifts = metrics.drifts(case, traj, metrics.applicable_integrals(case))
        row.update(energy_drift=drifts["energy_drift"], casimir_drift=drifts["casimir_drift"])
        if with_truth:
            from stereodyn.reference import truth as reference_truth

            truth = reference_truth.truth(case.body, case.quat0, case.omega0, grid.times)
            row.update(metrics.errors(traj, truth.quat, truth.omega, case.horizon))
            parts = [row["attitude_err"], row["omega_err"], row["casimir_drift"]]
            row["state_err"] = max((p for p in parts if math.isfinite(p)), default=math.nan) \
                if math.isfinite(row["attitude_err"]) else math.nan
        if timed and traj.status is Status.OK:
            row.update(_timed(sim, grid))
    except Exception as exc:  # a point that breaks is data, as in the sweep
        row.update(status=Status.FAILED.value, message=f"{type(exc).__name__}: {exc}".splitlines()[0])
    return row


def _timed(sim, grid) -> dict:
    measured = timing.measure(lambda: sim.run(grid), TIMING_REPEATS, TIMING_BUDGET_S)
    return {"wall_s": measured.best, "us_per_sim_s": measured.best / grid.t_end * 1e6,
            "us_per_sim_s_spread": measured.spread / grid.t_end * 1e6}


def time_points(points: list[dict], families_by_label: dict[tuple, "Family"]) -> None:
    """The ladders' timing phase: every ok point timed in this process, one at a time, after all the accuracy runs
    (harness.timing: a timed run shares the cores with no other run). Updates the points in place."""
    for row in points:
        if row.get("status") != Status.OK.value:
            continue
        family = families_by_label[(row["case"], row["engine"], row["formulation"], row["integrator"])]
        try:
            sim = _prepare(family, row["dt"])
            grid = time_grid(family.case.t_end, row["dt"], family.case.samples)
            sim.run(grid)  # the warm-up
            row.update(_timed(sim, grid))
        except Exception:  # it ran ok untimed: left untimed rather than breaking the phase
            pass


def _stable(row: dict) -> bool:
    drift = row.get("energy_drift", math.nan)
    return row.get("status") == Status.OK.value and not (isinstance(drift, float) and drift > STABLE_ENERGY_DRIFT)


# ------------------------------------------------------------------------------------------------ fits

def stability_limit(is_stable: Callable[[float], bool], dt_start: float, dt_cap: float,
                    dt_floor: float) -> tuple[float, str]:
    """(largest stable dt, note): doubling or halving from dt_start until the outcome changes, then geometric
    bisection to STABILITY_RTOL. NaN with a note when no change is found in [dt_floor, dt_cap]."""
    dt = min(dt_start, dt_cap)
    stable_dt = unstable_dt = None
    if is_stable(dt):
        stable_dt = dt
        while unstable_dt is None and dt * 2.0 <= dt_cap * (1 + 1e-12):
            dt *= 2.0
            if is_stable(dt):
                stable_dt = dt
            else:
                unstable_dt = dt
        if unstable_dt is None:
            return math.nan, f"stable up to dt = {dt:.4g} s (t_end / {MIN_STEPS} is the largest tried)"
    else:
        unstable_dt = dt
        while stable_dt is None and dt / 2.0 >= dt_floor:
            dt /= 2.0
            if is_stable(dt):
                stable_dt = dt
            else:
                unstable_dt = dt
        if stable_dt is None:
            return math.nan, f"unstable down to dt = {dt:.4g} s"
    while unstable_dt / stable_dt > 1.0 + STABILITY_RTOL:
        middle = math.sqrt(stable_dt * unstable_dt)
        if is_stable(middle):
            stable_dt = middle
        else:
            unstable_dt = middle
    return stable_dt, ""


def fit(points: pd.DataFrame, declared: float) -> dict:
    """order, floor_dt, floor_err, points and a note from ladder points (columns dt, steps, status, state_err)."""
    ok = points[(points["status"] == Status.OK.value) & np.isfinite(points["state_err"])
                & (points["state_err"] > 0)].sort_values("dt", ascending=False)
    dt, err, steps = ok["dt"].to_numpy(float), ok["state_err"].to_numpy(float), ok["steps"].to_numpy(float)
    below = err <= ASYMPTOTIC_MAX
    floor_index = None
    for i in range(len(dt) - 1):
        if not (below[i] and err[i] <= FLOOR_MAX):
            continue
        slope = math.log(err[i] / err[i + 1]) / math.log(dt[i] / dt[i + 1])
        if slope < FLOOR_SLOPE:
            floor_index = i
            break
    floor_dt = float(dt[floor_index]) if floor_index is not None else math.nan
    floor_err = float(err[floor_index:].min()) if floor_index is not None else math.nan
    asymptotic = below & (err >= ROUNDOFF_MARGIN * EPS * steps)
    if floor_index is not None:  # the stall's first point may already carry the floor
        asymptotic &= np.arange(len(dt)) < floor_index
    n = int(asymptotic.sum())
    notes = []
    order = math.nan
    if n >= 2:
        order = float(np.polyfit(np.log(dt[asymptotic]), np.log(err[asymptotic]), 1)[0])
    else:
        notes.append(f"{n} point(s) in the asymptotic range ({ROUNDOFF_MARGIN:g} eps steps <= state_err <= "
                     f"{ASYMPTOTIC_MAX:g})")
    if floor_index is None and len(dt):
        notes.append(f"no round-off floor down to dt = {dt[-1]:.3g}")
    return {"order": order, "floor_dt": floor_dt, "floor_err": floor_err, "declared_order": declared, "points": n,
            "note": "; ".join(notes)}


# ------------------------------------------------------------------------------------------------ ladders

def ladder_dts(top: float, bottom: float, points: int = LADDER_POINTS) -> list[float]:
    """points log-spaced steps from top down to bottom (each rounded to 4 significant digits, so a dt prints back)."""
    if not bottom < top:
        return [top]
    return [float(f"{x:.4g}") for x in np.geomspace(top, bottom, points)]


def run_ladder(family: Family, max_steps: int) -> tuple[list[dict], dict]:
    """The ladder of one family: its points and its convergence row. Never raises."""
    case = family.case
    declared = declared_order(family.engine, family.integrator)
    cap, floor = case.t_end / MIN_STEPS, case.t_end / max_steps
    cache: dict[float, dict] = {}

    def is_stable(dt: float) -> bool:
        cache[dt] = measure(family, dt, timed=False, with_truth=False)
        return _stable(cache[dt])

    start = max(case.dt)
    stable_dt, stability_note = stability_limit(is_stable, start, cap, floor)
    top = stable_dt if math.isfinite(stable_dt) else (cap if "stable up to" in stability_note else start)
    points = [measure(family, dt, timed=False) for dt in ladder_dts(top, floor)]  # timed later (time_points)
    frame = pd.DataFrame(points, columns=list(LADDER_COLUMNS))
    row = {"case": case.name, "engine": family.engine, "formulation": family.formulation,
           "integrator": family.integrator, "stable_dt_max": stable_dt, "source": "ladder", **fit(frame, declared)}
    if stability_note:
        row["note"] = "; ".join(x for x in (row["note"], stability_note) if x)
    return points, row


def families(cases: list[Case], engines: list[str], integrators: list[str] | None,
             formulations: tuple[str, ...] | None = None) -> list[Family]:
    """The fixed-step run families a sweep of these cases would have (harness.runner.plan's selection)."""
    from stereodyn.harness.runner import plan

    specs, _ = plan(cases, engines, integrators)
    out = {}
    for spec in specs:
        if spec.dt is None or (formulations is not None and spec.formulation not in formulations):
            continue
        out.setdefault((spec.case.name, spec.engine, spec.formulation, spec.integrator),
                       Family(spec.case, spec.engine, spec.formulation, spec.integrator))
    return list(out.values())


def _ladder_task(family: Family, max_steps: int) -> tuple[list[dict], dict]:
    return run_ladder(family, max_steps)


def run_ladders(chosen: list[Family], max_steps: int, jobs: int | None = None,
                progress: Callable[[str], None] | None = None) -> tuple[list[dict], list[dict]]:
    """Every family's ladder, on `jobs` processes (spawned, as the sweep's). Returns (points, convergence rows)."""
    points, rows = _accuracy_ladders(chosen, max_steps, jobs, progress)
    time_points(points, {(f.case.name, f.engine, f.formulation, f.integrator): f for f in chosen})
    return points, rows


def _accuracy_ladders(chosen: list[Family], max_steps: int, jobs: int | None,
                      progress: Callable[[str], None] | None) -> tuple[list[dict], list[dict]]:
    """run_ladders without the timing: every family's untimed points and convergence row."""
    points, rows = [], []
    jobs = jobs or os.cpu_count() or 1
    if jobs == 1 or len(chosen) <= 1:
        for family in chosen:
            p, r = run_ladder(family, max_steps)
            points += p
            rows.append(r)
            if progress:
                progress(family.label)
        return points, rows
    context = multiprocessing.get_context("spawn")
    with ProcessPoolExecutor(max_workers=jobs, mp_context=context) as pool:
        futures = {pool.submit(_ladder_task, f, max_steps): f for f in chosen}
        for future in as_completed(futures):
            family = futures[future]
            try:
                p, r = future.result()
            except Exception as exc:  # a worker that died: the family's row says so
                p, r = [], {"case": family.case.name, "engine": family.engine, "formulation": family.formulation,
                            "integrator": family.integrator, "source": "ladder",
                            "note": f"worker failed: {type(exc).__name__}: {exc}".splitlines()[0]}
            points += p
            rows.append(r)
            if progress:
                progress(family.label)
    return points, rows


# ------------------------------------------------------------------------------------------------ from a sweep

def with_state_err(df: pd.DataFrame) -> pd.DataFrame:
    df = df.copy()
    parts = df[["attitude_err", "omega_err", "casimir_drift"]].astype(float)
    df["state_err"] = parts.max(axis=1).where(np.isfinite(df["attitude_err"].astype(float)))
    return df


def sweep_orders(results: pd.DataFrame, skip: set[tuple]) -> list[dict]:
    """Convergence rows from the sweep's own dt lists (no extra runs), for families not in skip."""
    df = with_state_err(results[results["dt"].notna()].fillna({"formulation": ""}))
    rows = []
    for (case, engine, formulation, integrator), group in df.groupby(
            ["case", "engine", "formulation", "integrator"], sort=False):
        if (case, engine, formulation, integrator) in skip or group["dt"].nunique() < 2:
            continue
        declared = declared_order(engine, integrator)
        row = {"case": case, "engine": engine, "formulation": formulation, "integrator": integrator,
               "stable_dt_max": math.nan, "source": "dt_list", **fit(group, declared)}
        rows.append(row)
    return rows


def convergence_table(rows: list[dict]) -> pd.DataFrame:
    df = pd.DataFrame(rows, columns=list(CONVERGENCE_COLUMNS))
    return df.fillna({"formulation": "", "note": ""})


def order_checks(convergence: pd.DataFrame) -> pd.DataFrame:
    """checks.csv rows: the fitted order against the declared one (dt empty: a fit over many)."""
    records = []
    for _, row in convergence.iterrows():
        if not math.isfinite(row["order"]) or not math.isfinite(row["declared_order"]):
            continue
        records.append({"case": row["case"], "engine": row["engine"], "formulation": row["formulation"],
                        "integrator": row["integrator"], "dt": math.nan, "quantity": ORDER_QUANTITY,
                        "theory": row["declared_order"], "measured": row["order"],
                        "error": checks.error(ORDER_QUANTITY, row["declared_order"], row["order"])})
    return pd.DataFrame(records, columns=list(checks.COLUMNS))


# Two candidates tie when their costs differ by no more than the timing noise: the sum of their spreads (slowest
# minus fastest of their timed runs), and at least TIE_RTOL of the cheaper cost. The floor stands for the noise that
# repeats inside one process do not show and two runs of the sweep do (clock boost, cache and memory placement); 5% is
# the usual run-to-run scatter of a micro-benchmark on an idle machine, an assumption to be checked by two runs there.
TIE_RTOL = 0.05


def pareto(results: pd.DataFrame, ladder: pd.DataFrame, failed: set | None = None) -> pd.DataFrame:
    """Per case and accuracy target, the cheapest fixed-step run (sweep or ladder) whose attitude_err reaches it, with
    ties and the runs not recommended (pareto_table)."""
    sweep = results[results["dt"].notna()].copy()
    sweep["us_per_sim_s"] = sweep["wall_s"] / sweep["t_end"] * 1e6
    sweep["us_per_sim_s_spread"] = sweep["us_per_step_spread"] * sweep["steps"] / sweep["t_end"]
    sweep["source"] = "sweep"
    ladder = ladder.copy()
    ladder["source"] = "ladder"
    columns = ["case", "engine", "formulation", "integrator", "dt", "attitude_err", "us_per_sim_s",
               "us_per_sim_s_spread", "rhs_per_sim_s", "steps", "source", "status"]
    for frame_ in (sweep, ladder):
        for column in columns:
            if column not in frame_:
                frame_[column] = math.nan
    both = pd.concat([sweep[columns], ladder[columns]] if len(ladder) else [sweep[columns]], ignore_index=True)
    return pareto_table(both, list(dict.fromkeys(results["case"])), failed or set())


def _candidate(row) -> str:
    return f"{_name(row)} dt={row['dt']:.3g} ({_num(row['us_per_sim_s'], '.3g')} µs/s)"


def pareto_table(runs: pd.DataFrame, cases: list[str], failed: set = frozenset()) -> pd.DataFrame:
    """The Pareto table from candidate runs (columns case, engine, formulation, integrator, dt, attitude_err,
    us_per_sim_s, us_per_sim_s_spread, rhs_per_sim_s, steps, source, status).

    Per case and target: among the ok runs reaching the target whose integrator passed its verdicts (failed: a set of
    (engine, formulation, integrator), harness.verdicts.failed_integrators), the cheapest; every run within the timing
    noise of it (TIE_RTOL, the spreads) is a tie, listed in `ties`, and the winner among the tied is the one with the
    fewest right-hand-side evaluations per simulated second (a cost noise cannot touch), then the cheapest.
    `not_recommended` names the cheaper runs left out because their integrator failed a verdict."""
    from stereodyn.harness.verdicts import is_failed

    runs = runs.fillna({"formulation": ""})
    runs = runs[(runs["status"] == Status.OK.value) & np.isfinite(runs["attitude_err"].astype(float))
                & np.isfinite(runs["us_per_sim_s"].astype(float))]
    bad = np.array([is_failed(set(failed), r.engine, r.formulation, r.integrator) for r in runs.itertuples()],
                   dtype=bool)
    records = []
    for case in cases:
        in_case = (runs["case"] == case).to_numpy()
        for target in ACCURACY_TARGETS:
            reach = in_case & (runs["attitude_err"] <= target).to_numpy()
            good, excluded = runs[reach & ~bad], runs[reach & bad]
            if good.empty:
                records.append({"case": case, "target": target, "engine": "", "formulation": "", "integrator": "",
                                "source": "none reached it" if excluded.empty else "only runs that failed a verdict",
                                "ties": "", "not_recommended": "; ".join(_candidate(r) for _, r in
                                                                          excluded.nsmallest(3, "us_per_sim_s")
                                                                          .iterrows())})
                continue
            cheapest = good.loc[good["us_per_sim_s"].idxmin()]
            noise = np.maximum(good["us_per_sim_s_spread"].fillna(0.0).to_numpy(float)
                               + (0.0 if not math.isfinite(cheapest["us_per_sim_s_spread"])
                                  else cheapest["us_per_sim_s_spread"]),
                               TIE_RTOL * cheapest["us_per_sim_s"])
            tied = good[(good["us_per_sim_s"].to_numpy(float) - cheapest["us_per_sim_s"]) <= noise]
            rhs = tied["rhs_per_sim_s"].astype(float).fillna(math.inf)
            best = tied.loc[tied.assign(_rhs=rhs).sort_values(["_rhs", "us_per_sim_s"], kind="stable").index[0]]
            cheaper_bad = excluded[excluded["us_per_sim_s"] < best["us_per_sim_s"]]
            records.append({"case": case, "target": target, **{c: best[c] for c in PARETO_COLUMNS[2:12]},
                            "ties": "; ".join(_candidate(r) for i, r in tied.iterrows() if i != best.name),
                            "not_recommended": "; ".join(_candidate(r) for _, r in
                                                         cheaper_bad.nsmallest(3, "us_per_sim_s").iterrows())})
    return pd.DataFrame(records, columns=list(PARETO_COLUMNS))


def rewrite_pareto(out_dir: Path, results: pd.DataFrame, failed: set) -> None:
    """pareto.csv again, leaving out the runs of the integrators that failed a verdict (harness.verdicts)."""
    ladder = read_optional(Path(out_dir) / LADDER_FILE, ("formulation", "engine", "integrator", "message"))
    if ladder is None:
        ladder = pd.DataFrame(columns=list(LADDER_COLUMNS))
    _write(pareto(results, ladder, failed), Path(out_dir) / PARETO_FILE)


def _write(df: pd.DataFrame, path: Path) -> None:
    write_atomic(path, df.to_csv(index=False, float_format="%.10g"))


def analyse(out_dir: Path, results: pd.DataFrame, cases: list[Case], engines: list[str],
            integrators: list[str] | None, ladder: str = "default", max_steps: int | None = None,
            jobs: int | None = None, progress: Callable[[str], None] | None = None) -> dict[str, Path]:
    """The work–precision phase of `stereodyn run`, after the sweep. ladder: "full" (every family of the sweep),
    "default" (DEFAULT_LADDER cases, DEFAULT_LADDER_FORMULATIONS) or "off". Writes ladder.csv, convergence.csv,
    pareto.csv and appends the orders to checks.csv; returns the paths written."""
    out_dir = Path(out_dir)
    # Orders, floors and stability limits are about the body with a fixed point; other scene kinds (the constrained
    # sliding ladder, whose MuJoCo model has soft constraints) keep their Pareto rows only.
    rigid = [c for c in cases if isinstance(c, Case)]
    other_kinds = {c.name for c in cases} - {c.name for c in rigid}
    if ladder == "full":
        chosen = families(rigid, engines, integrators)
        max_steps = max_steps or FULL_MAX_STEPS
    elif ladder == "default":
        chosen = [f for f in families([c for c in rigid if c.name in DEFAULT_LADDER], engines, integrators,
                                      DEFAULT_LADDER_FORMULATIONS) if f.integrator not in DEFAULT_LADDER_SKIP]
        max_steps = max_steps or DEFAULT_MAX_STEPS
    else:
        chosen = []
    # the costliest first, so the pool ends together
    chosen.sort(key=lambda f: (f.engine == "mujoco", -ENGINE_ORDERS.get((f.engine, f.integrator), 0)))
    points, ladder_rows = run_ladders(chosen, max_steps or DEFAULT_MAX_STEPS, jobs, progress) if chosen else ([], [])
    laddered = {(r["case"], r["engine"], r["formulation"], r["integrator"]) for r in ladder_rows}
    convergence = convergence_table(ladder_rows + sweep_orders(results[~results["case"].isin(other_kinds)], laddered))
    ladder_df = pd.DataFrame(points, columns=list(LADDER_COLUMNS))
    paths = {"ladder": out_dir / LADDER_FILE, "convergence": out_dir / CONVERGENCE_FILE,
             "pareto": out_dir / PARETO_FILE}
    _write(ladder_df, paths["ladder"])
    _write(convergence, paths["convergence"])
    _write(pareto(results, ladder_df), paths["pareto"])
    checks_path = out_dir / checks.CHECKS_FILE
    existing = checks.read_checks(checks_path) if checks_path.is_file() else pd.DataFrame(columns=list(checks.COLUMNS))
    existing = existing[existing["quantity"] != ORDER_QUANTITY]
    merged = pd.concat([existing, order_checks(convergence)], ignore_index=True) if len(existing) \
        else order_checks(convergence)
    write_atomic(checks_path, merged.to_csv(index=False, float_format="%.17g"))
    return paths


# ------------------------------------------------------------------------------------------------ the report

def read_optional(path: Path, text_columns: tuple[str, ...] = ("formulation",)) -> pd.DataFrame | None:
    if not Path(path).is_file():
        return None
    df = pd.read_csv(path, dtype={c: str for c in text_columns}, keep_default_na=True)
    return df.fillna({c: "" for c in text_columns if c in df})


def _name(row) -> str:
    return " ".join(str(x) for x in (row["engine"], row["formulation"], row["integrator"]) if isinstance(x, str) and x)


def report_lines(out_dir: Path) -> list[str]:
    """The report's "What to use" and "Convergence" sections, from pareto.csv and convergence.csv (empty without)."""
    lines: list[str] = []
    pareto_df = read_optional(Path(out_dir) / PARETO_FILE, ("formulation", "engine", "integrator", "source", "ties",
                                                             "not_recommended"))
    if pareto_df is not None and len(pareto_df):
        lines += ["## What to use", "",
                  "Per case and accuracy target (max attitude error, rad, up to the case's horizon): the cheapest "
                  "fixed-step run that reaches it, over the sweep's runs and the dt ladders (pareto.csv); cost in µs of "
                  "stepping per simulated second. Adaptive runs (heyoka) are the truth and its relatives, not "
                  "contenders. Timings are comparable within one report only; each run is timed alone (best of up "
                  "to 3). '**tie** with N': N other runs cost the same within the timing noise (pareto.csv `ties`, "
                  f"the sum of their spreads, at least {TIE_RTOL:.0%}); the one shown needs "
                  "the fewest right-hand-side evaluations per simulated second. A run whose integrator failed a "
                  "verdict is never shown; a cheaper one is named as not recommended.", ""]
        targets = sorted(pareto_df["target"].unique(), reverse=True)
        header = ["case"] + [f"≤ {t:.0e}" for t in targets]
        rows = []
        for case, group in pareto_df.groupby("case", sort=False):
            cells = [case]
            for target in targets:
                hit = group[group["target"] == target]
                row = hit.iloc[0] if len(hit) else None
                if row is None or not row["engine"]:
                    cell = "-"
                else:
                    cell = f"{_name(row)} dt={row['dt']:.3g} ({_num(row['us_per_sim_s'], '.3g')} µs/s)"
                    ties = row.get("ties", "")
                    if isinstance(ties, str) and ties:
                        cell += f" **tie** with {ties.count(';') + 1}"
                failed_runs = row.get("not_recommended", "") if row is not None else ""
                if isinstance(failed_runs, str) and failed_runs:
                    cell += f" (cheaper, not recommended: {failed_runs.split(';')[0]}, failed a verdict)"
                cells.append(cell)
            rows.append(cells)
        lines += _md(header, rows) + [""]
    convergence = read_optional(Path(out_dir) / CONVERGENCE_FILE, ("formulation", "note", "source"))
    if convergence is not None and len(convergence):
        ladders = convergence[convergence["source"] == "ladder"]
        fitted = convergence[np.isfinite(convergence["order"])]
        lines += ["## Convergence, round-off floors and stability", "",
                  f"convergence.csv: {len(fitted)} of {len(convergence)} run families have a fitted order (slope of "
                  "log state error, max(attitude_err, omega_err, casimir_drift), against log dt over the asymptotic "
                  f"range: {ROUNDOFF_MARGIN:g} eps steps <= error <= {ASYMPTOTIC_MAX:g}). Families with a dt ladder "
                  "(ladder.csv: about ten dt from the stability limit down to the round-off regime) also have the "
                  "round-off floor and the largest stable dt over t_end (bisection; stable: finished ok with energy "
                  f"drift <= {STABLE_ENERGY_DRIFT:g}); the others are fitted on the sweep's own dt list.", ""]
        if len(ladders):
            rows = [[r["case"], _name(r), _num(r["declared_order"], ".0f"), _num(r["order"], ".2f"),
                     _num(r["floor_dt"], ".3g"), _num(r["floor_err"]), _num(r["stable_dt_max"], ".4g"),
                     r["note"]] for _, r in ladders.iterrows()]
            lines += _md(["case", "run", "declared", "fitted order", "floor dt", "floor err", "stable dt max",
                          "note"], rows) + [""]
        others = fitted[fitted["source"] != "ladder"]
        if len(others):
            summary = []
            for (engine, formulation, integrator), group in others.groupby(["engine", "formulation", "integrator"],
                                                                           sort=False):
                summary.append([_name({"engine": engine, "formulation": formulation, "integrator": integrator}),
                                _num(group["declared_order"].iloc[0], ".0f"), str(len(group)),
                                _num(group["order"].min(), ".2f"), _num(group["order"].max(), ".2f")])
            lines += ["Fitted on the sweep's dt lists (every case with two asymptotic points):", "",
                      *_md(["run", "declared", "cases", "smallest order", "largest order"], summary), ""]
    return lines
