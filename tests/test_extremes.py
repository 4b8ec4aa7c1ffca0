"""The extremes suite (cases/extreme/, `stereodyn run --extremes`): every row is a number or a clean status with a
reason; nothing crashes, no NaN without a status. The default run takes a fast subset; the whole suite is slow."""
import math

import numpy as np
import pandas as pd
import pytest

from stereodyn.harness.scenes.cases import load_suite, suite_dir
from stereodyn.harness.run.sweep import SweepOptions, run_sweep

EXTREME_DIR = suite_dir() / "extreme"
# The fast subset: these cases on MuJoCo and Pinocchio; the long horizon (1e6 steps), the 1e5-step round-off case and
# the reference engine's formulations are left to the slow test.
FAST_CASES = ("fast-spin", "near-separatrix", "near-planar", "rod", "beyond-stability")


def _assert_clean(df: pd.DataFrame) -> None:
    assert len(df)
    assert set(df["status"]) <= {"ok", "diverged", "failed", "skipped"}
    problems = df[df["status"] != "ok"]
    assert (problems["message"].fillna("").str.len() > 0).all(), problems[["case", "engine", "integrator", "dt"]]
    ok = df[df["status"] == "ok"]
    truth = (ok["engine"] == "reference") & (ok["formulation"] == "quaternion") & (ok["integrator"] == "taylor")
    for column in ("energy_drift", "casimir_drift"):
        assert np.isfinite(ok[column]).all(), ok[~np.isfinite(ok[column])][["case", "engine", "integrator", "dt"]]
    measured = ok[~truth]
    assert np.isfinite(measured["attitude_err"]).all(), \
        measured[~np.isfinite(measured["attitude_err"])][["case", "engine", "integrator", "dt"]]
    assert np.isfinite(ok["us_per_step"]).all()


def test_extreme_cases_are_tagged():
    cases = load_suite(EXTREME_DIR)
    assert {c.name for c in cases} >= set(FAST_CASES) | {"long-horizon", "roundoff-steps"}
    assert all("extreme" in c.tags for c in cases)
    planar = next(c for c in cases if c.name == "near-planar")
    moments = np.linalg.eigvalsh(planar.inertia)
    assert abs(moments[0] + moments[1] - moments[2]) <= 1e-6
    spin = next(c for c in cases if c.name == "fast-spin")
    assert np.linalg.norm(spin.omega0) >= 1000.0
    long = next(c for c in cases if c.name == "long-horizon")
    assert round(long.t_end / min(long.dt)) >= 1_000_000


@pytest.mark.slow  # since 2026-12-02, ~24 s; the whole extremes suite is -m slow beside it (the default suite's 8 minutes)
def test_extremes_fast_subset_runs_clean(tmp_path):
    cases = [c for c in load_suite(EXTREME_DIR) if c.name in FAST_CASES]
    df = run_sweep(cases, SweepOptions(["mujoco", "pinocchio"], tmp_path, ["euler", "rk4", "symplectic_euler"], jobs=2))
    _assert_clean(df)
    beyond = df[(df["case"] == "beyond-stability") & (df["integrator"] == "euler")]  # MuJoCo's and Pinocchio's
    assert (beyond["status"] == "diverged").all() and np.isfinite(beyond["diverged_at"]).all()
    spin = df[(df["case"] == "fast-spin") & (df["integrator"] == "rk4") & (df["engine"] != "reference")]
    assert (spin["status"] == "ok").all() and (spin["attitude_err"] < 1e-6).all()  # h |ω| = 0.1: RK4 to ~1e-8


@pytest.mark.slow
def test_extremes_suite_runs_clean(tmp_path):
    """Every extreme case on every engine and integrator of a default sweep (minutes: the 1e6-step horizon)."""
    df = run_sweep(load_suite(EXTREME_DIR), SweepOptions(["mujoco", "pinocchio", "reference"], tmp_path, jobs=2))
    _assert_clean(df)
    long = df[(df["case"] == "long-horizon") & (df["engine"] == "mujoco")]
    assert (long["steps"] == 1_000_000).all()
    assert not math.isnan(long[long["integrator"] == "rk4"]["attitude_err"].iloc[0])
