"""The suite's cases with exact solutions (issue 4) through the runner, truth only: oracle_err within each horizon, the
special integrals only on their cases, the truth's measurements against theory, and bad oracles rejected."""
import math
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from stereodyn.harness import cli
from stereodyn.harness.scenes.cases import load_suite
from stereodyn.harness.scenes.checks import read_checks
from stereodyn.harness.run.results import read_results

REPO = Path(__file__).resolve().parent.parent
# The issue's bound on oracle_err, the truth against the exact solution, within each case's horizon.
ORACLE_BOUND = 1e-11
WITHOUT_ORACLE = ("goryachev-chaplygin", "hess")
# The Hess invariant relation K·k = 0 holds on these three states: the Hess–Grioli precessions and Mlodzejowski's
# rotations (their cos b2 = 0 case) are motions on the Hess manifold (FORMULARY G11).
ON_HESS_MANIFOLD = {"hess", "hess-grioli", "mlodzejowski"}
FREE = ("euler-poinsot-major", "euler-poinsot-minor", "euler-poinsot-symmetric", "free-asymmetric")
EXPECTED_CHECKS = {
    **{case: {"period", "montgomery_phase"} for case in FREE},
    "dzhanibekov": {"period", "montgomery_phase", "lyapunov_exponent"},
    "lagrange-precession": {"precession_rate"},
    "sleeping-top-stable": {"tilt_growth_rate"},
    "sleeping-top-unstable": {"tilt_growth_rate"},
    "grioli-precession": {"omega_squared", "precession_axis_drift"},
}


def _names() -> list[str]:
    return [case.name for case in load_suite() if case.oracle or case.name in WITHOUT_ORACLE]


@pytest.fixture(scope="module")
def truth_sweep(tmp_path_factory):
    """Every oracle case, the Goryachev–Chaplygin and Hess cases and free-asymmetric on the reference engine's
    heyoka runs (the truth and the other formulations)."""
    out = tmp_path_factory.mktemp("oracles")
    assert cli.main(["run", *_names(), "free-asymmetric", "--engines", "reference", "--integrators", "taylor",
                     "--jobs", "1", "--quiet", "--out", str(out)]) == 0
    df = read_results(out / "results.csv")
    truth = df[(df.formulation == "quaternion") & (df.integrator == "taylor")].set_index("case")
    checks = read_checks(out / "checks.csv")
    return out, df, truth, checks[(checks.formulation == "quaternion") & (checks.integrator == "taylor")]


def test_the_suite_covers_the_issue():
    suite = {case.name: case for case in load_suite()}
    assert {case.oracle for case in suite.values()} - {None} == {
        "euler_poinsot", "euler_poinsot_separatrix", "lagrange_precession", "staude_rotation", "grioli_precession",
        "hess_grioli", "mlodzejowski", "self_excited_spinup", "self_excited_uniform"}
    for case in suite.values():
        if "unstable" in case.tags and case.oracle:
            assert case.horizon is not None, case.name  # FORMULARY §6: round-off grows exponentially
    assert suite["dzhanibekov"].horizon < suite["dzhanibekov"].t_end


def test_every_oracle_case_has_oracle_err_within_the_bound(truth_sweep):
    """Measured: <= 7.3e-14 rad (dzhanibekov up to its horizon, the separatrix 3.8e-14)."""
    _, df, truth, _ = truth_sweep
    for name in _names():
        if name in WITHOUT_ORACLE:
            assert math.isnan(truth.loc[name, "oracle_err"])
        else:
            assert truth.loc[name, "oracle_err"] <= ORACLE_BOUND, name
    assert df[df.case == "free-asymmetric"].oracle_err.isna().all()
    ran = df[~df.case.isin([*WITHOUT_ORACLE, "free-asymmetric"]) & (df.status == "ok")]
    assert np.isfinite(ran.oracle_err).all()
    # every formulation models every torque (issue 13): a skipped row would name the feature it lacks
    assert df[df.status == "skipped"].message.str.contains("[body_torque]", regex=False).all()


def test_special_integrals_only_on_their_cases(truth_sweep):
    _, df, truth, _ = truth_sweep
    assert (np.isfinite(df.chaplygin_drift) == (df.case == "goryachev-chaplygin")).all()
    assert (np.isfinite(df.hess_drift) == df.case.isin(ON_HESS_MANIFOLD)).all()
    # Measured 5.6e-15 (Goryachev–Chaplygin is neutrally stable) and 3.6e-14: the Hess manifold is transversally
    # unstable, |K·k| grows like e^(0.54 t) from round-off (FORMULARY G7), so t_end = 20 keeps it near 1e-13.
    assert truth.loc["goryachev-chaplygin", "chaplygin_drift"] <= 1e-13
    assert truth.loc["hess", "hess_drift"] <= 1e-12


def test_checks_rows_have_the_expected_quantities(truth_sweep):
    out, _, _, checks = truth_sweep
    assert tuple(read_checks(out / "checks.csv").columns) == (
        "case", "engine", "formulation", "integrator", "precision", "dt", "quantity", "theory", "measured", "error")
    found = {case: set(group.quantity) for case, group in checks.groupby("case")}
    assert found == EXPECTED_CHECKS
    assert np.isfinite(checks[["theory", "measured", "error"]].to_numpy()).all()


def _truth_check(checks, case, quantity):
    row = checks[(checks.case == case) & (checks.quantity == quantity)]
    assert len(row) == 1
    return row.iloc[0]


def test_the_truth_agrees_with_theory(truth_sweep):
    _, _, _, checks = truth_sweep
    for case in FREE:
        # Zeros of ω on a degree-7 local interpolant, averaged over the run: measured <= 5e-16 relative.
        assert _truth_check(checks, case, "period").error <= 1e-10
        # The issue's bound, on three bodies and both families; measured <= 7.4e-15 rad.
        assert _truth_check(checks, case, "montgomery_phase").error <= 1e-10
    # The flip's period is measured across the second flip (t ~ 13.4), past the horizon, where the truth's round-off
    # has grown to ~1e-11 rad: measured 9e-13 relative and 5e-11 rad.
    assert _truth_check(checks, "dzhanibekov", "period").error <= 1e-11
    assert _truth_check(checks, "dzhanibekov", "montgomery_phase").error <= 1e-9
    # The issue's 2%; measured 4.6e-5 (the O(angle²) of the linearisation about the run, not about e2).
    assert _truth_check(checks, "dzhanibekov", "lyapunov_exponent").error <= 0.02
    assert _truth_check(checks, "dzhanibekov", "lyapunov_exponent").error <= 1e-3
    # Regular precession and the sleeping top: exact motions, errors at round-off (measured <= 1.4e-13).
    assert _truth_check(checks, "lagrange-precession", "precession_rate").error <= 1e-10
    unstable = _truth_check(checks, "sleeping-top-unstable", "tilt_growth_rate")
    assert unstable.theory > 0.1 and unstable.error <= 1e-8
    stable = _truth_check(checks, "sleeping-top-stable", "tilt_growth_rate")
    assert stable.theory == 0.0 and abs(stable.measured) <= 1e-8
    # The issue's Grioli acceptance (1e-12 over t = 100 for the reference; here t = 20): measured 1.5e-15, 4.3e-15.
    assert _truth_check(checks, "grioli-precession", "omega_squared").error <= 1e-12
    assert _truth_check(checks, "grioli-precession", "precession_axis_drift").measured <= 1e-12


def test_the_report_summarises_checks_and_oracles(truth_sweep):
    out, _, _, _ = truth_sweep
    section = (out / "report.md").read_text().split("## Oracle and theory checks")[1].split("\n## ")[0]
    for quantity in ("period", "montgomery_phase", "lyapunov_exponent", "tilt_growth_rate", "omega_squared"):
        assert f"| {quantity} |" in section
    assert "| truth oracle_err |" in section and "| separatrix |" in section


def test_a_bad_oracle_exits_2_naming_expect_oracle(tmp_path, capsys):
    text = (REPO / "cases" / "euler-poinsot-major.toml").read_text().replace(
        'oracle = "euler_poinsot"', 'oracle = "staude_rotation"')
    bad = tmp_path / "bad.toml"
    bad.write_text(text)
    assert cli.main(["run", "--case-file", str(bad), "--quiet", "--out", str(tmp_path / "out")]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and f"{bad}: expect.oracle: " in err and "no weight moment" in err


def test_the_committed_cases_are_the_tools_output():
    """cases/*.toml with oracles are written by tools/make_oracle_cases.py; rerunning it must change nothing."""
    done = subprocess.run([sys.executable, str(REPO / "tools" / "make_oracle_cases.py"), "--check"],
                          capture_output=True, text=True, cwd=REPO)
    assert done.returncode == 0, done.stderr


def test_the_tools_check_allows_a_few_ulps_and_nothing_else():
    """--check compares numbers within a few ulps (CPUs differ in the last bit of a computed rate) and everything else
    exactly: one more ulp passes; 100 ulps, a renamed key, an edited comment or a float turned int do not."""
    sys.path.insert(0, str(REPO / "tools"))
    try:
        from make_oracle_cases import CHECK_ULPS, same_case_text
    finally:
        sys.path.remove(str(REPO / "tools"))
    value = -0.04793729606362009
    text = f"name = \"x\"  # a 1e-11 horizon\n[state]\nomega = [{value!r}, 0.1877639148503953, 15.0]\n"
    assert same_case_text(text, text)
    assert same_case_text(text, text.replace(repr(value), repr(value - math.ulp(value))))
    assert not same_case_text(text, text.replace(repr(value), repr(value - 100 * math.ulp(value))))
    assert not same_case_text(text, text.replace(repr(value), repr(value + (CHECK_ULPS + 1) * math.ulp(value))))
    assert not same_case_text(text, text.replace("omega =", "omegas ="))
    assert not same_case_text(text, text.replace("1e-11 horizon", "1e-10 horizon"))
    assert not same_case_text(text, text.replace("15.0", "15"))
