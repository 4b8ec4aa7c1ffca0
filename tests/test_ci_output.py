"""CI-friendly output (issue 31): a closed pipe keeps check's status, --quiet prints nothing on success, --junit
writes JUnit XML counting the failures the text counts, GITHUB_STEP_SUMMARY receives the markdown summary. The tables
are written by hand (the gate reads any valid results.csv): no sweep, seconds in all."""
import json
import os
import re
import subprocess
import sys
from pathlib import Path
from xml.etree import ElementTree

import pandas as pd
import pytest

from stereodyn.harness import cli

from helpers import FAST, case_file, tiny_case


def _table(rows: int) -> pd.DataFrame:
    """`rows` ok rows of one integrator on one case, one per dt, with two metrics."""
    dts = [1e-3 * (k + 1) for k in range(rows)]
    return pd.DataFrame({"case": "lagrange-top", "engine": "reference", "formulation": "quaternion",
                         "integrator": "rk4", "precision": "float64", "dt": dts, "status": "ok", "message": "",
                         "attitude_err": [1e-6 * (k + 1) for k in range(rows)],
                         "energy_drift": [1e-7 * (k + 1) for k in range(rows)]})


def _folder(path: Path, table: pd.DataFrame, orders: list[float] | None = None) -> Path:
    path.mkdir()
    table.to_csv(path / "results.csv", index=False)
    if orders is not None:
        pd.DataFrame({"case": "lagrange-top", "engine": "reference", "formulation": ["quaternion", "euler_zxz"],
                      "integrator": "rk4", "precision": "float64", "order": orders,
                      "declared_order": 4.0}).dropna().to_csv(path / "convergence.csv", index=False)
    return path


@pytest.fixture
def gated(tmp_path):
    """A baseline of 6 rows and 2 fitted orders, and a run of it where 2 rows got worse (one of them twice), 1 row
    is missing, 1 order fell and 1 order is missing."""
    base = _folder(tmp_path / "base", _table(6), [4.0, 4.0])
    baseline = tmp_path / "baseline.json"
    assert cli.main(["baseline", str(base), "--out", str(baseline), "--allow-partial"]) == 0
    table = _table(6)
    table.loc[0, ["attitude_err", "energy_drift"]] *= 3.0
    table.loc[1, "attitude_err"] *= 1.5
    run = _folder(tmp_path / "run", table.drop(index=5), [2.5, float("nan")])
    return base, baseline, run


def _check(run: Path, baseline: Path, *options: str) -> int:
    return cli.main(["check", str(run), "--baseline", str(baseline), "--allow-partial", *options])


def test_junit_has_a_case_per_row_and_order_and_counts_the_failures_the_text_counts(gated, tmp_path, capsys):
    _, baseline, run = gated
    junit = tmp_path / "junit.xml"
    capsys.readouterr()
    assert _check(run, baseline, "--junit", str(junit)) == 1
    last = capsys.readouterr().out.splitlines()[-1]
    counts = {what: int(n) for n, what in re.findall(r"(\d+) of \d+ (baseline rows got worse|baseline rows missing|"
                                                      r"fitted orders fell|fitted orders missing)", last)}
    assert counts == {"baseline rows got worse": 2, "baseline rows missing": 1, "fitted orders fell": 1,
                      "fitted orders missing": 1}, last
    root = ElementTree.parse(junit).getroot()
    assert root.tag == "testsuites"
    (suite,) = root.findall("testsuite")
    cases = suite.findall("testcase")
    failed = [case for case in cases if case.find("failure") is not None]
    assert int(suite.get("tests")) == len(cases) == 6 + 2  # every baseline row and every fitted order
    assert int(suite.get("failures")) == len(failed) == sum(counts.values())
    assert all(case.get("classname") == "stereodyn.reference" and case.get("name") for case in cases)
    twice = next(case for case in failed if case.get("name").endswith("dt=0.001"))
    assert twice.find("failure").text.count("\n") == 1  # its two metrics, one line each
    assert {case.find("failure").get("type") for case in failed} == {"attitude_err", "missing", "order",
                                                                     "missing order"}


def test_a_passing_check_writes_junit_without_failures_and_quiet_prints_nothing(gated, tmp_path, capsys):
    base, baseline, _ = gated
    junit = tmp_path / "junit.xml"
    capsys.readouterr()
    assert _check(base, baseline, "--junit", str(junit), "--quiet") == 0
    assert capsys.readouterr().out == ""
    suite = ElementTree.parse(junit).getroot().find("testsuite")
    assert (suite.get("tests"), suite.get("failures")) == ("8", "0")


def test_quiet_check_prints_only_the_failures(gated, capsys):
    _, baseline, run = gated
    capsys.readouterr()
    assert _check(run, baseline, "--quiet") == 1
    printed = capsys.readouterr().out
    assert not printed.startswith(("environment:", "gate:")) and printed.splitlines()[-1].startswith("check failed")


def test_the_step_summary_is_appended_when_github_names_a_file(gated, tmp_path, capsys, monkeypatch):
    _, baseline, run = gated
    summary = tmp_path / "summary.md"
    summary.write_text("earlier step\n")
    monkeypatch.setenv("GITHUB_STEP_SUMMARY", str(summary))
    assert _check(run, baseline) == 1
    text = summary.read_text()
    assert text.startswith("earlier step\n### stereodyn check failed: 2 of 6 baseline rows got worse")
    assert "- gate: same-machine mode (the baseline's)" in text
    assert "| lagrange-top quaternion rk4 dt=0.001 | reference | energy_drift |" in text
    monkeypatch.setenv("GITHUB_STEP_SUMMARY", str(tmp_path / "no-folder" / "summary.md"))
    capsys.readouterr()
    assert _check(run, baseline) == 1  # the gate's status stands; the summary that cannot be written is a warning
    assert "GITHUB_STEP_SUMMARY=" in capsys.readouterr().err


def test_a_closed_pipe_keeps_checks_status_and_prints_no_broken_pipe(tmp_path):
    """`check | head -1`: head leaves after the first line, and the output (~100 KB: far over a pipe's 64 KB, so the
    writes meet the closed pipe whatever the timing) is cut. 0.2.0 exited 2, "stereodyn: error: Broken pipe"."""
    base = _folder(tmp_path / "base", _table(400))
    baseline = tmp_path / "baseline.json"
    assert cli.main(["baseline", str(base), "--out", str(baseline), "--allow-partial"]) == 0
    table = _table(400)
    table[["attitude_err", "energy_drift"]] *= 10.0
    worse = _folder(tmp_path / "worse", table)
    command = [sys.executable, "-m", "stereodyn", "check", "--allow-partial", "--baseline", str(baseline)]
    env = {**os.environ, "PYTHONWARNINGS": "ignore"}
    for folder, code in ((worse, 1), (base, 0)):
        shell = f"set -o pipefail; {' '.join(command)} {folder} | head -1"
        result = subprocess.run(["bash", "-c", shell], capture_output=True, text=True, env=env, timeout=120)
        assert result.returncode == code, result.stderr
        assert result.stdout.startswith("environment: ") and result.stdout.count("\n") == 1
        assert "Broken pipe" not in result.stderr and "Exception ignored" not in result.stderr, result.stderr


def test_run_quiet_prints_nothing_and_a_rerun_compares_identical_in_one_line(tmp_path, capsys):
    """A passing `run --quiet` prints nothing (FAST has --quiet); its rerun is bit-identical on one machine, and
    `compare --format pr` says so in one line, the same as compare-pr.md."""
    case = case_file(tmp_path, tiny_case())
    for name in ("a", "b"):
        assert cli.main(["run", "--case-file", str(case), *FAST, "--no-ladder", "--no-certify", "--out",
                         str(tmp_path / name)]) == 0
        captured = capsys.readouterr()
        assert (captured.out, captured.err) == ("", "")
    assert len(pd.read_csv(tmp_path / "a" / "results.csv")) > 0
    assert cli.main(["compare", str(tmp_path / "a"), str(tmp_path / "b"), "--format", "pr"]) == 0
    printed = capsys.readouterr().out
    assert printed.count("\n") == 1 and "is identical to" in printed, printed
    assert (tmp_path / "b" / "compare-pr.md").read_text() == printed


def test_a_hand_edited_message_with_control_characters_gives_valid_junit_and_printable_lines(gated, tmp_path, capsys,
                                                                                            monkeypatch):
    """Issue 46's fifth attack, finding 2: a results.csv message holding ESC, NUL and BEL (a hand-edited or foreign
    file: stereodyn's writer escapes them) went raw into the JUnit file (no XML parser took it), the step summary
    and the terminal. The reader escapes them (results.read_results), so every output holds the escapes. Break-
    checked: without the escaping in read_results the XML does not parse."""
    _, baseline, run = gated
    table = pd.read_csv(run / "results.csv", keep_default_na=False)
    table.loc[2, ["status", "message"]] = ["failed", "bad \x1b[31m \x00 \x07 end"]
    table.to_csv(run / "results.csv", index=False)
    junit, summary = tmp_path / "junit.xml", tmp_path / "summary.md"
    monkeypatch.setenv("GITHUB_STEP_SUMMARY", str(summary))
    capsys.readouterr()
    assert _check(run, baseline, "--junit", str(junit)) == 1
    printed = capsys.readouterr().out
    texts = [junit.read_text(), summary.read_text(), printed]
    assert all("\x1b" not in text and "\x00" not in text and "\x07" not in text for text in texts)
    messages = [f.text or "" for f in ElementTree.parse(junit).getroot().iter("failure")]
    assert any("bad \\x1b[31m \\x00 \\x07 end" in text for text in messages), messages


def test_a_garbled_runs_json_is_named_as_such_not_as_missing(gated, capsys):
    """Issue 46's fifth attack, finding 6: with a runs.json that is there but not JSON, check said "run environment
    unknown (no runs.json beside results.csv)", and history "no 'date' recorded". Both now name the file and why it
    cannot be read. Break-checked: without manifest_problem passed to environment_changes the old words come back."""
    base, _, _ = gated
    (base / "runs.json").write_text(json.dumps({"format": 1, "environment": {"python": "3.11", "date": "2026-12-03"},
                                                "runs": [], "complete": True}))
    baseline = base.parent / "with-environment.json"
    assert cli.main(["baseline", str(base), "--out", str(baseline)]) == 0
    (base / "runs.json").write_text('{"complete": tr')
    capsys.readouterr()
    assert _check(base, baseline) == 0
    line = next(line for line in capsys.readouterr().out.splitlines() if line.startswith("environment:"))
    assert "runs.json: not a runs.json stereodyn can read (invalid JSON" in line and "no runs.json" not in line, line
    assert cli.main(["history", str(base), str(baseline), "--by", "date", "--out", str(base.parent / "h")]) == 2
    said = capsys.readouterr().err  # the cause first (the sixth attack: it led with "no 'date' recorded")
    assert f"--by date: {base / 'runs.json'}: not a runs.json stereodyn can read (invalid JSON" in said, said
    assert "recorded" not in said and said.rstrip().endswith("so --by date cannot place it"), said


def test_a_hand_edited_environment_value_is_printed_escaped(gated, capsys):
    """Issue 46's sixth attack, finding 4: runs.json's environment keys and values reached check's terminal and step
    summary (and compare, the report) raw: ESC, NUL, a newline that made a markdown heading. The reader of runs.json
    escapes them (store._manifest). Break-checked: without it the ESC is printed."""
    base, _, _ = gated
    (base / "runs.json").write_text(json.dumps({"format": 1, "environment": {"numpy": "2.4.6"}, "runs": [],
                                                "complete": True}))
    baseline = base.parent / "with-environment.json"
    assert cli.main(["baseline", str(base), "--out", str(baseline)]) == 0
    (base / "runs.json").write_text(json.dumps({"format": 1, "runs": [], "complete": True, "environment": {
        "numpy": "2.4.6\x1b[31mRED\x00\n# Heading | x"}}))
    capsys.readouterr()
    _check(base, baseline)
    printed = capsys.readouterr().out
    assert "\x1b" not in printed and "\x00" not in printed and "\n# Heading" not in printed, printed
    assert "2.4.6\\x1b[31mRED\\x00\\n# Heading | x" in printed, printed


def test_the_step_summary_escapes_every_value():
    """Issue 46's eighth attack, F9: check's step summary escaped only `|` and newlines: a case name or environment
    value holding <script>, an image, backticks or a link rendered as such in GitHub's page (compare --format pr
    escaped them). Every value is md_text's. Break-checked: without md_text in step_summary the raw tags stand."""
    from stereodyn.harness.analysis.gate import Finding, Verdict
    from stereodyn.harness.report.check import step_summary

    nasty = "<script>alert(1)</script> `tick` [l](http://e) **b**"
    finding = Finding((nasty, "mujoco", "", "rk4", "float64", 0.01), "attitude_err", "1e-6", "2e-6", "1.05x",
                      message="<img src=x onerror=alert(1)>")
    text = step_summary(Verdict(1, 0, (finding,), ()), "check failed: 1 of 1 baseline rows got worse",
                        [f"environment: cpu {nasty}"], [f"1 worse: {nasty}"])
    assert "<script>" not in text and "<img src=x onerror=alert(1)>" not in text and " `tick`" not in text \
        and "[l](http" not in text, text
    assert "\\<script\\>" in text and "\\`tick\\`" in text and "\\*\\*b\\*\\*" in text, text


def test_no_output_of_check_lands_on_a_file_it_reads(gated, tmp_path, capsys, monkeypatch):
    """Issue 46's fourteenth attack: GITHUB_STEP_SUMMARY naming DIR/results.csv (or a link to it) got check's summary
    appended to the table it had just checked, exit 0, no word; every later command on DIR refused the folder. The
    step summary there is a warning and not written; --junit onto a file of DIR, the baseline or the tolerance file
    is refused, exit 2. A new path in DIR stays allowed. Break-checked: without check._reads the table grows."""
    _, baseline, run = gated
    before = (run / "results.csv").read_bytes()
    (tmp_path / "link.csv").symlink_to(run / "results.csv")
    for target in (run / "results.csv", tmp_path / "link.csv", baseline):
        monkeypatch.setenv("GITHUB_STEP_SUMMARY", str(target))
        capsys.readouterr()
        assert _check(run, baseline) == 1
        assert "a file of the folder checked, the baseline or the tolerance file" in capsys.readouterr().err
    assert (run / "results.csv").read_bytes() == before
    monkeypatch.delenv("GITHUB_STEP_SUMMARY")
    for target in (run / "results.csv", baseline):
        assert _check(run, baseline, "--junit", str(target)) == 2
    assert (run / "results.csv").read_bytes() == before
    assert _check(run, baseline, "--junit", str(run / "junit.xml")) == 1 and (run / "junit.xml").is_file()
