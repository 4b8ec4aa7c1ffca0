"""CI outputs that agree with the gate (issue 46, findings 6-10 and the smaller ones): one environment rule for check,
compare and history (the measurement context is no difference), a step summary that never blocks, a metric become NaN
worse everywhere the gate fails it, a pull-request summary that stays markdown of <= 60 lines whatever the values
hold, and numbers that every command can compute with. The folders are written by hand (a results table of a few
rows, runs.json, convergence.csv, verdicts.csv): no sweep, seconds in all."""
import json
import os
import subprocess
import sys
from pathlib import Path

import pandas as pd
import pytest

from stereodyn.harness import cli
from stereodyn.harness.environment import TIMING_END, TIMING_START

ROWS = [  # case, engine, formulation, integrator, dt, energy_drift, attitude_err
    ("free-asymmetric", "mujoco", "", "rk4", 0.01, 3.1e-9, 2.0e-7),
    ("free-asymmetric", "mujoco", "", "rk4", 0.003, 2.5e-11, 1.7e-9),
    ("lagrange-top", "reference", "quaternion", "rk4", 0.01, 1.0e-9, 3.0e-7),
]


def environment(date: str, load: str) -> dict:
    """A sweep's runs.json environment as harness.environment records it: versions, machine, and the context."""
    return {"python": "3.11.7", "numpy": "2.1.0", "mujoco": "3.3.7", "cpu": "AMD EPYC 7B13", "machine": "x86_64",
            "platform": "Linux-6.1-x86_64", "date": date, "git commit": date[:10].replace("-", "") * 4,
            TIMING_START: f"load average {load} (1, 5, 15 min) on 2 CPUs, AMD EPYC 7B13, at {date}",
            TIMING_END: f"load average {load}1 (1, 5, 15 min) on 2 CPUs, AMD EPYC 7B13, at {date}"}


def folder(path: Path, date: str = "2026-11-01T10:00:00+00:00", load: str = "6.10, 7.00, 8.00", values=None,
           env: dict | None = None, case_names=None, verdict: str | None = None) -> Path:
    """A finished result folder: results.csv (ROWS; `values`: {(row, column): value}), runs.json, convergence.csv
    and, with `verdict`, verdicts.csv (mujoco rk4's order verdict with that status)."""
    path.mkdir(parents=True)
    rows = []
    for index, (case, engine, formulation, integrator, dt, energy, attitude) in enumerate(ROWS):
        row = dict(case=(case_names or {}).get(index, case), engine=engine, formulation=formulation,
                   integrator=integrator, precision="float64", dt=dt, status="ok", message="", energy_drift=energy,
                   attitude_err=attitude, us_per_step=1.0 + index)
        for (at, column), value in (values or {}).items():
            if at == index:
                row[column] = value
        rows.append(row)
    pd.DataFrame(rows).to_csv(path / "results.csv", index=False)
    code = {"stereodyn source": "a" * 24, "engines": {}, "integrators": {}}
    (path / "runs.json").write_text(json.dumps({"format": 1, "environment": env or environment(date, load),
                                                "code": code, "runs": [], "complete": True}))
    pd.DataFrame([dict(case="free-asymmetric", engine="mujoco", formulation="", integrator="rk4", precision="float64",
                       order=4.01, declared_order=4.0, points=2, source="dt_list", note="")]) \
        .to_csv(path / "convergence.csv", index=False)
    if verdict:
        pd.DataFrame([dict(verdict="order", engine="mujoco", formulation="", integrator="rk4", precision="float64",
                           case="", status=verdict, detail="", rule="")]).to_csv(path / "verdicts.csv", index=False)
    return path


def rerun_pair(tmp_path):
    """A run and its rerun on the same machine an hour later: other date, commit checked out and load averages."""
    a = folder(tmp_path / "a", verdict="not measured, no reason")
    b = folder(tmp_path / "b", date="2026-11-01T11:00:00+00:00", load="0.50, 1.20, 3.40",
               verdict="not measured, no reason")
    return a, b


# ------------------------------------------------------------------------------- finding 6: one environment rule

def test_a_same_machine_rerun_is_the_same_environment_for_check_compare_and_history(tmp_path, capsys, monkeypatch):
    """The load averages, the date and the commit are measurement context: check says "as in the baseline" and gives
    no hint to loosen the gate (in the step summary neither), compare --format pr calls the rerun identical, with a
    baseline as A too (which records no verdicts), and history lists no environment column."""
    a, b = rerun_pair(tmp_path)
    baseline = tmp_path / "baseline.json"
    assert cli.main(["baseline", str(a), "--out", str(baseline)]) == 0
    summary = tmp_path / "summary.md"
    monkeypatch.setenv("GITHUB_STEP_SUMMARY", str(summary))
    capsys.readouterr()
    assert cli.main(["check", str(b), "--baseline", str(baseline)]) == 0
    printed = capsys.readouterr().out
    assert "environment: as in the baseline" in printed and "cross-machine" not in printed, printed
    assert "cross-machine" not in summary.read_text() and "as in the baseline" in summary.read_text()
    for first in (a, baseline):
        assert cli.main(["compare", str(first), str(b), "--out", str(tmp_path / "cmp"), "--format", "pr"]) == 0
        pr = capsys.readouterr().out
        assert pr.count("\n") == 1 and "is identical to" in pr, pr
    assert cli.main(["history", str(a), str(b), "--out", str(tmp_path / "h")]) == 0
    points = pd.read_csv(tmp_path / "h" / "history_points.csv")
    assert not {TIMING_START, TIMING_END, "stereodyn source"} & set(points.columns), points.columns


def test_a_real_difference_still_differs_everywhere(tmp_path, capsys):
    """Another MuJoCo is a difference for all three readers, and the only one named."""
    from stereodyn.harness.environment import differences

    a = folder(tmp_path / "a")
    env = {**environment("2026-11-02T10:00:00+00:00", "1.00, 1.00, 1.00"), "mujoco": "4.0.0"}
    b = folder(tmp_path / "b", env=env)
    assert differences(environment("x", "1"), env) == ["mujoco"]
    baseline = tmp_path / "baseline.json"
    assert cli.main(["baseline", str(a), "--out", str(baseline)]) == 0
    capsys.readouterr()
    assert cli.main(["check", str(b), "--baseline", str(baseline)]) == 0
    printed = capsys.readouterr().out
    assert "environment: mujoco 3.3.7 -> 4.0.0\n" in printed and "--mode cross-machine" in printed, printed
    assert cli.main(["compare", str(a), str(b), "--format", "pr"]) == 0
    pr = capsys.readouterr().out
    assert "Environment: 1 key differs" in pr and "| mujoco | 3.3.7 | 4.0.0 |" in pr, pr


def test_a_change_of_stereodyns_own_source_is_named_by_every_reader_and_is_no_other_machine(tmp_path, capsys):
    """Issue 46's eleventh attack, F2: a baseline left out stereodyn's source, so after a change of the code check
    and compare with the baseline as A said "same environment" while compare of the two folders said "1 key
    differs: stereodyn source". All three name it now; check gives no --mode cross-machine hint for it (the code
    under test changes by design). Break-checked: recorded_environment without the own source fails the first
    assertion; mode_line without OWN_SOURCE among its exceptions fails the second."""
    a = folder(tmp_path / "a")
    b = folder(tmp_path / "b", date="2026-11-01T11:00:00+00:00")
    manifest = json.loads((b / "runs.json").read_text())
    manifest["code"]["stereodyn source"] = "b" * 24
    (b / "runs.json").write_text(json.dumps(manifest))
    baseline = tmp_path / "baseline.json"
    assert cli.main(["baseline", str(a), "--out", str(baseline)]) == 0
    capsys.readouterr()
    assert cli.main(["check", str(b), "--baseline", str(baseline)]) == 0
    printed = capsys.readouterr().out
    assert f"environment: stereodyn source {'a' * 24} -> {'b' * 24}\n" in printed, printed
    assert "cross-machine" not in printed, printed
    for first in (a, baseline):
        assert cli.main(["compare", str(first), str(b), "--format", "pr"]) == 0
        pr = capsys.readouterr().out
        assert "Environment: 1 key differs" in pr, pr
        assert "| stereodyn source | aaaaaaaaaaaa… | bbbbbbbbbbbb… |" in pr, pr  # hashes cut to 12 digits
    assert cli.main(["history", str(baseline), str(b), "--out", str(tmp_path / "h")]) == 0
    assert "stereodyn source" in pd.read_csv(tmp_path / "h" / "history_points.csv").columns


# ---------------------------------------------- issue 46 F8: an answer moved by timing noise is no change

# answers.csv cells of a run and of its rerun on one machine (issue 46 F8, measured: `run free-asymmetric
# lagrange-top --t-end 2 --dt 1e-2,3e-3` twice): (case, scope, target, engine, integrator, dt, us_per_sim_s, spread).
# Between the two, each cell named another of the runs that tie in cost: noise, yet "2 answers changed" and
# "identical" in one summary.
ANSWERS_A = [("free-asymmetric", "pinocchio", 1e-2, "pinocchio", "euler", 0.01, 317.634, 21.457),
             ("lagrange-top", "pinocchio", 1e-2, "pinocchio", "rk4_naive", 0.01, 879.5825, 11.277),
             ("lagrange-top", "any", 1e-6, "mujoco", "rk4", 0.003, 456.0, 9.0)]
ANSWERS_B = [("free-asymmetric", "pinocchio", 1e-2, "pinocchio", "symplectic_euler", 0.01, 358.465, 28.6875),
             ("lagrange-top", "pinocchio", 1e-2, "pinocchio", "rk4", 0.01, 1259.2445, 535.514),
             ("lagrange-top", "any", 1e-6, "mujoco", "rk4", 0.003, 471.0, 12.0)]


def write_answers(path: Path, cells) -> Path:
    """DIR/answers.csv of `cells` (ANSWERS_A's shape; engine None: no answer), every column answers.csv has."""
    from stereodyn.harness.analysis.answers import ANSWER_COLUMNS, ANSWERS_FILE, LISTED

    rows = [dict(case=case, scope=scope, target=target, engine=engine or "", formulation="",
                 integrator=integrator or "", dt=dt, tolerance=float("nan"), error=target / 2 if engine else None,
                 us_per_sim_s=cost, us_per_sim_s_spread=spread, source=LISTED if engine else "", fails_at=None,
                 why_none="" if engine else "none reached it")
            for case, scope, target, engine, integrator, dt, cost, spread in cells]
    pd.DataFrame(rows, columns=list(ANSWER_COLUMNS)).to_csv(path / ANSWERS_FILE, index=False)
    return path


def test_a_rerun_whose_answers_moved_by_timing_noise_is_identical_and_no_answer_changed(tmp_path, capsys):
    """A same-machine rerun whose answers name other runs tied in cost (the Pareto tie rule) passes check, and
    compare --format pr calls it identical in one line that names no answer changed (before: "2 answers changed"
    above "is identical"); with another MuJoCo in B the summary's answers line says the same."""
    a, b = rerun_pair(tmp_path)
    write_answers(a, ANSWERS_A), write_answers(b, ANSWERS_B)
    baseline = tmp_path / "baseline.json"
    assert cli.main(["baseline", str(a), "--out", str(baseline)]) == 0
    assert cli.main(["check", str(b), "--baseline", str(baseline)]) == 0
    capsys.readouterr()
    assert cli.main(["compare", str(a), str(b), "--out", str(tmp_path / "cmp"), "--format", "pr"]) == 0
    pr = capsys.readouterr().out
    assert pr.count("\n") == 1 and "is identical to" in pr and "changed" not in pr, pr
    assert "answers (2 moved only within the timing noise)" in pr, pr
    env = {**environment("2026-11-02T10:00:00+00:00", "1.00, 1.00, 1.00"), "mujoco": "4.0.0"}
    other = write_answers(folder(tmp_path / "other", env=env), ANSWERS_B)
    assert cli.main(["compare", str(a), str(other), "--out", str(tmp_path / "cmp2"), "--format", "pr"]) == 0
    pr = capsys.readouterr().out
    assert "identical" not in pr and "answers changed" not in pr and "answer changed (" not in pr, pr
    assert pr.splitlines()[0].endswith("an order moved by more than 0.1)."), pr  # the headline: no answer counted
    assert ("What to use (answers.csv): no answer changed beyond the timing noise (2 moved between runs whose costs "
            "tie).") in pr.splitlines(), pr


def test_an_answer_whose_run_became_costlier_or_that_went_is_a_change(tmp_path, capsys):
    """The same rows, but in B the answer at 1e-6 costs 3x (its run slowed: a costlier one answers) and the one of
    free-asymmetric at 1e-2 is gone (nothing reaches it): no longer identical, the headline counts 2 answers changed
    and the answers line names both, and the one that moved within the noise as no change."""
    a, b = rerun_pair(tmp_path)
    write_answers(a, ANSWERS_A)
    write_answers(b, [(*ANSWERS_B[0][:3], None, None, float("nan"), float("nan"), float("nan")), ANSWERS_B[1],
                      ("lagrange-top", "any", 1e-6, "reference", "rk4", 0.003, 1380.0, 12.0)])
    capsys.readouterr()
    assert cli.main(["compare", str(a), str(b), "--format", "pr"]) == 0
    pr = capsys.readouterr().out
    assert "identical" not in pr and "; 2 answers changed (What to use)." in pr.splitlines()[0], pr
    assert ("What to use (answers.csv): 2 answers changed: free-asymmetric pinocchio 1e-02: pinocchio euler dt=0.01 "
            "-> -; lagrange-top any 1e-06: mujoco rk4 dt=0.003 -> reference rk4 dt=0.003; 1 more moved only within "
            "the timing noise (no change).") in pr.splitlines(), pr


# ----------------------------------------------------------------------------- finding 7: a FIFO never blocks

@pytest.mark.parametrize("kind", ["fifo", "device"])
def test_a_step_summary_that_is_no_regular_file_is_a_warning_never_a_hang(tmp_path, monkeypatch, kind):
    """GITHUB_STEP_SUMMARY naming a FIFO nobody reads (or /dev/null) is a warning saying what it is; check keeps its
    status and returns at once (before: blocked in open() for ever)."""
    a, b = rerun_pair(tmp_path)
    baseline = tmp_path / "baseline.json"
    assert cli.main(["baseline", str(a), "--out", str(baseline)]) == 0
    target = tmp_path / "fifo"
    if kind == "fifo":
        os.mkfifo(target)
    else:
        target = Path("/dev/null")
    env = {**os.environ, "GITHUB_STEP_SUMMARY": str(target)}
    done = subprocess.run([sys.executable, "-m", "stereodyn", "check", str(b), "--baseline", str(baseline)],
                          env=env, capture_output=True, text=True, timeout=60)
    assert done.returncode == 0, done.stderr
    expected = "a FIFO" if kind == "fifo" else "a character device"
    assert f"GITHUB_STEP_SUMMARY={target}: cannot append the summary (not a regular file ({expected}))" in done.stderr


def test_compare_out_that_is_no_folder_names_the_option(tmp_path, capsys):
    a, b = rerun_pair(tmp_path)
    os.mkfifo(tmp_path / "fifo")
    for out, what in (("/dev/null", "a character device"), (str(tmp_path / "fifo"), "a FIFO")):
        assert cli.main(["compare", str(a), str(b), "--out", out]) == 2
        err = capsys.readouterr().err
        assert err.count("\n") == 1 and f"--out {out}: is {what}, not a folder" in err, err


# ------------------------------------------------------------------------ finding 8: a NaN is worse everywhere

def test_a_metric_become_nan_is_worse_in_check_compare_and_history(tmp_path, capsys):
    """An ok row whose attitude_err became NaN fails check; compare --format pr counts it worse and history flags it
    worse at that run (before: "no change for the worse", "0 steps flagged")."""
    a = folder(tmp_path / "a")
    b = folder(tmp_path / "b", date="2026-11-02T10:00:00+00:00", values={(1, "attitude_err"): float("nan")})
    baseline = tmp_path / "baseline.json"
    assert cli.main(["baseline", str(a), "--out", str(baseline)]) == 0
    assert cli.main(["check", str(b), "--baseline", str(baseline)]) == 1
    capsys.readouterr()
    assert cli.main(["compare", str(a), str(b), "--format", "pr"]) == 0
    pr = capsys.readouterr().out
    assert "**1 change for the worse**" in pr and "NaN in B free-asymmetric mujoco rk4 dt=0.003" in pr, pr
    changes = pd.read_csv(b / "compare.csv")
    assert changes["attitude_err"].max() == float("inf")  # compare.csv: B / A infinitely worse
    assert cli.main(["history", str(a), str(b), "--out", str(tmp_path / "h")]) == 0
    assert "1 steps flagged, 1 worse:" in capsys.readouterr().out
    steps = pd.read_csv(tmp_path / "h" / "history_steps.csv", keep_default_na=False)
    assert steps[["dt", "quantity", "direction", "change"]].values.tolist() == [[0.003, "attitude_err", "worse",
                                                                                  "NaN"]]


def test_history_flags_a_nan_on_an_order_and_a_recovery_better(tmp_path):
    """A fitted order that became NaN (the gate: "fell") is worse; the metric that has a number again, better."""
    from stereodyn.harness.analysis import history

    def point(label, attitude, order):
        table = pd.DataFrame([dict(case="c", engine="e", formulation="", integrator="i", precision="float64",
                                   dt=0.01, status="ok", attitude_err=attitude)])
        orders = pd.DataFrame([dict(case="c", engine="e", formulation="", integrator="i", precision="float64",
                                    fitted=order, declared=4.0)])
        return history.Point(label, label, table, orders, {})

    nan = float("nan")
    _, steps = history.history([point("1", 1e-6, 4.0), point("2", nan, nan), point("3", 1e-6, 4.0)])
    assert sorted(zip(steps["quantity"], steps["label"], steps["direction"])) == [
        ("attitude_err", "2", "worse"), ("attitude_err", "3", "better"), ("order", "2", "worse"),
        ("order", "3", "better")], steps


def test_an_order_that_fell_toward_its_declared_one_is_worse_where_the_gate_fails_it(tmp_path, capsys):
    """Issue 46's re-attack: a baseline's fitted 4.8 (declared 4) against a run's 4.01 fails check ("fell" by more than
    gate.ORDER_DROP), while compare --format pr called it better (nearer the declared order) and history flagged
    "0 worse". Both call it worse now; a rise toward the declared order stays better. Break-checked: compare's
    old sign rule fails the pr assertion."""
    from stereodyn.harness.analysis import compare, history

    run = folder(tmp_path / "run")
    baseline = tmp_path / "baseline.json"
    assert cli.main(["baseline", str(run), "--out", str(baseline)]) == 0
    data = json.loads(baseline.read_text())
    data["orders"][0]["fitted"] = 4.8
    baseline.write_text(json.dumps(data))
    assert cli.main(["check", str(run), "--baseline", str(baseline)]) == 1
    capsys.readouterr()
    assert cli.main(["compare", str(baseline), str(run), "--format", "pr"]) == 0
    pr = capsys.readouterr().out
    assert "no change for the worse" not in pr and "**1 change for the worse**" in pr, pr
    key = ("c",)
    assert [c["sign"] for c in compare.order_changes({key: {"fitted": 3.0, "declared": 4.0}},
                                                     {key: {"fitted": 4.0, "declared": 4.0}})] == ["better"]

    def point(label, order):
        table = pd.DataFrame([dict(case="c", engine="e", formulation="", integrator="i", precision="float64",
                                   dt=0.01, status="ok", attitude_err=1e-6)])
        orders = pd.DataFrame([dict(case="c", engine="e", formulation="", integrator="i", precision="float64",
                                    fitted=order, declared=4.0)])
        return history.Point(label, label, table, orders, {})

    for before, after, direction in ((4.8, 4.0, "worse"), (3.0, 4.0, "better"), (4.0, 4.8, "changed")):
        _, steps = history.history([point("1", before), point("2", after)])
        assert list(zip(steps["label"], steps["direction"])) == [("2", direction)], (before, after, steps)


# ---------------------------------------------------- finding 9: the PR summary is markdown of <= 60 lines

def test_the_pr_summary_escapes_every_value_and_stays_within_60_lines(tmp_path, capsys):
    """Environment values holding newlines, bars, backticks and markup: every value is one escaped line, every table
    row has its columns, and the summary stays within 60 lines (before: 198 lines of broken tables). Case names
    holding them are refused where results.csv is read (a name shows as itself everywhere: issue 46's eleventh
    attack, F3; compare.md and report.md escaped only bars)."""
    nasty = "x\n| injected | row |\n`code` *bold* <b>"
    env_a = {**environment("2026-11-01T10:00:00+00:00", "1"), **{f"key{i}": f"a{i}\n{nasty}" for i in range(10)}}
    env_b = {**environment("2026-11-01T10:00:00+00:00", "1"), **{f"key{i}": f"b{i}|{nasty}" for i in range(10)}}
    hostile = folder(tmp_path / "hostile", case_names={i: f"case{i}\n{nasty}" for i in range(3)})
    a = folder(tmp_path / "a", env=env_a, case_names={i: f"case{i}" for i in range(3)})
    b = folder(tmp_path / "b", env=env_b, case_names={i: f"case{i}" for i in range(3)},
               values={(i, m): 3.0 for i in range(3) for m in ("attitude_err", "energy_drift")})  # <= pi
    assert cli.main(["compare", str(a), str(hostile), "--format", "pr"]) == 2
    assert "row 1, column case: " in capsys.readouterr().err
    assert cli.main(["compare", str(a), str(b), "--format", "pr"]) == 0
    printed = capsys.readouterr().out
    lines = printed.splitlines()
    assert len(lines) <= 60, len(lines)
    assert "injected" in printed and not any(line.startswith("| injected") for line in lines)
    for line in lines:
        if line.startswith("|"):  # a table row: its cells are the header's, bars inside values escaped
            cells = line.replace("\\|", "").count("|")
            assert cells in (4, 5, 6), line
    assert "\\`code\\` \\*bold\\* \\<b\\>" in printed and "\\n" in printed
    # compare.md escapes them too (it escaped only bars: a backtick opened a code span, <b> bold for the page)
    assert cli.main(["compare", str(a), str(b), "--out", str(tmp_path / "plain")]) == 0
    page = (tmp_path / "plain" / "compare.md").read_text()
    assert "\\`code\\` \\*bold\\* \\<b\\>" in page and "`code`" not in page, page


# ------------------------------------------------------- finding 10: numbers every command can compute with

def test_a_value_above_the_bound_is_refused_where_it_is_read(tmp_path, capsys):
    """A metric of 1e308 in results.csv (finite, accepted before) is refused by every reader with one line naming the
    file, the row, the column and the bound: history no longer dies of an OverflowError (exit 1, "a row got worse");
    a baseline holding one, or an order below 0, is refused too (either could never fail)."""
    a = folder(tmp_path / "a")
    b = folder(tmp_path / "b", date="2026-11-02T10:00:00+00:00", values={(0, "energy_drift"): 1e308})
    capsys.readouterr()
    assert cli.main(["history", str(a), str(b), "--out", str(tmp_path / "h")]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "row 1, column energy_drift: '1e+308': must be <= 1e+100" in err, err
    baseline = tmp_path / "baseline.json"
    assert cli.main(["baseline", str(a), "--out", str(baseline)]) == 0
    data = json.loads(baseline.read_text())
    for edit, words in ((lambda d: d["rows"][0].update(energy_drift=1e308), "rows[0].energy_drift: must be <= 1e+100"),
                        (lambda d: d["orders"][0].update(fitted=-50), "orders[0].fitted: must be >= 0"),
                        (lambda d: d["rows"][0].update(attitude_err=10 ** 400), "rows[0].attitude_err: must be finite")):
        edited = json.loads(json.dumps(data))
        edit(edited)
        bad = tmp_path / "bad.json"
        bad.write_text(json.dumps(edited))
        for argv in (["check", str(a), "--baseline", str(bad)], ["history", str(bad), str(a), "--out",
                                                                   str(tmp_path / "h2")]):
            assert cli.main(argv) == 2, argv
            err = capsys.readouterr().err
            assert err.count("\n") == 1 and words in err, err


def edited_baselines(tmp_path, base: Path, edits):
    """(path, words) for each (edit, words): base's JSON changed by edit(data), written beside it."""
    data = json.loads(base.read_text())
    for index, (edit, words) in enumerate(edits):
        edited = json.loads(json.dumps(data))
        edit(edited)
        path = tmp_path / f"edited-{index}.json"
        path.write_text(json.dumps(edited))
        yield path, words


# Each quantity's range where a baseline is read: an angle in rad up to pi (9.9e99 passed the global 1e100 bound, and
# check could then never fail the row), an order up to MAX_ORDER, only the keys write_baseline writes, text in the
# environment. None: the file is accepted (the bound itself, and pi as results.csv writes it, 10 digits).
BASELINE_EDITS = [
    (lambda d: d["rows"][0].update(attitude_err=9.9e99), "rows[0].attitude_err: must be <= pi (an angle in rad)"),
    (lambda d: d["rows"][0].update(attitude_err_end=3.2), "rows[0].attitude_err_end: must be <= pi"),
    (lambda d: d["rows"][0].update(attitude_err=3.141592654), None),
    (lambda d: d["orders"][0].update(fitted=101), "orders[0].fitted: must be <= 100 (a convergence order)"),
    (lambda d: d["orders"][0].update(declared=1e99), "orders[0].declared: must be <= 100"),
    (lambda d: d["orders"][0].update(fitted=100), None),
    (lambda d: d["orders"][0].update(fited=4.0), "orders[0].fited: unknown key (allowed: case, engine, formulation"),
    (lambda d: d.update(order=d["orders"]), ": order: unknown key (allowed: format, mode, environment, rows, orders)"),
    (lambda d: d["environment"].update(numpy=2), "environment.numpy: must be a string, got 2"),
]


def test_a_baseline_value_outside_its_quantitys_range_or_an_unknown_key_is_one_line(tmp_path, capsys):
    a = folder(tmp_path / "a")
    baseline = tmp_path / "baseline.json"
    assert cli.main(["baseline", str(a), "--out", str(baseline)]) == 0
    for path, words in edited_baselines(tmp_path, baseline, BASELINE_EDITS):
        for argv in (["check", str(a), "--baseline", str(path)], ["compare", str(path), str(a)]):
            capsys.readouterr()
            code = cli.main(argv)
            err = capsys.readouterr().err
            if words is None:
                assert code in (0, 1) and "error" not in err, (argv, err)
            else:
                assert code == 2 and err.count("\n") == 1 and f"{path}: " in err and words in err, (argv, words, err)


@pytest.mark.parametrize("value, code", [(3.5, 2), (3.141592654, 0)])
def test_an_angle_above_pi_in_results_csv_is_refused_by_every_reader(tmp_path, capsys, value, code):
    a = folder(tmp_path / "a")
    b = folder(tmp_path / "b", date="2026-11-02T10:00:00+00:00", values={(1, "attitude_err_end"): value})
    baseline = tmp_path / "baseline.json"
    assert cli.main(["baseline", str(a), "--out", str(baseline)]) == 0
    for argv in (["check", str(b), "--baseline", str(baseline)], ["compare", str(a), str(b)],
                 ["history", str(a), str(b), "--out", str(tmp_path / "h")], ["baseline", str(b), "--out",
                                                                             str(tmp_path / "b.json")]):
        capsys.readouterr()
        assert cli.main(argv) == code, argv  # a's baseline holds no attitude_err_end: check passes pi
        err = capsys.readouterr().err
        if code:
            assert err.count("\n") == 1 and "row 2, column attitude_err_end: '3.5': must be <= pi" in err, (argv, err)


def test_the_largest_accepted_values_leave_every_command_finite(tmp_path, capsys):
    """At the bound (1e100, against the floor's 1e-12) history, compare and check compute without overflow."""
    from stereodyn.harness.run.results import MAX_VALUE

    a = folder(tmp_path / "a", values={(0, "energy_drift"): 0.0})  # a relative drift: an angle stays <= pi
    b = folder(tmp_path / "b", date="2026-11-02T10:00:00+00:00", values={(0, "energy_drift"): MAX_VALUE})
    assert cli.main(["history", str(a), str(b), "--out", str(tmp_path / "h")]) == 0
    assert cli.main(["compare", str(a), str(b), "--format", "pr"]) == 0
    baseline = tmp_path / "baseline.json"
    assert cli.main(["baseline", str(a), "--out", str(baseline)]) == 0
    assert cli.main(["check", str(b), "--baseline", str(baseline), "--time-factor", "1e300"]) == 1
    steps = pd.read_csv(tmp_path / "h" / "history_steps.csv", keep_default_na=False)
    assert steps["change"].tolist() == ["1e+112x"], steps


def test_a_timing_of_zero_in_the_baseline_is_no_division_by_zero(tmp_path, capsys):
    a = folder(tmp_path / "a", values={(0, "us_per_step"): 0.0})
    b = folder(tmp_path / "b", date="2026-11-02T10:00:00+00:00")
    baseline = tmp_path / "baseline.json"
    assert cli.main(["baseline", str(a), "--out", str(baseline)]) == 0
    assert cli.main(["check", str(b), "--baseline", str(baseline), "--time-factor", "2"]) == 1
    assert "us_per_step up to inf" in capsys.readouterr().out


# ------------------------------------------------------------------------------------- the smaller findings

def test_history_refuses_one_folder_twice_and_says_why_git_failed_in_words(tmp_path, capsys):
    a = folder(tmp_path / "a")
    assert cli.main(["history", str(a), str(tmp_path / "." / "a"), "--out", str(tmp_path / "h")]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "given twice" in err, err
    b = folder(tmp_path / "b", date="2026-11-02T10:00:00+00:00")
    empty = tmp_path / "not-a-repo"
    empty.mkdir()
    assert cli.main(["history", str(a), str(b), "--by", "commit", "--repo", str(empty)]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "not a git repository" in err and "['" not in err, err


HOLD_LOCK = ("import fcntl, os, sys, time; fd = os.open(sys.argv[1], os.O_RDONLY); fcntl.flock(fd, fcntl.LOCK_EX); "
             "print('locked', flush=True); time.sleep(120)")


def test_history_into_a_result_folder_locks_it_and_its_index_lists_the_files(tmp_path, capsys):
    """history --out a result folder holds its lock (a sweep writing it makes history wait: StoreBusy, exit 2) and
    leaves the folder's README listing history's files as history's, never "not written by stereodyn"."""
    from stereodyn.harness.report import index

    a = folder(tmp_path / "a")
    b = folder(tmp_path / "b", date="2026-11-02T10:00:00+00:00")
    (b / "store").mkdir()
    index.write(b)
    holder = subprocess.Popen([sys.executable, "-c", HOLD_LOCK, str(b / "store")], stdout=subprocess.PIPE, text=True)
    try:
        assert holder.stdout.readline() == "locked\n"  # as a sweep writing b holds it
        assert cli.main(["history", str(a), str(b), "--out", str(b)]) == 2
    finally:
        holder.kill()
        holder.wait()
    assert "another stereodyn command is writing" in capsys.readouterr().err
    assert not (b / "history.csv").exists()
    assert cli.main(["history", str(a), str(b), "--out", str(b)]) == 0
    readme = (b / index.INDEX_FILE).read_text()
    assert "`history.csv`: `stereodyn history`" in readme and index.OTHER not in readme, readme


def test_a_garbled_or_huge_runs_json_is_named(tmp_path, capsys):
    """A runs.json that is not JSON, or larger than the readers' limit, still counts as absent (test_faults), but
    every reader names it and says why in its one warning line (before: "no completion mark", and history's error
    "no 'date' recorded" with nothing about the file)."""
    a = folder(tmp_path / "a")
    b = folder(tmp_path / "b", date="2026-11-02T10:00:00+00:00")
    baseline = tmp_path / "baseline.json"
    assert cli.main(["baseline", str(a), "--out", str(baseline)]) == 0
    from stereodyn.harness.run.results import frame, read_results, write_results

    write_results(frame(read_results(b / "results.csv").to_dict("records")), b / "results.csv")  # report's columns
    for content, words in (("{garbled", "invalid JSON"), (None, "larger than")):
        with open(b / "runs.json", "w") as handle:
            handle.write(content) if content else handle.truncate(300 << 20)  # sparse: 300 MB on no disk
        for argv, code in ((["history", str(a), str(b), "--out", str(tmp_path / "h")], 2),
                           (["compare", str(a), str(b)], 0), (["check", str(b), "--baseline", str(baseline)], 0),
                           (["report", str(b), "--no-figures"], 0)):
            capsys.readouterr()
            assert cli.main(argv) == code, argv
            warning = capsys.readouterr().err.splitlines()[0]
            assert f"{b / 'runs.json'}: not a runs.json stereodyn can read (" in warning and words in warning, (
                argv, warning)


def test_history_refuses_a_duplicated_row_as_every_reader_does(tmp_path, capsys):
    a = folder(tmp_path / "a")
    b = folder(tmp_path / "b", date="2026-11-02T10:00:00+00:00")
    text = (b / "results.csv").read_text().splitlines()
    (b / "results.csv").write_text("\n".join([*text, text[1]]) + "\n")
    for path, other in ((b, a), (a, b)):
        assert cli.main(["history", str(other), str(path), "--out", str(tmp_path / "h")]) == 2
        err = capsys.readouterr().err
        assert "duplicate key" in err, err


@pytest.mark.parametrize("value, kept", [(None, True), (2.5e-7, True), ("inf", True), (-1e-9, False),
                                         (1e308, False), (float("nan"), False), (10 ** 400, False), ("1e-3", False),
                                         (3.2, False)])
def test_resume_keeps_only_records_whose_numbers_results_csv_would_accept(value, kept):
    """A hand-edited store record (a negative error, 1e308, a NaN literal where the store writes null) counts as
    absent on --resume and is redone, never copied into a results.csv that check then refuses; what the store itself
    writes (null, "inf": test_store_contracts) is kept."""
    from stereodyn.harness.run.results import COLUMNS
    from stereodyn.harness.run.store import FORMAT, seal, well_formed

    text = {"case": "c", "engine": "reference", "formulation": "quaternion", "integrator": "rk4",
            "precision": "float64", "status": "ok", "message": "", "timing": "single"}
    row = {column: text.get(column) for column in COLUMNS}
    row.update(dt=0.01, t_end=1.0, steps=100, attitude_err=value)
    record = {"format": FORMAT, "key": "k" * 24, "identity": {"engine": "reference"}, "row": row, "series": None}
    record["seal"] = seal(record)  # sealed as Store.put seals it: what is judged here is the number
    assert well_formed(record, "k" * 24) is kept


def test_a_verdict_status_no_verdict_has_is_refused_by_every_reader(tmp_path, capsys):
    """Issue 46's eleventh attack, F6: a verdicts.csv status edited to `garbage` was compared as "not measured ->
    garbage: better" and rendered as a verdict; results.csv refuses a status it does not know, and so does
    verdicts.csv now: one line naming the file, the row and the statuses (exit 2). Break-checked: without the check
    in verdicts.read compare --format pr exits 0."""
    a = folder(tmp_path / "a", verdict="not measured, no reason")
    b = folder(tmp_path / "b", verdict="garbage")
    capsys.readouterr()
    assert cli.main(["compare", str(a), str(b), "--out", str(tmp_path / "cmp"), "--format", "pr"]) == 2
    err = capsys.readouterr().err
    assert f"{b / 'verdicts.csv'}: row 1: status = 'garbage': must be one of 'pass', 'fail'" in err, err
    assert cli.main(["compare", str(a), str(a), "--out", str(tmp_path / "same"), "--format", "pr"]) == 0


def test_history_escapes_an_environment_key_in_its_header(tmp_path):
    """Issue 46's twelfth attack: an environment key `we|rd*key` that differs became a column whose header history.md
    wrote raw: a header of 11 cells over rows of 10. Break-checked: without md_text on the header the counts differ."""
    a = folder(tmp_path / "a", env={**environment("2026-11-01T10:00:00+00:00", "1"), "we|rd*key": "1"})
    b = folder(tmp_path / "b", env={**environment("2026-11-01T11:00:00+00:00", "1"), "we|rd*key": "2"})
    assert cli.main(["history", str(a), str(b), "--out", str(tmp_path / "h")]) == 0
    table = [line for line in (tmp_path / "h" / "history.md").read_text().splitlines() if line.startswith("|")]
    cells = [line.replace("\\|", "").count("|") for line in table[:4]]
    assert len(set(cells)) == 1 and "we\\|rd\\*key" in table[0], table[:4]
