"""The regression gate's rules on made-up tables (harness.analysis.gate): which rows are compared, how a row is
matched, what a baseline may hold. Found by the mutation check (tools/mutants.py, docs/mutants.md)."""
from __future__ import annotations

import math

import pandas as pd
import pytest

from stereodyn.harness.analysis import gate


def _row(dt=0.01, status="ok", **metrics) -> dict:
    return {"case": "c", "engine": "mujoco", "formulation": "", "integrator": "rk4", "precision": "float64", "dt": dt,
            "status": status, **metrics}


def test_the_metrics_of_a_run_that_did_not_complete_are_not_compared():
    # diverged in the baseline (its drift measured before the blow-up), ok now with a larger drift: an improvement
    findings = gate.compare(pd.DataFrame([_row(status="ok", energy_drift=1.0)]),
                            [_row(status="diverged", energy_drift=1e-3)])
    assert findings == []


def test_a_row_is_matched_by_its_dt_to_ten_digits():
    findings = gate.compare(pd.DataFrame([_row(0.01, energy_drift=1e-6)]),
                            [_row(0.01, energy_drift=1e-6), _row(0.010001, energy_drift=1e-6)])
    assert [(f.key[5], f.what) for f in findings] == [("0.010001", "missing")]


def test_new_rows_counts_the_rows_the_baseline_lacks():
    current = pd.DataFrame([_row(0.01), _row(0.005), _row(0.0025)])
    assert gate.new_rows(current, [_row(0.01)]) == 2


def test_the_date_and_commit_are_no_environment_change():
    before = {"date": "2026-11-01", "git commit": "abc", "numpy": "2.1"}
    after = {"date": "2026-11-26", "git commit": "def", "numpy": "2.2"}
    assert gate.environment_changes(before, after) == ["numpy 2.1 -> 2.2"]


def test_a_baseline_with_an_infinite_metric_is_refused(tmp_path):
    path = tmp_path / "baseline.json"
    path.write_text('{"format": "stereodyn-baseline/1", "environment": {}, "rows": [{"case": "c", "engine": "e", '
                    '"formulation": "", "integrator": "i", "dt": 0.01, "status": "ok", "energy_drift": Infinity}]}')
    with pytest.raises(gate.GateError, match=r"rows\[0\]\.energy_drift: must be finite"):
        gate.read_baseline_file(path)


def test_an_order_that_became_nan_fails_and_one_within_the_drop_passes():
    old = [{"case": "c", "engine": "mujoco", "formulation": "", "integrator": "rk4", "precision": "float64",
            "fitted": 4.0, "declared": 4.0}]

    def now(order):
        return pd.DataFrame([{"case": "c", "engine": "mujoco", "formulation": "", "integrator": "rk4",
                              "precision": "float64", "order": order, "declared_order": 4.0}])
    nan = gate.compare_orders(now(math.nan), old)
    assert [(f.what, f.current) for f in nan] == [("order", "NaN")]
    assert gate.compare_orders(now(3.6), old) == []
    assert [f.current for f in gate.compare_orders(now(3.4), old)] == ["3.40"]
