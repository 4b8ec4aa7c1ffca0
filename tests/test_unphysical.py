"""[body] physical = false (issue 21 item 7): principal moments that break the triangle inequality, Euler's equations
only. The case loads, the truth and the reference formulations run it, engines that build a physical body skip it
naming the rule, and Pinocchio (which does not check the inequality) runs it."""
from __future__ import annotations

import math

import numpy as np
import pandas as pd
import pytest

from stereodyn.harness import cli
from stereodyn.harness.scenes.cases import CaseError, load_case, unphysical_inertia
from stereodyn.harness.engines import UnavailableEngine, get_engine

# Hairer–Lubich–Wanner's free rigid body (Geometric Numerical Integration, §IV.1 and §VII.5): I = (2, 1, 2/3),
# angular momentum y0 = (cos 1.1, 0, sin 1.1), so omega0 = y0 / I. 1 + 2/3 < 2: no mass distribution has it.
HLW = f"""\
name = "hlw"
tags = ["free", "integrable"]

[body]
mass = 1.0
com = [0.0, 0.0, 0.0]
principal_moments = [2.0, 1.0, {2 / 3!r}]
physical = false

[initial]
attitude = {{ quaternion = [1.0, 0.0, 0.0, 0.0] }}
omega = [{math.cos(1.1) / 2!r}, 0.0, {math.sin(1.1) * 1.5!r}]

[expect]
oracle = "euler_poinsot"

[run]
t_end = 2.0
dt = [1e-2]
samples = 101
"""


def write(tmp_path, text, name="hlw.toml"):
    path = tmp_path / name
    path.write_text(text, encoding="utf-8")
    return path


def test_physical_false_lifts_only_the_triangle_inequality(tmp_path):
    case = load_case(write(tmp_path, HLW))
    assert case.physical is False and np.allclose(np.diag(case.inertia), [2.0, 1.0, 2 / 3])
    assert "triangle inequality" in unphysical_inertia(case) and "about O" in unphysical_inertia(case)
    # without the key the same body is refused, and the message says how to allow it
    with pytest.raises(CaseError) as info:
        load_case(write(tmp_path, HLW.replace("physical = false\n", ""), "strict.toml"))
    assert info.value.key == "body.principal_moments" and "physical = false" in info.value.rule
    # the other rules still hold: a matrix that is not positive definite, a value that is not a boolean
    not_definite = HLW.replace(f"principal_moments = [2.0, 1.0, {2 / 3!r}]",
                               "inertia = [[1.0, 1.5, 0.0], [1.5, 1.0, 0.0], [0.0, 0.0, 1.0]]")
    with pytest.raises(CaseError, match="positive definite"):
        load_case(write(tmp_path, not_definite, "indefinite.toml"))
    with pytest.raises(CaseError) as info:
        load_case(write(tmp_path, HLW.replace("physical = false", 'physical = "no"'), "word.toml"))
    assert info.value.key == "body.physical" and "true or false" in info.value.rule
    # a physical body declared physical = false is nothing unusual: no engine has a reason to skip it
    physical = HLW.replace(f"{2 / 3!r}]", "1.5]")
    assert unphysical_inertia(load_case(write(tmp_path, physical, "physical.toml"))) is None


@pytest.mark.slow  # since 2026-12-02, ~7 s; by default this file's refusals (the default suite's 8 minutes)
def test_truth_and_reference_run_it_mujoco_skips_it_naming_the_rule(tmp_path):
    out = tmp_path / "out"
    drake = not isinstance(get_engine("drake"), UnavailableEngine)
    engines = "mujoco,pinocchio,reference" + (",drake" if drake else "")
    # Drake offers neither rk4 nor taylor, and an engine that offers none of the named integrators gets no rows
    # (DESIGN §1, the plan): name one of Drake's too, so that its refusal of the body is seen
    integrators = "rk4,taylor" + (",runge_kutta3" if drake else "")
    assert cli.main(["run", "--case-file", str(write(tmp_path, HLW)), "--engines", engines, "--integrators",
                     integrators, "--no-ladder", "--no-certify", "--out", str(out), "--quiet"]) == 0
    df = pd.read_csv(out / "results.csv")
    reference = df[df.engine == "reference"]
    assert len(reference) >= 5 and (reference.status == "ok").all(), reference[["integrator", "status", "message"]]
    truth = reference[(reference.formulation == "quaternion") & (reference.integrator == "taylor")].iloc[0]
    # the truth against Jacobi's elliptic-function solution (reference.exact): round-off, as for physical bodies
    # (measured 2.7e-15 rad here; the suite's bound for the truth is verdicts.TRUTH_ORACLE_MAX = 1e-10)
    assert truth.oracle_err < 1e-12 and truth.energy_drift < 1e-13
    # rk4 at dt = 1e-2 over 2 s: measured 1.1e-10 (Pinocchio) and 2.9e-10 (reference quaternion) at t_end = 10
    rk4 = df[(df.integrator == "rk4") & (df.status == "ok")]
    assert set(rk4.engine) == {"pinocchio", "reference"} and (rk4.attitude_err < 1e-8).all()
    for engine in ("mujoco", "drake"):
        rows = df[df.engine == engine]
        if engine == "drake" and "drake" not in engines:
            continue
        assert len(rows) and (rows.status == "skipped").all(), rows[["status", "message"]]
        assert rows.message.str.contains("physical = false", regex=False).all()
        assert rows.message.str.contains("triangle inequality A_i + A_j >= A_k", regex=False).all()


def test_mjcf_export_refuses_it(tmp_path, capsys):
    assert cli.main(["export", str(write(tmp_path, HLW)), "--format", "mjcf"]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "triangle inequality" in err
