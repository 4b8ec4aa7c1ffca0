"""The result store: keys, atomic records, --resume, and sweeps interrupted by SIGKILL and Ctrl-C (SIGINT)."""
import dataclasses
import json
import os
import shutil
import signal
import subprocess
import sys
import time
from pathlib import Path

import pandas as pd
import pytest
from helpers import TIMINGS, store_mtimes, without_timings

from stereodyn.harness import cli
from stereodyn.harness.scenes.cases import find_case
from stereodyn.harness.run.store import Store, StoreBusy, run_identity, run_key

# Two cases, both simulators, 32 runs; the slowest take ~0.1 s, so a sweep on one process lasts a few seconds.
SWEEP = ["lagrange-top", "kovalevskaya", "--engines", "mujoco,pinocchio", "--t-end", "2", "--dt", "1e-2,3e-3",
         "--quiet"]


def table(out: Path) -> pd.DataFrame:
    """results.csv less its timings and the timing phase's marks (helpers.without_timings)."""
    return without_timings(pd.read_csv(out / "results.csv"))


@pytest.fixture(scope="module")
def uninterrupted(tmp_path_factory):
    out = tmp_path_factory.mktemp("full")
    assert cli.main(["run", *SWEEP, "--jobs", "1", "--out", str(out)]) == 0
    return out


def test_the_key_changes_with_what_a_row_depends_on():
    case = find_case("lagrange-top")
    versions = {"mujoco": "4.0.0"}
    base = run_key(run_identity(case, "mujoco", "", "rk4", 1e-2, False, versions))
    assert base == run_key(run_identity(case, "mujoco", "", "rk4", 1e-2, False, dict(versions)))
    heavier = dataclasses.replace(case, mass=case.mass * (1 + 1e-15))  # bit-exact: the last bit counts
    variants = [run_identity(heavier, "mujoco", "", "rk4", 1e-2, False, versions),
                run_identity(case, "pinocchio", "", "rk4", 1e-2, False, versions),
                run_identity(case, "mujoco", "gibbs", "rk4", 1e-2, False, versions),
                run_identity(case, "mujoco", "", "euler", 1e-2, False, versions),
                run_identity(case, "mujoco", "", "rk4", 3e-3, False, versions),
                run_identity(case, "mujoco", "", "rk4", 1e-2, True, versions),
                run_identity(case, "mujoco", "", "rk4", 1e-2, False, {"mujoco": "4.0.1"}),
                run_identity(case, "mujoco", "", "rk4", 1e-2, False, versions, precision="float32")]
    keys = {run_key(identity) for identity in variants}
    assert base not in keys and len(keys) == len(variants)
    # A case's description and file path are not physics: same key.
    described = dataclasses.replace(case, description="other words", path=None)
    assert run_key(run_identity(described, "mujoco", "", "rk4", 1e-2, False, versions)) == base


def test_one_sweep_per_folder_and_leftovers_are_removed(tmp_path):
    (tmp_path / "store").mkdir()
    leftover = tmp_path / "store" / ".abc.json.x1y2.tmp"
    leftover.write_text('{"format": 1, "ro')
    with Store(tmp_path):
        assert not leftover.exists()
        with pytest.raises(StoreBusy):
            Store(tmp_path).__enter__()
    with Store(tmp_path):  # released on exit
        pass


def test_resume_reuses_every_stored_run(uninterrupted, tmp_path):
    out = tmp_path / "copy"
    shutil.copytree(uninterrupted, out)
    before, first = store_mtimes(out), pd.read_csv(out / "results.csv")
    assert len(before) == len(first)
    assert cli.main(["run", *SWEEP, "--jobs", "1", "--out", str(out), "--resume"]) == 0
    assert store_mtimes(out) == before  # nothing recomputed, nothing rewritten
    pd.testing.assert_frame_equal(pd.read_csv(out / "results.csv"), first)  # timings included: they are stored
    pd.testing.assert_frame_equal(table(out), table(uninterrupted))
    manifest = json.loads((out / "runs.json").read_text())
    assert sorted(f"{key}.json" for key in manifest["runs"]) == sorted(before)


def test_without_resume_every_run_is_redone(tmp_path):
    argv = ["run", "free-asymmetric", "--engines", "mujoco", "--integrators", "euler", "--t-end", "0.2", "--dt",
            "1e-2", "--jobs", "1", "--quiet", "--out", str(tmp_path)]
    assert cli.main(argv) == 0
    before = store_mtimes(tmp_path)
    time.sleep(0.01)
    assert cli.main(argv) == 0
    after = store_mtimes(tmp_path)
    assert after.keys() == before.keys() and all(after[k] > before[k] for k in before)


def _interrupted(out: Path, sig: int, jobs: str, at_least: int) -> tuple[int, dict]:
    """Start the sweep in its own process group, send `sig` to the group once `at_least` runs are stored."""
    log = out.parent / f"{out.name}.stderr"  # a file, not a pipe: a full pipe would stall the sweep
    with log.open("w") as stderr:
        process = subprocess.Popen([sys.executable, "-m", "stereodyn.harness.cli", "run", *SWEEP, "--jobs", jobs, "--out",
                                    str(out)], stdout=subprocess.DEVNULL, stderr=stderr, start_new_session=True)
    try:
        deadline = time.monotonic() + 120
        while not (out / "store").is_dir() or len(store_mtimes(out)) < at_least:
            assert process.poll() is None, log.read_text()
            assert time.monotonic() < deadline, "the sweep stored nothing in two minutes"
            time.sleep(0.01)
        os.killpg(process.pid, sig)  # the group: the sweep and its workers, as Ctrl-C in a terminal does
        code = process.wait(timeout=60)
        if sig == signal.SIGINT:
            assert "interrupted; every finished run is stored" in log.read_text(), log.read_text()
    finally:
        if process.poll() is None:
            os.killpg(process.pid, signal.SIGKILL)
            process.wait()
    return code, store_mtimes(out)


def _no_partial_files(out: Path) -> None:
    assert not [p for p in out.rglob("*") if p.name.endswith(".tmp")]
    for path in (out / "store").glob("*.json"):
        json.loads(path.read_text())  # every record is whole


def test_a_killed_sweep_resumes_to_the_uninterrupted_table(uninterrupted, tmp_path):
    out = tmp_path / "sweep"
    total = len(pd.read_csv(uninterrupted / "results.csv"))
    code, stored = _interrupted(out, signal.SIGKILL, "1", at_least=4)
    assert code == -signal.SIGKILL and 4 <= len(stored) < total
    # results.csv is refreshed from the store at most every PUBLISH_EVERY_S, so after a SIGKILL it may lag the store
    # (which is what --resume reads); it is never a partial file: it parses, and holds no more runs than were done.
    partial = pd.read_csv(out / "results.csv")
    assert len(partial) <= total
    rows = {name: json.loads((out / "store" / name).read_text())["row"] for name in stored}
    assert cli.main(["run", *SWEEP, "--jobs", "1", "--out", str(out), "--resume"]) == 0
    after = store_mtimes(out)
    # what was done was not redone: a record is rewritten only when the kill came before the sweep's timing phase,
    # which then times again, with repeats, a run its worker timed once, and changes nothing else
    for name, mtime in stored.items():
        if after[name] != mtime:
            row = json.loads((out / "store" / name).read_text())["row"]
            assert rows[name].get("timing") == "single" and row.get("timing", "").startswith("best of")
            assert {k: v for k, v in row.items() if k not in TIMINGS} == {
                k: v for k, v in rows[name].items() if k not in TIMINGS}
    pd.testing.assert_frame_equal(table(out), table(uninterrupted))
    _no_partial_files(out)


def test_ctrl_c_stops_a_parallel_sweep_keeping_every_finished_run(uninterrupted, tmp_path):
    out = tmp_path / "sweep"
    total = len(pd.read_csv(uninterrupted / "results.csv"))
    code, stored = _interrupted(out, signal.SIGINT, "2", at_least=3)
    assert code == 130 and 3 <= len(stored) < total
    _no_partial_files(out)
    assert cli.main(["run", *SWEEP, "--jobs", "2", "--out", str(out), "--resume"]) == 0
    pd.testing.assert_frame_equal(table(out), table(uninterrupted))
    _no_partial_files(out)


def test_a_run_whose_worker_died_is_not_stored_and_is_retried(tmp_path, monkeypatch):
    from stereodyn.harness.run import pool as run_pool

    argv = ["run", "free-asymmetric", "--engines", "mujoco", "--integrators", "euler,rk4", "--t-end", "0.2",
            "--dt", "1e-2", "--jobs", "1", "--quiet", "--out", str(tmp_path)]
    real = run_pool.sweep_run

    def crash_rk4(spec, truth, budgets=None):
        if spec.integrator == "rk4":
            return run_pool.worker_failed_row(spec, BrokenPipeError("worker gone"))
        return real(spec, truth, budgets)

    monkeypatch.setattr(run_pool, "sweep_run", crash_rk4)
    assert cli.main(argv) == 0
    first = pd.read_csv(tmp_path / "results.csv").set_index("integrator")
    assert first.loc["rk4", "status"] == "failed" and first.loc["rk4", "message"].startswith("worker process failed")
    assert len(store_mtimes(tmp_path)) == 1  # only the euler run is stored
    monkeypatch.setattr(run_pool, "sweep_run", real)
    assert cli.main([*argv, "--resume"]) == 0
    assert set(pd.read_csv(tmp_path / "results.csv").status) == {"ok"} and len(store_mtimes(tmp_path)) == 2


def test_runs_json_records_the_load_at_the_timing_phases_start_and_end(uninterrupted):
    """Issue 32: timings come from a shared machine; runs.json's environment (the report's Environment section) says
    how busy it was when the timing phase began and ended. Break-check: without the two snapshots in run_sweep this
    fails."""
    from stereodyn.harness.environment import TIMING_END, TIMING_START, cpu_name

    environment = json.loads((uninterrupted / "runs.json").read_text())["environment"]
    for key in (TIMING_START, TIMING_END):
        assert environment[key].startswith("load average ") and cpu_name() in environment[key], environment[key]
        load = [float(x) for x in environment[key].split("load average ")[1].split(" (")[0].split(", ")]
        assert len(load) == 3 and min(load) >= 0.0


def test_the_cache_folders_are_the_users_under_stereodyn(monkeypatch, tmp_path):
    """stereodyn's caches (the matrix's environments, JAX's compilation cache for MJX) live in $XDG_CACHE_HOME/stereodyn,
    else ~/.cache/stereodyn: where docs/guide.md says a user finds and clears them."""
    from stereodyn.harness.environment import user_cache
    from stereodyn.harness.run.environments import cache_root

    monkeypatch.setenv("XDG_CACHE_HOME", str(tmp_path / "xdg"))
    assert cache_root() == tmp_path / "xdg" / "stereodyn" / "matrix"
    monkeypatch.delenv("XDG_CACHE_HOME")
    monkeypatch.setenv("HOME", str(tmp_path / "home"))
    assert user_cache("jax") == tmp_path / "home" / ".cache" / "stereodyn" / "jax"
