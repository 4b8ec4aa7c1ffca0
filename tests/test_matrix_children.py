"""`stereodyn matrix` owns its children (issue 46, finding 11): SIGTERM, SIGINT or SIGKILL of the matrix ends the
environment's run and what that run started; the interrupt line says what to run; a rerun resumes the interrupted
run's folder (its stored runs kept), and never deletes a folder another process is writing; run arguments that run
nothing are refused up front, or a row.

Offline as tests/test_matrix.py: the toy engine's wheels installed with uv from a local folder over this environment
(--overlay), and a stand-in for `stereodyn run` in the environment's own Python (matrix.command replaced; in a
matrix started as a process of its own, by a small driver script)."""
import json
import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import pandas as pd
import pytest

from stereodyn.harness import cli

from test_matrix import DIST, RUN, STAND_IN, offline  # noqa: F401 (offline: the fixture)

pytest.importorskip("uv", reason="stereodyn matrix needs uv (pip install 'stereodyn[matrix]')")

# A run that is still running when the matrix is stopped: it stores a run, starts a grandchild (tied to it by the
# parent-death signal, as a run's pool workers are, when STAND_IN_TIED is set; a plain child otherwise, which only
# the matrix's process-group kill reaches), names both and sleeps.
SLOW_RUN = """
import os, subprocess, sys, time
from pathlib import Path

out = Path(sys.argv[1])
(out / "store").mkdir(exist_ok=True)
(out / "store" / "kept.json").write_text("{}")
options = {}
if os.environ.get("STAND_IN_TIED"):
    from stereodyn.harness.run.processes import parent_death_signal
    options["preexec_fn"] = parent_death_signal
child = subprocess.Popen([sys.executable, "-c", "import time; time.sleep(300)"], **options)
if os.environ.get("STAND_IN_HANDLES"):  # as `stereodyn run` does: SIGTERM ends what it started, tied or not
    import signal
    signal.signal(signal.SIGTERM, lambda *_: (child.kill(), os._exit(143)))
(out.parent / "pids.tmp").write_text(f"{os.getpid()} {child.pid}")
os.replace(out.parent / "pids.tmp", out.parent / "pids")
time.sleep(300)
"""
# The matrix as a process of its own, its run replaced by SLOW_RUN.
DRIVER = """
import sys
from stereodyn.harness import cli
from stereodyn.harness.cli import matrix

matrix.command = lambda python, argv, folder: [str(python), "-c", sys.argv[1], str(folder), *argv]
sys.exit(cli.main(sys.argv[2:]))
"""


def _alive(pid: int) -> bool:
    """Whether pid is a live process (a zombie, dead but not yet reaped by whoever adopted it, counts as dead)."""
    try:
        with open(f"/proc/{pid}/stat") as stat:
            return stat.read().rsplit(")", 1)[1].split()[0] != "Z"
    except FileNotFoundError:
        return False


def _gone(pids: list[int], seconds: float = 15.0) -> bool:
    deadline = time.monotonic() + seconds
    while any(_alive(pid) for pid in pids):
        if time.monotonic() > deadline:
            return False
        time.sleep(0.05)
    return True


def _started_matrix(offline, out: Path, tied: bool, handles: bool = False) -> tuple[subprocess.Popen, list[int]]:
    env = {k: v for k, v in os.environ.items() if k not in ("STAND_IN_TIED", "STAND_IN_HANDLES")}
    env.update({"STAND_IN_TIED": "1"} if tied else {}, **({"STAND_IN_HANDLES": "1"} if handles else {}))
    argv = ["matrix", f"{DIST}==1.0", "--overlay", "--out", str(out), "--", *RUN]
    matrix = subprocess.Popen([sys.executable, "-c", DRIVER, SLOW_RUN, *argv], env=env, stdout=subprocess.PIPE,
                              stderr=subprocess.PIPE, text=True)
    pids_file = out / "runs" / "pids"
    deadline = time.monotonic() + 120
    while not pids_file.is_file():
        assert matrix.poll() is None, matrix.communicate()
        assert time.monotonic() < deadline, "the matrix started no run in two minutes"
        time.sleep(0.05)
    return matrix, [int(p) for p in pids_file.read_text().split()]


@pytest.mark.parametrize("sig, tied, handles", [(signal.SIGTERM, False, False), (signal.SIGINT, False, False),
                                                (signal.SIGKILL, True, False), (signal.SIGKILL, False, True)],
                         ids=["SIGTERM", "SIGINT", "SIGKILL, child tied", "SIGKILL, child a daemon"])
def test_stopping_the_matrix_ends_its_run_and_what_the_run_started(offline, sig, tied, handles):
    """SIGTERM or SIGINT to the matrix's pid alone (not its group): the run and the run's own child, untied, end with
    it, and the last line says to rerun the same matrix command (exit 130 "interrupted"; SIGTERM 143 "terminated
    (SIGTERM)", as every command since issue 46's fifth attack). SIGKILL: the run ends by its parent-death
    signal, and the run's child, tied to the run as a pool worker is, with it (before: both ran on, writing). The
    parent-death signal is SIGTERM, which a run handles as the user's: what it started that no tie reaches (a
    plug-in's daemon) ends too (issue 46's eighth attack, F7: with SIGKILL such daemons were left to init).
    Break-checked: with SIGKILL as the run's parent-death signal the daemon lives on."""
    out = offline / "out"
    matrix, pids = _started_matrix(offline, out, tied, handles)
    try:
        os.kill(matrix.pid, sig)
        _, err = matrix.communicate(timeout=60)
        assert _gone(pids), [pid for pid in pids if _alive(pid)]
        if sig != signal.SIGKILL:
            stopped = "terminated (SIGTERM)" if sig == signal.SIGTERM else "interrupted"
            assert matrix.returncode == (143 if sig == signal.SIGTERM else 130), err
            # "without --rerun": with it, following the line word for word redid every finished run (issue 46's
            # third attack, B4); a rerun without it resumes (test_a_rerun_resumes_the_interrupted_run_...)
            assert err.strip().splitlines()[-1] == (f"stereodyn: {stopped}; the environments built and the runs "
                                                    "finished are kept (rerun the same matrix command, without "
                                                    "--rerun, to go on: it reuses them)"), err
    finally:
        for pid in [matrix.pid, *pids]:
            if _alive(pid):
                os.kill(pid, signal.SIGKILL)


def test_a_rerun_resumes_the_interrupted_run_and_never_deletes_a_folder_being_written(offline, monkeypatch, capsys):
    """After an interrupt the rerun runs `stereodyn run --resume` into the same folder, whose stored runs are kept;
    with --rerun, a folder whose lock another process holds (an orphan still writing it) is refused in one line and
    left as it is."""
    from stereodyn.harness.cli import matrix

    out = offline / "out"
    folder = out / "runs" / f"1-{DIST}==1.0"
    calls = []

    def stopped(python, argv, target):  # the first run is interrupted after it stored a run
        calls.append(argv)
        return [str(python), "-c", "import sys; from pathlib import Path; (Path(sys.argv[1]) / 'store').mkdir(); "
                "(Path(sys.argv[1]) / 'store' / 'kept.json').write_text('{}'); sys.exit(130)", str(target)]

    argv = ["matrix", f"{DIST}==1.0", "--overlay", "--out", str(out), "--", *RUN]
    monkeypatch.setattr(matrix, "command", stopped)
    assert cli.main(argv) == 130
    assert "rerun the same matrix command" in capsys.readouterr().err
    monkeypatch.setattr(matrix, "command", lambda python, run, target: calls.append(run) or
                        [str(python), "-c", STAND_IN, str(target)])
    assert cli.main(argv) == 0
    assert calls == [RUN, [*RUN, "--resume"]], calls
    assert (folder / "store" / "kept.json").is_file()
    assert pd.read_csv(out / "matrix.csv")["status"].tolist() == ["ok"]
    assert cli.main(argv) == 0 and len(calls) == 2  # finished: reused, not run again

    holder = subprocess.Popen([sys.executable, "-c", "import fcntl, os, sys, time; fd = os.open(sys.argv[1], "
                               "os.O_RDONLY); fcntl.flock(fd, fcntl.LOCK_EX); print('locked', flush=True); "
                               "time.sleep(120)", str(folder / "store")], stdout=subprocess.PIPE, text=True)
    try:
        assert holder.stdout.readline() == "locked\n"
        capsys.readouterr()
        assert cli.main([*argv[:-len(RUN) - 1], "--rerun", "--", *RUN]) == 2
    finally:
        holder.kill()
        holder.wait()
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "another stereodyn command is writing to this folder" in err, err
    assert (folder / "store" / "kept.json").is_file() and (folder / "results.csv").is_file()


def test_a_finished_run_another_command_changed_is_resumed_not_reused(offline, monkeypatch, capsys):
    """Issue 46's eleventh attack, F4: the matrix reused a finished run folder ("ok (cached, runs reused)") after a
    plain `stereodyn run --resume` with other arguments had run into it (or been interrupted there): its rows were no
    longer the matrix's run. The stamp seals the runs.json the matrix's run left; any other is resumed with the
    matrix's arguments. Break-checked: without the seal's comparison the third call reuses the folder."""
    from stereodyn.harness.cli import matrix

    out = offline / "out"
    folder = out / "runs" / f"1-{DIST}==1.0"
    calls = []

    def stand_in(python, run, target):
        calls.append(run)
        return [str(python), "-c", STAND_IN + "\nimport sys; (Path(sys.argv[1]) / 'store').mkdir(exist_ok=True)",
                str(target)]

    monkeypatch.setattr(matrix, "command", stand_in)
    argv = ["matrix", f"{DIST}==1.0", "--overlay", "--out", str(out), "--", *RUN]
    assert cli.main(argv) == 0 and cli.main(argv) == 0 and calls == [RUN], calls  # finished: reused
    manifest = json.loads((folder / "runs.json").read_text())
    (folder / "runs.json").write_text(json.dumps({**manifest, "complete": False}))  # another command ran there
    assert cli.main(argv) == 0
    assert calls == [RUN, [*RUN, "--resume"]], calls
    assert cli.main(argv) == 0 and len(calls) == 2  # finished as the matrix's run: reused again


def test_an_overlay_environment_is_another_when_a_plugins_source_changed(monkeypatch):
    """Issue 46's eleventh attack, F7: with --overlay the plug-ins are this environment's; after one was edited
    the same matrix reused the runs of the old code. The overlay's key holds the plug-ins' sources
    (environment.plugin_sources), so an edit is another environment. Break-checked: without them the keys agree."""
    from stereodyn.harness import environment as env_info
    from stereodyn.harness.run import environments

    monkeypatch.setattr(env_info, "plugin_sources", lambda: "a" * 24)
    before = environments.key(("numpy==2.4.6",), "stereodyn==0.3.0", True)
    assert environments.key(("numpy==2.4.6",), "stereodyn==0.3.0", False) != before
    monkeypatch.setattr(env_info, "plugin_sources", lambda: "b" * 24)
    assert environments.key(("numpy==2.4.6",), "stereodyn==0.3.0", True) != before


def test_the_plugin_sources_change_with_a_plugins_file_and_import_nothing(tmp_path, monkeypatch):
    """plugin_sources hashes the files of the modules the entry points name, found without importing them."""
    from stereodyn.harness import environment as env_info

    package = tmp_path / "edited_plugin"
    package.mkdir()
    (package / "__init__.py").write_text("raise SystemExit('imported')\n")
    monkeypatch.syspath_prepend(str(tmp_path))

    class Entry:
        value = "edited_plugin:Engine"

    monkeypatch.setattr(env_info.metadata, "entry_points",
                        lambda group: [Entry()] if group == "stereodyn.engines" else [])
    first = env_info.plugin_sources()
    (package / "__init__.py").write_text("raise SystemExit('imported, edited')\n")
    assert env_info.plugin_sources() != first


@pytest.mark.parametrize("run_args", [["--help"], ["-h"], ["free-asymmetric", "--hel"], ["--h"]])
def test_run_arguments_that_run_nothing_are_refused_up_front(tmp_path, capsys, run_args):
    """`matrix A -- --help` would print the run's help in every environment and leave no results: one line, exit 2,
    before any environment is built (before: exit 2 with no matrix.csv, after building them)."""
    assert cli.main(["matrix", "mujoco==4.0.0", "--out", str(tmp_path / "o"), "--", *run_args]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "prints the run's help and runs nothing" in err, err
    assert not (tmp_path / "o").exists()


@pytest.mark.parametrize("run_args, words", [
    (["--bogus"], "matrix: after --: unrecognized arguments: --bogus"),
    (["free-asymmetric", "--dt", "0"], "matrix: after --: argument --dt: must be finite and in"),
    (["no-such-case"], "matrix: after --: "),
    (["--certify", "--no-certify"], "matrix: after --: --certify and --no-certify"),
    # run's check_options, the matrix's too (it repeated two of them; this one it lacked)
    (["--ladder-max-steps", "3"], "matrix: after --: --ladder-max-steps: must be >= 40, got 3"),
], ids=["unknown option", "dt 0", "unknown case", "certify twice", "ladder too short"])
def test_run_arguments_this_stereodyn_refuses_are_refused_up_front(tmp_path, capsys, run_args, words):
    """Issue 46's fourth attack, F6: `matrix A -- --bogus` (or --dt 0, a case the suite lacks) built every environment
    and ended exit 0, "0 of 1 environments ran", a `run failed` row each. Refused before anything is built: one line,
    exit 2. Break-checked: without check_run_arguments each case reaches uv."""
    assert cli.main(["matrix", "mujoco==4.0.0", "--out", str(tmp_path / "o"), "--", *run_args]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and words in err, err
    assert not (tmp_path / "o").exists()


def test_a_run_that_exits_0_without_results_is_a_row(offline, monkeypatch):
    """What the up-front check cannot foresee (an environment whose stereodyn prints and exits 0): a row saying so,
    and the matrix goes on to write matrix.csv."""
    from stereodyn.harness.cli import matrix

    out = offline / "out"
    monkeypatch.setattr(matrix, "command", lambda python, argv, folder: [str(python), "-c", "print('usage: ...')"])
    assert cli.main(["matrix", f"{DIST}==1.0", "--overlay", "--out", str(out), "--", *RUN]) == 0
    row = pd.read_csv(out / "matrix.csv", keep_default_na=False).iloc[0]
    assert row["status"] == "run failed" and "exited 0 but wrote no results.csv" in row["reason"], row
