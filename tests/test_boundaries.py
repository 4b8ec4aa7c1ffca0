"""Hardened boundaries (issue 16): every hostile input ends in exit 0 with rows carrying a status and a reason, or in
exit 2 with one line and no traceback; names are data; one folder tells one story."""
import json
import os
import signal
import subprocess
import sys
import time
import xml.etree.ElementTree as ET
from pathlib import Path

import pandas as pd
import pytest

from child_processes import alive_in
from helpers import FAST, case_file, one_line_error, tiny_case

from stereodyn.harness.run import pool as run_pool
from stereodyn.harness import cli
from stereodyn.harness.report.build import figure_stem
from stereodyn.harness.run.store import Store, StoreBusy, folder_lock

BASE = tiny_case()  # a small valid body; each hostile input below replaces one line of it


# --- 1. numbers at the boundary: the inputs the issue lists, each exit 2 naming the key (or data, below)

@pytest.mark.parametrize("old, new, key", [
    ("[run]", "[gravity]\ng = 1e308\n[run]", "gravity.g"),
    ("[run]", "[body_torque]\naxis = [0.0, 0.0, 1.0]\na = 1e308\nb = 0.0\n[run]", "body_torque.a"),
    ("com = [0.0, 0.0, 0.0]\nprincipal_moments = [2.0, 1.5, 1.0]",
     "com = [0.0, 0.0, 0.0]\nprincipal_moments = [2.0, 1.5, 1.0]\n[central_field]\nmu = 1e308\nradius = 1.0\n"
     "direction = [0.0, 0.0, 1.0]", "central_field.mu"),
    ("com = [0.0, 0.0, 0.0]\nprincipal_moments = [2.0, 1.5, 1.0]",
     "com = [0.0, 0.0, 0.0]\nprincipal_moments = [2.0, 1.5, 1.0]\n[central_field]\nmu = 1.0\nradius = 5e-324\n"
     "direction = [0.0, 0.0, 1.0]", "central_field.radius"),
    ("com = [0.0, 0.0, 0.0]\nprincipal_moments = [2.0, 1.5, 1.0]",
     "com = [0.0, 0.0, 0.0]\nprincipal_moments = [2.0, 1.5, 1.0]\n[central_field]\nmu = 1.0\nradius = 1.0\n"
     "direction = [0.0, 0.0, 1.0]\norbit_rate = 1e308", "central_field.orbit_rate"),
    ("[run]", "[precession_torque]\ntheta = 1e-300\nl = 0.0\nm3 = 0.0\n[run]", "precession_torque.theta"),
    ("[run]", "[precession_torque]\ntheta = 1.0\nl = 1e308\nm3 = 0.0\n[run]", "precession_torque.l"),
    ("principal_moments = [2.0, 1.5, 1.0]", "principal_moments = [1e308, 1e308, 1e308]", "principal_moments[0]"),
    ("principal_moments = [2.0, 1.5, 1.0]", "principal_moments = [5e-324, 5e-324, 5e-324]", "principal_moments[0]"),
    ("principal_moments = [2.0, 1.5, 1.0]", "principal_moments = [1e-300, 1e-300, 1e-300]", "principal_moments[0]"),
    ("principal_moments = [2.0, 1.5, 1.0]", "inertia = [[1e308, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0]]",
     "body.inertia[0][0]"),
    ("omega = [0.4, 0.1, 2.0]", "omega = [1e308, 0.0, 0.0]", "initial.omega[0]"),
    ("com = [0.0, 0.0, 0.0]", "com = [1e200, 0.0, 0.0]", "body.com[0]"),
    ("euler_zxz = [0.3, 0.8, -0.5]", "euler_zxz = [1e308, 1e308, 1e308]", "euler_zxz[0]"),
    ("euler_zxz = [0.3, 0.8, -0.5]", "gibbs = [1e200, 0.0, 0.0]", "gibbs[0]"),
    ("samples = 11", "samples = 9223372036854775807", "run.samples"),
    ("samples = 11", "samples = 100000000", "run.samples"),
    ("samples = 11", "samples = 1" + "0" * 400, "run.samples"),
    ("dt = [1e-2]", "dt = [1e-2" + ", 1e-2" * 40 + "]", "run.dt"),
    ("t_end = 0.1", "t_end = 1e5", "run.dt[0]"),  # 1e7 steps of 1e-2 allowed, 1e7 + ... not: t_end/dt = 1e7
    ("name = \"base\"", "name = \"a\\u0001b\"", "name"),
])
def test_out_of_range_numbers_exit_2_naming_the_key(tmp_path, capsys, old, new, key):
    text = BASE.replace(old, new, 1)
    assert text != BASE
    if key == "run.dt[0]":
        text = text.replace("t_end = 1e5", "t_end = 1e6")  # 1e8 steps of 1e-2: over MAX_STEPS
    path = case_file(tmp_path, text)
    one_line_error(cli.main(["run", "--case-file", str(path), "--out", str(tmp_path / "out"), *FAST]), capsys,
                   str(path), key)


def test_deep_nesting_and_a_byte_order_mark(tmp_path, capsys):
    deep = case_file(tmp_path, BASE + "x = " + "[" * 5000 + "]" * 5000 + "\n", "deep.toml")
    one_line_error(cli.main(["run", "--case-file", str(deep), *FAST]), capsys, "nested too deep")
    deep = case_file(tmp_path, BASE + "y = " + "{a = " * 3000 + "1" + "}" * 3000 + "\n", "deep2.toml")
    one_line_error(cli.main(["run", "--case-file", str(deep), *FAST]), capsys, "deep2.toml")
    bom = tmp_path / "bom.toml"
    bom.write_bytes(b"\xef\xbb\xbf" + BASE.encode())
    assert cli.main(["run", "--case-file", str(bom), "--out", str(tmp_path / "out"), *FAST]) == 0
    assert list(pd.read_csv(tmp_path / "out" / "results.csv").status) == ["ok"]


def test_a_truth_that_cannot_be_computed_fails_its_rows_and_the_sweep_goes_on(tmp_path):
    """(a + b |ω|²) u with b = 1e6 on a unit body blows up at t ~ 1e-6 s: heyoka stops on a non-finite state. Every
    run of that case is `failed` with the reason; the other case's runs are ok."""
    blow = case_file(tmp_path, BASE.replace("name = \"base\"", "name = \"blow-up\"").replace(
        "[run]", "[body_torque]\naxis = [0.0, 0.0, 1.0]\na = 0.0\nb = 1e6\n[run]"), "blow.toml")
    good = case_file(tmp_path, BASE, "good.toml")
    out = tmp_path / "out"
    assert cli.main(["run", "--case-file", str(blow), "--case-file", str(good), "--out", str(out), *FAST]) == 0
    df = pd.read_csv(out / "results.csv")
    assert set(df.case) == {"blow-up", "base"}
    blown = df[df.case == "blow-up"]
    assert len(blown) == 1 and set(blown.status) == {"failed"}
    assert blown.message.str.startswith("truth failed: ValueError: truth propagation (double) stopped").all()
    assert set(df[df.case == "base"].status) == {"ok"}


# --- the command line's options

@pytest.mark.parametrize("argv, expected", [
    (["run", "--engines", ""], "--engines"),
    (["run", "--integrators", ""], "--integrators"),
    (["run", "--engines", "mujoco,mujoco"], "mujoco given twice"),
    (["run", "--engines", "mujoco,,pinocchio"], "empty name"),
    (["run", "--dt", "0"], "--dt"),
    (["run", "--dt", "-1"], "--dt"),
    (["run", "--dt", "nan"], "--dt"),
    (["run", "--dt", "5e-324"], "--dt"),
    (["run", "--t-end", "1e308"], "--t-end"),
    (["run", "--t-end", "1e300"], "--t-end"),
    (["run", "--t-end", "inf"], "--t-end"),
    (["run", "--jobs", "-3"], "--jobs"),
    (["run", "--jobs", "x"], "--jobs"),
    (["run", "--ladder-max-steps", "1"], "--ladder-max-steps"),
    (["run", "--dt-ladder", "--no-ladder"], "--dt-ladder and --no-ladder"),
    (["run", "free-asymmetric", "--dt", "0.5", "--t-end", "0.1"], "--dt: with case 'free-asymmetric'"),
    (["run", "free-asymmetric", "--t-end", "1e-3"], "--t-end: with case 'free-asymmetric'"),
    (["run", "free-asymmetric", "--t-end", "1e6"], "--t-end"),  # 1e6 / 1e-3 = 1e9 steps
    (["run", "--no-such-option"], "unrecognized arguments"),
    (["export", "free-asymmetric", "--format", "mjcf", "--dt", "0"], "--dt"),
    (["export", "free-asymmetric", "--format", "mjcf", "--dt", "inf"], "--dt"),
])
def test_bad_options_exit_2_with_one_line(argv, expected, capsys, tmp_path):
    code = cli.main(argv + ["--out", str(tmp_path / "out.x")] if argv[0] == "run" else argv)
    one_line_error(code, capsys, expected)
    assert not (tmp_path / "out.x").exists()  # validated before anything was written


def test_jobs_are_capped_at_the_number_of_runs(tmp_path, monkeypatch):
    seen = []
    original = run_pool.WatchedPool

    def pool(jobs, *args, **kwargs):
        seen.append(jobs)
        return original(jobs, *args, **kwargs)

    monkeypatch.setattr(run_pool, "WatchedPool", pool)
    path = case_file(tmp_path, BASE.replace("dt = [1e-2]", "dt = [1e-2, 5e-3]"))
    assert cli.main(["run", "--case-file", str(path), "--engines", "mujoco", "--integrators", "rk4", "--jobs", "16",
                     "--quiet", "--out", str(tmp_path / "out")]) == 0
    assert seen == [2]  # two runs, two workers (not 16)


# --- 3. names are data

def test_a_name_with_a_double_quote_runs_everywhere_and_exports_xml_that_parses(tmp_path, capsys):
    # quotes and an apostrophe (XML attribute delimiters); < & > are Markdown markup, refused since issue 46's
    # eleventh attack (test_a_case_name_shows_as_itself_in_markdown)
    name = 'say "hi" it\'s -- (x)'
    path = case_file(tmp_path, BASE.replace('name = "base"', f"name = {json.dumps(name)}"))
    out = tmp_path / "out"
    assert cli.main(["run", "--case-file", str(path), "--engines", "mujoco,pinocchio", "--integrators", "rk4",
                     "--jobs", "1", "--quiet", "--out", str(out)]) == 0
    df = pd.read_csv(out / "results.csv")
    assert set(df.engine) == {"mujoco", "pinocchio"} and set(df.status) == {"ok"} and set(df.case) == {name}
    for fmt, root in (("mjcf", "model"), ("urdf", "name")):
        target = tmp_path / f"model.{fmt}"
        assert cli.main(["export", str(path), "--format", fmt, "--out", str(target)]) == 0
        assert ET.parse(target).getroot().get(root) == name


def test_a_name_longer_than_200_characters_is_one_line_exit_2(tmp_path, capsys):
    """docs/limits.md: a name is in every row and table (100 000 characters made a 38 MB results.csv)."""
    path = case_file(tmp_path, BASE.replace('name = "base"', f'name = "{"x" * 201}"'))
    one_line_error(cli.main(["run", "--case-file", str(path), "--out", str(tmp_path / "out"), *FAST]), capsys,
                   str(path), "name: must be at most 200 characters", "got 201")


# slow (issue 28: the default suite within 8 min on 2 idle cores): 20-80 s at load ~6; `pytest -m slow` runs it
@pytest.mark.slow
def test_two_non_ascii_names_keep_distinct_bounded_figures(tmp_path):
    names = ["тело", "物体", "x" * 200]  # the longest name allowed
    stems = {figure_stem(n) for n in names}
    assert len(stems) == 3 and all(len(s) <= 49 and s.isascii() for s in stems)
    files = [case_file(tmp_path, BASE.replace('name = "base"', f'name = "{n}"'), f"c{i}.toml")
             for i, n in enumerate(names)]
    out = tmp_path / "out"
    argv = ["run", *[a for f in files for a in ("--case-file", str(f))], "--out", str(out), *FAST]
    assert cli.main(argv) == 0
    figures = sorted(p.name for p in (out / "figures").glob("*.png"))
    assert figures == sorted(f"{figure_stem(n)}-{k}.png" for n in names for k in ("invariants", "work-precision"))
    report = (out / "report.md").read_text()
    assert all(f"figures/{figure_stem(n)}-invariants.png" in report for n in names)


# --- 4. paths and malformed files

def test_unwritable_output_paths_exit_2_with_one_line(tmp_path, capsys):
    path = case_file(tmp_path, BASE)
    a_file = tmp_path / "file.txt"
    a_file.write_text("x")
    for out in (a_file, a_file / "under", Path("/dev/null"), Path("/proc/x")):
        one_line_error(cli.main(["run", "--case-file", str(path), "--out", str(out), *FAST]), capsys, "--out")
        one_line_error(cli.main(["export", str(path), "--format", "mjcf", "--out", str(out / "m.xml")]), capsys,
                       "--out")
    one_line_error(cli.main(["export", str(path), "--format", "urdf", "--out", str(tmp_path)]), capsys, "is a folder")
    good = tmp_path / "good"
    assert cli.main(["run", "--case-file", str(path), "--out", str(good), *FAST]) == 0
    one_line_error(cli.main(["baseline", str(good), "--out", str(a_file / "b.json")]), capsys, "--out")
    # a folder whose store/ is a file: that file is named, not the folder (issue 46's twelfth attack)
    (tmp_path / "odd").mkdir()
    (tmp_path / "odd" / "store").write_text("x")
    one_line_error(cli.main(["run", "--case-file", str(path), "--out", str(tmp_path / "odd"), *FAST]), capsys,
                   f"--out {tmp_path / 'odd'}: {tmp_path / 'odd' / 'store'} is not a folder")


def test_run_out_into_a_folder_of_another_tools_tables_is_refused(tmp_path, capsys):
    """A folder holding results.csv (or report.md) but no runs.json is not a run of ours: `run --out` refuses it and
    leaves the file as it was (issue 46's re-attack: it was overwritten); a folder of other files, and a run folder of
    ours, are run into."""
    path = case_file(tmp_path, BASE)
    for name in ("results.csv", "report.md"):
        theirs = tmp_path / f"theirs-{name}"
        theirs.mkdir()
        (theirs / name).write_text("their,table\n1,2\n")
        one_line_error(cli.main(["run", "--case-file", str(path), "--out", str(theirs), *FAST]), capsys,
                       f"holds {name} but no runs.json")
        assert (theirs / name).read_text() == "their,table\n1,2\n" and not (theirs / "store").exists()
    mixed = tmp_path / "mixed"
    mixed.mkdir()
    (mixed / "notes.txt").write_text("mine")
    for _ in range(2):  # then a run folder of ours: rerun in place
        assert cli.main(["run", "--case-file", str(path), "--out", str(mixed), *FAST]) == 0
    assert (mixed / "notes.txt").read_text() == "mine"


@pytest.mark.parametrize("name, text", [
    ("results.csv", ""),
    ("results.csv", "\x00\x01garbage\n\"unclosed"),
    ("results.csv", "a,b\n1,2\n"),
    ("results.csv", "case,engine,integrator,status,dt\nx,mujoco,rk4,ok,not-a-number\n"),
])
def test_malformed_results_exit_2_in_report_baseline_and_check(swept, tmp_path, capsys, name, text):
    """docs/limits.md, "Files stereodyn reads back": each command refuses the table with one line naming it (check
    against a good baseline, so that the table is what it judges)."""
    good = tmp_path / "good.json"
    assert cli.main(["baseline", str(swept[0]), "--out", str(good)]) == 0
    folder = tmp_path / "bad"
    folder.mkdir()
    (folder / name).write_text(text)
    capsys.readouterr()
    for argv in (["report", str(folder)], ["baseline", str(folder), "--out", str(tmp_path / "b.json")],
                 ["check", str(folder), "--baseline", str(good)]):
        one_line_error(cli.main(argv), capsys, f"{folder / name}: ")
    assert not (tmp_path / "b.json").exists()


@pytest.fixture(scope="module")
def swept(tmp_path_factory):
    out = tmp_path_factory.mktemp("swept")
    path = case_file(out.parent, BASE, "swept.toml")
    assert cli.main(["run", "--case-file", str(path), "--out", str(out), *FAST]) == 0
    return out, path


@pytest.mark.parametrize("name, text, code", [
    ("results.csv", "case,engine,formulation,integrator,dt,t_end,steps,status,message\n", 2),  # a crashed sweep's
    ("runs.json", '{"format": 1, "runs": {"a": 1}, "environment": []}', 0),
    ("runs.json", "[1, 2]", 0),
    ("checks.csv", "", 2),
    ("answers.csv", "\x00garbage,\n\"x", 2),  # the report reads answers.csv, not pareto.csv
])
def test_report_on_a_malformed_table_is_one_line_or_ignores_it(swept, tmp_path, capsys, name, text, code):
    """docs/limits.md: results.csv without rows is an error; a runs.json of the wrong shape counts as absent (the
    folder reads as one without a completion mark: one warning line, the report is written); a derived table the
    report cannot parse is an error."""
    import shutil

    out = tmp_path / "copy"
    shutil.copytree(swept[0], out)
    (out / name).write_text(text)
    (out / "report.html").unlink()
    assert cli.main(["report", str(out)]) == code
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "Traceback" not in err, err
    if code == 2:
        assert err.startswith("stereodyn: error: ") and str(out) in err and not (out / "report.html").exists()
    else:
        assert err.startswith("stereodyn: warning: ") and (out / "report.html").is_file()


def test_a_malformed_store_record_is_absent_and_recomputed(swept, tmp_path):
    import shutil

    out = tmp_path / "copy"
    shutil.copytree(swept[0], out)
    (record,) = (out / "store").glob("*.json")
    data = json.loads(record.read_text())
    data["row"]["status"] = "weird"
    record.write_text(json.dumps(data))
    assert cli.main(["run", "--case-file", str(swept[1]), "--out", str(out), "--resume", *FAST]) == 0
    assert list(pd.read_csv(out / "results.csv").status) == ["ok"]
    assert json.loads(record.read_text())["row"]["status"] == "ok"


# --- 5. one folder, one story

# slow (issue 28: the default suite within 8 min on 2 idle cores): 20-80 s at load ~6; `pytest -m slow` runs it
@pytest.mark.slow
def test_the_lock_covers_the_whole_command(tmp_path, monkeypatch, capsys):
    """While `run` writes its report, the folder is locked against every other descriptor; a second command into
    the folder exits 2 with one line."""
    import fcntl

    from stereodyn.harness.report import build

    held = []
    original = build.write_reports

    def spy(out_dir, df=None, **options):
        fd = os.open(out_dir / "store", os.O_RDONLY)
        try:
            fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
            held.append(False)
        except BlockingIOError:
            held.append(True)
        finally:
            os.close(fd)
        return original(out_dir, df, **options)

    monkeypatch.setattr(build, "write_reports", spy)
    path = case_file(tmp_path, BASE)
    out = tmp_path / "out"
    assert cli.main(["run", "--case-file", str(path), "--out", str(out), *FAST]) == 0
    assert held == [True]
    capsys.readouterr()
    with folder_lock(out):
        child = subprocess.run([sys.executable, "-m", "stereodyn", "run", "--case-file", str(path), "--out",
                                str(out), *FAST], capture_output=True, text=True, timeout=120)
        assert child.returncode == 2 and child.stderr.count("\n") == 1, child.stderr
        assert "another stereodyn command is writing to this folder" in child.stderr
        child = subprocess.run([sys.executable, "-m", "stereodyn", "report", str(out)], capture_output=True,
                               text=True, timeout=120)
        assert child.returncode == 2 and child.stderr.count("\n") == 1, child.stderr
    with Store(out):  # one process, one Store: a second is refused
        with pytest.raises(StoreBusy):
            Store(out).__enter__()


@pytest.mark.slow  # since 2026-12-02, ~17 s; by default test_store.py's killed sweep that resumes (the default suite's 8 minutes)
@pytest.mark.skipif(not Path("/proc/self/stat").exists(), reason="reads /proc")
def test_a_sigkilled_sweep_leaves_no_process_and_the_next_run_no_temporary(tmp_path):
    path = case_file(tmp_path, BASE.replace("t_end = 0.1", "t_end = 2.0").replace("dt = [1e-2]",
                                                                                   "dt = [1e-2, 5e-3, 2e-3, 1e-3]"))
    out = tmp_path / "out"
    argv = ["run", "--case-file", str(path), "--engines", "mujoco,pinocchio", "--jobs", "2", "--quiet",
            "--out", str(out)]
    log = (tmp_path / "stderr").open("w")
    process = subprocess.Popen([sys.executable, "-m", "stereodyn", *argv], stdout=subprocess.DEVNULL, stderr=log,
                               start_new_session=True)
    try:
        deadline = time.monotonic() + 120
        while len(list((out / "store").glob("*.json"))) < 2:
            assert process.poll() is None, (tmp_path / "stderr").read_text()
            assert time.monotonic() < deadline
            time.sleep(0.02)
        assert len(alive_in(session=process.pid)) >= 3  # the sweep and its two workers at least
        os.kill(process.pid, signal.SIGKILL)  # the parent alone: its workers are orphaned
        process.wait()
        # the orphaned workers poll their parent every PARENT_POLL_S = 0.5 s (harness/run/processes.py) and are gone
        # ~0.5 s later on an idle machine; the 60 s bound only keeps a loaded machine from failing the test (under
        # load it failed the former fixed 5 s wait), it is not a timing check
        deadline = time.monotonic() + 60
        while alive_in(session=process.pid) and time.monotonic() < deadline:
            time.sleep(0.1)
        assert alive_in(session=process.pid) == []
    finally:
        for pid in alive_in(session=process.pid):
            os.kill(pid, signal.SIGKILL)
    (out / "figures").mkdir(exist_ok=True)
    for leftover in (out / ".results.csv.abc.tmp", out / "figures" / ".x.png.abc.tmp", out / "store" / ".k.json.tmp"):
        leftover.write_text("partial")
    assert cli.main(["run", "--case-file", str(path), "--engines", "mujoco", "--integrators", "rk4", "--resume",
                     "--jobs", "1", "--quiet", "--out", str(out)]) == 0
    assert not [p for p in out.rglob("*") if p.name.endswith(".tmp")]


def test_interrupted_while_importing_is_one_line(monkeypatch, capsys):
    def interrupted():
        raise KeyboardInterrupt

    from stereodyn.harness.cli import dispatch

    monkeypatch.setattr(dispatch, "_load", interrupted)  # the entry point is cli.dispatch since the cli split
    assert cli.main(["cases"]) == 130
    err = capsys.readouterr().err
    assert err == "stereodyn: interrupted\n"


@pytest.mark.slow  # since 2026-12-02, ~6 s; by default test_warp.py's and the CI output tests' empty stderr (the default suite's 8 minutes)
def test_no_warnings_on_stderr_and_the_mujoco_log_under_out(tmp_path):
    """A diverging MuJoCo run (explicit Euler far past its stability limit) warns; nothing of it reaches stderr
    nor the working directory."""
    path = case_file(tmp_path, BASE.replace("omega = [0.4, 0.1, 2.0]", "omega = [40.0, 10.0, 200.0]")
                     .replace("t_end = 0.1", "t_end = 1.0").replace("dt = [1e-2]", "dt = [0.05]"))
    work = tmp_path / "cwd"
    work.mkdir()
    child = subprocess.run([sys.executable, "-m", "stereodyn", "run", "--case-file", str(path), "--engines",
                            "mujoco,pinocchio", "--jobs", "1", "--quiet", "--out", str(tmp_path / "out")], cwd=work,
                           capture_output=True, text=True, timeout=120)
    assert child.returncode == 0, child.stderr
    assert child.stderr == "", child.stderr
    assert list(work.iterdir()) == []
    df = pd.read_csv(tmp_path / "out" / "results.csv")
    assert "diverged" in set(df.status)
