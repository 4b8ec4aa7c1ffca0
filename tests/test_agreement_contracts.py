"""agreement.csv and its headline on made-up trajectories (harness.analysis.agreement): which pairs are compared, in
which order, what state_diff is, and how summary and headline pick the largest. Found by the mutation check
(tools/mutants.py, docs/mutants.md)."""
from __future__ import annotations

import math

import numpy as np

from stereodyn.harness.analysis import agreement
from stereodyn.harness.engines.base import FLOAT32, FLOAT64

TIMES = np.linspace(0.0, 1.0, 11)


def _turned(angles) -> np.ndarray:
    """Unit quaternions (wxyz) turned by each angle (rad) about z."""
    angles = np.asarray(angles, dtype=float)
    return np.stack([np.cos(angles / 2), 0 * angles, 0 * angles, np.sin(angles / 2)], axis=1)


def _entry(engine, rank, angles=0.0, spin=1.0, precision=FLOAT64, horizon=None, dt=0.01, integrator="euler"):
    return {"case": "c", "method": "semi_implicit_euler", "dt": dt, "engine": engine, "formulation": "",
            "integrator": integrator, "precision": precision, "rank": (rank,), "horizon": horizon, "times": TIMES,
            "quat": _turned(np.broadcast_to(angles, TIMES.shape)),
            "omega": np.outer(np.broadcast_to(spin, TIMES.shape), [0.0, 0.0, 1.0])}


def test_state_diff_is_the_larger_of_the_attitude_and_omega_differences():
    # same attitude to 1e-9 rad, omega off by 1e-3: the two engines do not agree to round-off
    df = agreement.table([_entry("mujoco", 0), _entry("pinocchio", 1, angles=1e-9, spin=1.001)])
    row = df.iloc[0]
    assert math.isclose(row["state_diff"], 1e-3, rel_tol=1e-6)
    assert row["attitude_diff"] < 1e-8
    assert agreement.headline(df) == ["pinocchio euler against mujoco euler: 0.001 on c dt=0.01"]


def test_attitude_diff_end_is_the_last_samples_difference_and_attitude_diff_the_largest():
    angles = np.where(TIMES < 0.55, 1e-3, 1e-6)  # apart mid-run, together at the end
    row = agreement.table([_entry("mujoco", 0), _entry("pinocchio", 1, angles=angles)]).iloc[0]
    assert math.isclose(row["attitude_diff"], 1e-3, rel_tol=1e-6)
    assert math.isclose(row["attitude_diff_end"], 1e-6, rel_tol=1e-6)


def test_the_earlier_run_in_results_order_is_a_and_one_engines_runs_are_not_paired():
    df = agreement.table([_entry("pinocchio", 1, angles=1e-4), _entry("mujoco", 0), _entry("mujoco", 2, angles=1e-3,
                                                                                            integrator="implicit")])
    pairs = sorted(zip(df["engine_a"], df["integrator_a"], df["engine_b"], df["integrator_b"]))
    assert pairs == [("mujoco", "euler", "pinocchio", "euler"), ("pinocchio", "euler", "mujoco", "implicit")]


def test_a_run_whose_omega_diverged_is_not_compared():
    bad = _entry("pinocchio", 1)
    bad["omega"] = bad["omega"].copy()
    bad["omega"][5:] = np.nan
    assert agreement.table([_entry("mujoco", 0), bad]).empty


def test_differences_after_the_cases_horizon_do_not_count():
    angles = np.where(TIMES <= 0.5, 0.0, 1e-2)
    df = agreement.table([_entry("mujoco", 0, horizon=0.5), _entry("pinocchio", 1, angles=angles, horizon=0.5)])
    assert df.iloc[0]["state_diff"] < 1e-12


def test_summary_and_headline_name_the_largest_difference_and_where():
    entries = [_entry("mujoco", 0, dt=dt) for dt in (0.01, 0.02, 0.04)]
    entries += [_entry("pinocchio", 1, angles=a, dt=dt) for a, dt in ((1e-3, 0.01), (2e-3, 0.02), (9e-3, 0.04))]
    entries += [_entry("mjx", 2, angles=1e-5, precision=FLOAT32)]
    df = agreement.table(entries)
    summary = agreement.summary(df)
    pin = summary[summary["engine_b"] == "pinocchio"].iloc[0]
    assert math.isclose(pin["state_diff_max"], 9e-3, rel_tol=1e-6) and pin["at"] == "c dt=0.04"
    assert math.isclose(pin["state_diff_median"], 2e-3, rel_tol=1e-6)  # the median, not the mean (4e-3)
    # largest first within a method: 9e-3, then mjx against pinocchio (~1e-3), then against mujoco (1e-5)
    assert list(zip(summary["engine_a"], summary["engine_b"])) == [("mujoco", "pinocchio"), ("pinocchio", "mjx"),
                                                                   ("mujoco", "mjx")]
    lines = agreement.headline(df)
    assert lines[0] == "pinocchio euler against mujoco euler: 0.009 on c dt=0.04"
    assert lines[2] == "mjx euler float32 against mujoco euler: 1e-05 on c dt=0.01"
