"""The invariant registry (reference.integrals.INTEGRALS): each drift column declared once, and every table, page and
figure reading it: every case's drift table shows every drift column defined for that case (issue 20 point 3, issue
21 item 3: the self-excited case's table lacked its invariant)."""
import re

import numpy as np
import pandas as pd
import pytest

from stereodyn.harness import cli
from stereodyn.harness.scenes import metrics
from stereodyn.harness.scenes.cases import load_suite
from stereodyn.harness.report import figures, html, markdown
from stereodyn.harness.run.results import COLUMNS
from stereodyn.harness.trajectory import Trajectory
from stereodyn.reference.integrals import DRIFT_COLUMNS, INTEGRALS

RIGID_BODY_CASES = [case for case in load_suite() if getattr(case, "body", None) is not None]


def _rows(case) -> pd.DataFrame:
    """Two ok rows of the case as the sweep writes them: the drifts of a short recorded motion (the initial state held
    for three samples, so every integral the case has is a finite number, 0), NaN for the others."""
    traj = Trajectory(times=np.array([0.0, 0.5, 1.0]), quat=np.tile(case.quat0, (3, 1)),
                      omega=np.tile(case.omega0, (3, 1)))
    drifts = metrics.drifts(case, traj, metrics.applicable_integrals(case))
    rows = [{column: np.nan for column in COLUMNS} | drifts
            | {"case": case.name, "engine": engine, "formulation": "", "integrator": "rk4", "dt": 0.01, "status": "ok",
               "attitude_err": 1e-6, "omega_err": 1e-6, "us_per_step": 1.0, "wall_s": 0.1}
            for engine in ("mujoco", "pinocchio")]
    return pd.DataFrame(rows, columns=list(COLUMNS))


def _markdown_header(lines: list[str]) -> list[str]:
    header = next(line for line in lines if line.startswith("| "))
    return [cell.strip() for cell in header.strip("|").split("|")]


def test_the_registry_is_the_one_list_of_drift_columns():
    assert DRIFT_COLUMNS == tuple(f"{name}_drift" for name in INTEGRALS)
    assert metrics.DRIFT_COLUMNS == DRIFT_COLUMNS
    assert [c for c in COLUMNS if c in DRIFT_COLUMNS] == list(DRIFT_COLUMNS)  # results.csv: each, in registry order
    for name, integral in INTEGRALS.items():
        assert integral.name == name and integral.column == f"{name}_drift"
        assert integral.short and integral.definition, name
        assert integral.column in markdown.TERMINAL_COLUMNS and markdown.SHORT[integral.column] == integral.short
        assert f"{name}: {integral.definition}" in " ".join(markdown.DEFINITIONS.split())
        assert html._graded(integral.short) == integral.graded
        assert (name in figures.QUANTITIES) == (integral.label is not None)


def test_the_self_excited_case_has_its_invariant():
    (case,) = [c for c in RIGID_BODY_CASES if c.name == "self-excited-conic"]
    assert "self_excited" in metrics.applicable_integrals(case)


@pytest.mark.parametrize("case", RIGID_BODY_CASES, ids=lambda case: case.name)
def test_every_case_table_shows_every_drift_column_defined_for_it(case):
    """report.md's drift table and the terminal's (--verbose) show, for each integral the case has, its column."""
    expected = [INTEGRALS[name].short for name in metrics.applicable_integrals(case)]
    assert expected, case.name  # the energy at least
    group = _rows(case)
    shown = _markdown_header(markdown.case_lines(case.name, group))
    assert [h for h in shown if h in expected] == expected, (case.name, shown)
    terminal = markdown.drift_table_text(group).splitlines()[1].split()
    assert [h for h in terminal if h in expected] == expected, (case.name, terminal)
    # and no column of an integral the case does not have
    others = {i.short for n, i in INTEGRALS.items() if n not in metrics.applicable_integrals(case)}
    assert not others & set(shown), case.name


# slow (issue 28: the default suite within 8 min on 2 idle cores): 20-80 s at load ~6; `pytest -m slow` runs it
@pytest.mark.slow
def test_a_run_of_the_self_excited_case_shows_its_invariant_in_report_md(tmp_path):
    """Through the whole path: sweep, results.csv, report.md, report.html (graded cell)."""
    assert cli.main(["run", "self-excited-conic", "--engines", "reference", "--integrators", "rk4", "--t-end", "0.5",
                     "--dt", "0.05", "--no-certify", "--jobs", "1", "--quiet", "--out", str(tmp_path)]) == 0
    results = pd.read_csv(tmp_path / "results.csv", dtype={"formulation": str}, keep_default_na=False)
    rk4 = results[(results["integrator"] == "rk4") & (results["formulation"] == "quaternion")].iloc[0]
    assert 0 < float(rk4["self_excited_drift"]) < 1e-3  # rk4 at dt 0.05 over 0.5 s: a small, nonzero drift
    text = (tmp_path / "report.md").read_text()
    cases = text[text.index("## Cases"):]  # (the case is also in "Formulations side by side")
    section = cases[cases.index("### self-excited-conic"):]
    lines = section.splitlines()
    header = _markdown_header(lines)
    assert "self_excited" in header
    column = header.index("self_excited")
    row = next(line for line in lines if line.startswith("| reference | quaternion | rk4 |"))
    cells = [cell.strip() for cell in row.strip("|").split("|")]
    assert cells[column] == f"{float(rk4['self_excited_drift']):.2e}"
    page = (tmp_path / "report.html").read_text()
    assert re.search(r"<th[^>]*>self_excited</th>", page)
