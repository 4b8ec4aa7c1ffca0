"""The state error's rule, max(attitude_err, omega_err, casimir_drift) over the finite ones and NaN without an attitude
error, has one home (harness.scenes.metrics.state_err): rows, tables, the ladders, fitting and harness.testing."""
import math

import numpy as np
import pandas as pd

from stereodyn.harness import testing
from stereodyn.harness.analysis import fitting
from stereodyn.harness.pipeline import dt_ladders, tolerance_ladders
from stereodyn.harness.scenes import metrics, rigid_body

ROWS = [{"attitude_err": 1e-6, "omega_err": 3e-6, "casimir_drift": 2e-6},
        {"attitude_err": 4e-6, "omega_err": math.nan, "casimir_drift": 1e-7},
        {"attitude_err": 1e-9, "omega_err": 2e-9, "casimir_drift": math.inf},
        {"attitude_err": math.nan, "omega_err": 1.0, "casimir_drift": 1.0},
        {"attitude_err": 1e-8, "omega_err": 2e-8, "casimir_drift": 5e-8}]


def test_the_rule_on_rows_and_tables():
    expected = [3e-6, 4e-6, 2e-9, math.nan, 5e-8]
    assert np.array_equal([metrics.state_err(r) for r in ROWS], expected, equal_nan=True)
    table = pd.DataFrame(ROWS, index=[5, 6, 7, 8, 9])
    assert np.array_equal(metrics.state_err(table).to_numpy(), expected, equal_nan=True)
    assert list(metrics.state_err(table).index) == [5, 6, 7, 8, 9]
    assert np.array_equal(fitting.with_state_err(table)["state_err"].to_numpy(), expected, equal_nan=True)
    assert math.isnan(metrics.state_err({"omega_err": 1.0}))  # no attitude error: none


def test_every_user_takes_the_one_rule():
    for module in (rigid_body, fitting, dt_ladders, tolerance_ladders):
        assert module.state_err is metrics.state_err, module.__name__
    assert "metrics.state_err" in open(testing.__file__, encoding="utf-8").read()
