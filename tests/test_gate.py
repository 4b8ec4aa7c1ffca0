"""The regression gate: baseline, check, the tolerance model, and the committed quick-suite baseline."""
import json
from pathlib import Path

import pandas as pd
import pytest

from stereodyn.harness import cli, gate, plan
from stereodyn.harness.cases import find_case, with_overrides
from stereodyn.harness.engines import engine_names

SWEEP = ["lagrange-top", "heavy-asymmetric", "--t-end", "0.5", "--dt", "1e-2", "--jobs", "1", "--quiet"]
REPO = Path(__file__).resolve().parents[1]
# The quick suite of .ci/run and its committed baseline.
QUICK_CASES = ("free-asymmetric", "lagrange-top", "kovalevskaya", "heavy-asymmetric")
QUICK_T_END, QUICK_DT = "2", "1e-2,3e-3"  # as written in .ci/run
QUICK_BASELINE = REPO / "reports" / "baselines" / "quick.json"


@pytest.fixture(scope="module")
def baseline(tmp_path_factory):
    out = tmp_path_factory.mktemp("base")
    assert cli.main(["run", *SWEEP, "--out", str(out)]) == 0
    path = out / "baseline.json"
    assert cli.main(["baseline", str(out), "--out", str(path)]) == 0
    return out, path


def edited(source: Path, target: Path, edit) -> Path:
    """A copy of a results folder whose results.csv went through edit(df) -> df."""
    target.mkdir()
    df = pd.read_csv(source / "results.csv", keep_default_na=True)
    edit(df).to_csv(target / "results.csv", index=False)
    return target


def check(directory: Path, baseline: Path, *options: str) -> int:
    return cli.main(["check", str(directory), "--baseline", str(baseline), *options])


def test_an_unchanged_rerun_passes(baseline, tmp_path, capsys):
    _, path = baseline
    assert cli.main(["run", *SWEEP, "--out", str(tmp_path)]) == 0
    capsys.readouterr()
    assert check(tmp_path, path) == 0
    assert "check passed" in capsys.readouterr().out


def _row(df: pd.DataFrame, engine: str, integrator: str, case: str = "lagrange-top") -> int:
    return df.index[(df.case == case) & (df.engine == engine) & (df.integrator == integrator)][0]


def test_a_drift_ten_times_worse_fails_listing_that_row(baseline, tmp_path, capsys):
    out, path = baseline

    def worse(df):
        df.loc[_row(df, "pinocchio", "rk4"), "energy_drift"] *= 10
        return df

    assert check(edited(out, tmp_path / "worse", worse), path) == 1
    printed = capsys.readouterr().out
    offending = [line for line in printed.splitlines() if "energy_drift" in line]
    assert len(offending) == 1
    assert offending[0].split()[:4] == ["lagrange-top", "pinocchio", "rk4", "0.01"]
    assert "check failed: 1 of" in printed


@pytest.mark.parametrize("status", ["diverged", "failed", "skipped"])
def test_a_status_that_got_worse_fails(baseline, tmp_path, capsys, status):
    out, path = baseline

    def broken(df):
        df.loc[_row(df, "mujoco", "euler"), "status"] = status
        return df

    assert check(edited(out, tmp_path / "bad", broken), path) == 1
    line = next(line for line in capsys.readouterr().out.splitlines() if " status " in f" {line} ")
    assert "mujoco" in line and "euler" in line and status in line


def test_a_missing_row_fails_and_a_new_row_does_not(baseline, tmp_path, capsys):
    out, path = baseline
    assert check(edited(out, tmp_path / "less", lambda df: df.drop(index=_row(df, "mujoco", "rk4"))), path) == 1
    assert "missing row" in capsys.readouterr().out

    def more(df):
        extra = df.loc[[_row(df, "mujoco", "rk4")]].assign(dt=5e-3)
        return pd.concat([df, extra], ignore_index=True)

    assert check(edited(out, tmp_path / "more", more), path) == 0
    assert "1 rows not in the baseline" in capsys.readouterr().out


def test_timing_fails_only_when_asked(baseline, tmp_path):
    out, path = baseline
    slow = edited(out, tmp_path / "slow", lambda df: df.assign(us_per_step=df.us_per_step * 10))
    assert check(slow, path) == 0
    assert check(slow, path, "--time-factor", "3") == 1
    assert check(slow, path, "--time-factor", "20") == 0


def test_the_floor_absorbs_round_off_and_the_factor_is_configurable(baseline, tmp_path):
    out, path = baseline

    def tenfold(column, engine, integrator):
        def edit(df):
            df.loc[_row(df, engine, integrator), column] *= 10
            return df
        return edit

    # The truth's energy drift is ~1e-16: ten times that is still round-off, under the 1e-12 floor.
    assert check(edited(out, tmp_path / "roundoff", tenfold("energy_drift", "reference", "taylor")), path) == 0
    worse = edited(out, tmp_path / "worse", tenfold("attitude_err", "mujoco", "rk4"))
    assert check(worse, path) == 1
    assert check(worse, path, "--factor", "20") == 0
    tolerances = tmp_path / "tolerances.toml"
    tolerances.write_text("[default]\nfactor = 2.0\nfloor = 1e-12\n\n[metric.attitude_err]\nfactor = 20.0\n")
    assert check(worse, path, "--tolerances", str(tolerances)) == 0
    tolerances.write_text("[metric.energy_drift]\nfactor = 20.0\n")
    assert check(worse, path, "--tolerances", str(tolerances)) == 1


@pytest.mark.parametrize("text, expected", [
    ("[default]\nfactor = 0.5\n", "default.factor"),
    ("[metric.wall_s]\nfactor = 3.0\n", "metric.wall_s"),
    ("[limits]\n", "limits: unknown key"),
    ("[default\n", "invalid TOML"),
])
def test_a_bad_tolerance_file_exits_2(baseline, tmp_path, capsys, text, expected):
    out, path = baseline
    tolerances = tmp_path / "t.toml"
    tolerances.write_text(text)
    assert check(out, path, "--tolerances", str(tolerances)) == 2
    err = capsys.readouterr().err
    assert expected in err and str(tolerances) in err and err.count("\n") == 1


def test_bad_input_exits_2(baseline, tmp_path, capsys):
    out, path = baseline
    assert check(tmp_path, path) == 2  # no results.csv
    (tmp_path / "not-a-baseline.json").write_text("[1, 2]")
    assert check(out, tmp_path / "not-a-baseline.json") == 2
    assert check(out, tmp_path / "absent.json") == 2
    assert check(out, path, "--factor", "0.5") == 2
    assert "not a baseline file" in capsys.readouterr().err


def test_the_baseline_is_readable_json_with_one_row_per_line(baseline):
    out, path = baseline
    text = path.read_text()
    data = json.loads(text)
    assert data["format"] == gate.BASELINE_FORMAT and data["environment"]["mujoco"]
    rows = pd.read_csv(out / "results.csv")
    assert len(data["rows"]) == len(rows) and text.count("\n  {") == len(rows)


def test_the_committed_quick_baseline_matches_the_quick_suite():
    """reports/baselines/quick.json covers every run the quick suite plans (regenerate it when the plan changes)."""
    rows = gate.read_baseline(QUICK_BASELINE)
    dts = [float(dt) for dt in QUICK_DT.split(",")]
    cases = [with_overrides(find_case(name), t_end=float(QUICK_T_END), dt=dts) for name in QUICK_CASES]
    specs, skipped = plan.plan(cases, list(engine_names()), None)
    planned = {gate._key(plan.base_row(spec, None)) for spec in specs} | {gate._key(row) for row in skipped}
    assert {gate._key(row) for row in rows} <= planned
    assert {(key[0], key[1]) for key in planned} == {(row["case"], row["engine"]) for row in rows}
    assert all(row["status"] == "ok" for row in rows)
    ci = (REPO / ".ci" / "run").read_text()
    assert f"{' '.join(QUICK_CASES)} --t-end {QUICK_T_END} --dt {QUICK_DT}" in ci
    assert "stereodyn check" in ci and "reports/baselines/quick.json" in ci
