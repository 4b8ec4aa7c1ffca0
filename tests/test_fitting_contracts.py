"""Order fitting on made-up ladders (harness.analysis.fitting): which points count, when two points are too few, the
tolerance fit's counts. Found by the mutation check (tools/mutants.py, docs/mutants.md)."""
from __future__ import annotations

import math

import numpy as np
import pandas as pd
import pytest

from stereodyn.harness.analysis import fitting

EPS = float(np.finfo(float).eps)


def _points(dts, errors, t_end=1.0) -> pd.DataFrame:
    dts = np.asarray(dts, dtype=float)
    return pd.DataFrame({"dt": dts, "steps": np.round(t_end / dts), "status": "ok", "state_err": errors})


def test_the_order_is_the_slope_of_log_error_against_log_dt():
    assert fitting.order_slope([0.1, 0.01], [1e-2, 1e-4]) == pytest.approx(2.0)


def test_two_points_steeper_than_declared_plus_one_are_too_few_and_three_are_superconvergent():
    two = fitting.fit(_points([0.02, 0.01], [1.6e-5, 1e-6]), declared=2.0)
    assert math.isnan(two["order"]) and "too few to tell superconvergence" in two["note"]
    three = fitting.fit(_points([0.02, 0.01, 0.005], [1.6e-5, 1e-6, 6.25e-8]), declared=2.0)
    assert three["order"] == pytest.approx(4.0) and fitting.SUPERCONVERGENT in three["note"]
    agreeing = fitting.fit(_points([0.02, 0.01], [4e-6, 1e-6]), declared=2.0)
    assert agreeing["order"] == pytest.approx(2.0) and agreeing["points"] == 2


def test_an_error_above_the_asymptotic_range_is_left_out():
    # 0.1 rad is above ASYMPTOTIC_MAX (3e-2): one asymptotic point is left, no order
    result = fitting.fit(_points([0.1, 0.05], [0.1, 4e-3]), declared=5.0)
    assert math.isnan(result["order"]) and "1 above 0.03" in result["note"]


def test_an_error_within_30_eps_per_step_is_round_off_and_left_out():
    # the finest point: 20 eps x 400 steps, inside the round-off margin; the other two fit the declared 4
    result = fitting.fit(_points([1e-2, 5e-3, 2.5e-3], [1e-8, 6.25e-10, 20 * EPS * 400]), declared=4.0)
    assert result["order"] == pytest.approx(4.0) and result["points"] == 2


def test_a_coarsest_point_whose_local_slope_is_off_the_next_pairs_leaves_the_fit():
    # Drake's rpy_ball runge_kutta3 on kovalevskaya (fitting.PRE_ASYMPTOTIC_GAP): local slopes 1.06, then 2.9, 3.0
    dts = np.array([1e-2, 3e-3, 1e-3, 3e-4])
    logs = np.cumsum([0.0, 1.06 * math.log(dts[1] / dts[0]), 2.9 * math.log(dts[2] / dts[1]),
                      3.0 * math.log(dts[3] / dts[2])])
    result = fitting.fit(_points(dts, 1e-3 * np.exp(logs)), declared=3.0)
    assert "pre-asymptotic, left out of the fit: dt = 0.01" in result["note"]
    assert abs(result["order"] - 2.95) < 0.05


def test_the_state_error_is_the_largest_of_attitude_omega_and_casimir():
    df = fitting.with_state_err(pd.DataFrame({"attitude_err": [1e-6, 1e-3], "omega_err": [1e-4, 1e-5],
                                              "casimir_drift": [1e-9, 1e-2]}))
    assert df["state_err"].tolist() == [1e-4, 1e-2]


def test_a_family_with_two_dts_gets_an_order_from_the_sweep():
    rows = [{"case": "c", "engine": "mujoco", "formulation": "", "integrator": "rk4", "precision": "float64", "dt": dt,
             "steps": round(1 / dt), "status": "ok", "attitude_err": 2e2 * dt ** 4, "omega_err": 1e2 * dt ** 4,
             "casimir_drift": 0.0} for dt in (0.02, 0.01)]
    found = fitting.sweep_orders(pd.DataFrame(rows), set())
    assert len(found) == 1 and found[0]["order"] == pytest.approx(4.0)


def test_the_tolerance_fit_counts_the_points_below_their_tolerance_above_round_off():
    points = pd.DataFrame({"tolerance": [1e-4, 1e-6, 1e-8, 1e-14], "steps": [100, 300, 900, 5000], "status": "ok",
                           "state_err": [5e-4, 3e-6, 4e-8, 1e-14]})
    fit = fitting.tolerance_fit(points)
    # the last point (1e-14 < 30 eps x 5000 steps) is at round-off: not fitted
    assert fit["points"] == 3 and fit["tol_min"] == 1e-8 and fit["below_tol"] == 0
    assert fit["max_err_over_tol"] == pytest.approx(5.0) and fit["slope"] == pytest.approx(1.0, abs=0.05)


@pytest.mark.filterwarnings("error::RuntimeWarning")  # nor a slope of 0/0
def test_two_points_of_one_dt_have_no_slope_and_raise_nothing():
    """A ladder's point and the sweep's at one dt (--dt-ladder --ladder-max-steps 100 over 1 s gives 0.01, a sweep dt
    too): regimes raised ZeroDivisionError, and advice rows read "worker failed: ZeroDivisionError"."""
    points = pd.DataFrame({"dt": [0.05, 0.01, 0.01, 0.003], "steps": [20, 100, 100, 333], "status": ["ok"] * 4,
                           "state_err": [1.6e-7, 2.5e-10, 2.5e-10, 2.0e-12]})
    marked, floor_dt, _ = fitting.regimes(points)
    assert len(marked) == 4 and (marked["regime"] == fitting.ASYMPTOTIC).sum() >= 3 and math.isnan(floor_dt)
