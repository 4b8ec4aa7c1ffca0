"""Verdict rules on made-up tables (harness.analysis.verdicts): known deviations, superconvergent cases, what a failed
energy claim excludes, a truth that did not finish. Found by the mutation check (tools/mutants.py, docs/mutants.md)."""
from __future__ import annotations

import pandas as pd
import pytest

from stereodyn.harness.analysis import verdicts
from stereodyn.harness.engines.base import KnownDeviation

DEVIATION = KnownDeviation(integrator="rk4", quantity="order", expected=2.0, tolerance=0.3, reference="upstream #1")


@pytest.fixture
def deviation(monkeypatch):
    """mjx's rk4 declares order 4 and a known deviation to order 2 (as harness/engines/mjx.py does)."""
    monkeypatch.setattr(verdicts, "_known_deviation",
                        lambda engine, integrator: DEVIATION if (engine, integrator) == ("mjx", "rk4") else None)


def _order(orders: dict, notes: dict | None = None, engine="mjx") -> verdicts.Verdict:
    rows = [{"case": c, "engine": engine, "formulation": "", "integrator": "rk4", "order": o, "declared_order": 4.0,
             "note": (notes or {}).get(c, "")} for c, o in orders.items()]
    return verdicts.order_verdicts(pd.DataFrame(rows))[0]


def test_a_matching_known_deviation_is_known_and_passes_strict(deviation):
    verdict = _order({"a": 2.0, "b": 2.1, "c": 1.95})
    assert verdict.status == verdicts.KNOWN and "known deviation: order 2 (upstream #1)" in verdict.detail
    assert verdicts.strict_failures([verdict]) == []


def test_a_known_deviation_with_one_case_more_than_1_away_fails(deviation):
    # the median (2.05) matches the deviation, but case c fits 3.2: no longer the documented defect, and not the
    # declared order either
    verdict = _order({"a": 2.0, "b": 2.05, "c": 3.2})
    assert verdict.status == verdicts.FAIL and "stopped matching its known deviation" in verdict.detail
    assert verdicts.strict_failures([verdict]) == [verdict]


def test_a_deviation_that_stopped_matching_and_meets_the_declared_order_is_fixed_upstream(deviation):
    verdict = _order({"a": 4.0, "b": 4.05, "c": 3.95})
    assert verdict.status == verdicts.FIXED and verdicts.strict_failures([verdict]) == []


def test_a_superconvergent_case_is_no_defect_of_one_case():
    # rk4_naive-like: one special motion fits 2 orders steeper (noted so by the fit); the median is the declared order
    verdict = _order({"a": 4.0, "b": 4.05, "c": 6.0}, {"c": "superconvergent on this motion (fitted 6.00, declared 4)"},
                     engine="pinocchio")
    assert verdict.status == verdicts.PASS and "superconvergent on this motion: c" in verdict.detail


def test_a_failed_energy_claim_excludes_the_method_on_every_engine_and_an_order_only_its_family():
    failed = [verdicts.Verdict("energy_bounded", "pinocchio", "lie", "moser_veselov", status=verdicts.FAIL),
              verdicts.Verdict("order", "mujoco", "", "rk4", status=verdicts.FAIL),
              verdicts.Verdict("order", "reference", "quaternion", "euler", status=verdicts.PASS)]
    assert verdicts.failed_integrators(failed) == {("*", "*", "moser_veselov"), ("mujoco", "", "rk4")}


def test_a_truth_that_diverged_fails_its_case():
    row = {"case": "c", "engine": "reference", "formulation": "quaternion", "integrator": "taylor",
           "status": "diverged", "message": "blew up", "energy_drift": 1e-15, "oracle_err": 1e-14}
    found = verdicts.truth_verdicts(pd.DataFrame([row]), None)
    assert [(v.verdict, v.status) for v in found] == [("truth_invariants", verdicts.FAIL)]
    assert "truth did not finish: diverged (blew up)" in found[0].detail
