"""Sweeps on a Dask cluster: a LocalCluster on this machine gives the local run's table, timings aside."""
import pandas as pd
import pytest
from helpers import without_timings

from stereodyn.harness import cli
from stereodyn.harness.run import distributed as stereodyn_distributed, timing, truth as run_truth

dask_distributed = pytest.importorskip(
    "distributed", reason="dask.distributed is not installed (pip install 'stereodyn[dask]')")

SWEEP = ["lagrange-top", "--t-end", "0.5", "--dt", "1e-2", "--quiet"]


def _nowhere_here(*args, **kwargs):
    raise AssertionError("computed in the parent: with --scheduler it only plans, gathers and writes")


def test_a_local_cluster_gives_the_local_table(tmp_path, capsys, monkeypatch):
    """The cluster's table is the local one, timings aside; the parent computed no truth and timed no run (issue 49:
    both are tasks on the workers). Break-checked: cluster_timer's spread timing the chunks here (timing.in_turn)
    fails on the patched _rounds."""
    local, remote = tmp_path / "local", tmp_path / "dask"
    assert cli.main(["run", *SWEEP, "--jobs", "1", "--out", str(local)]) == 0
    with dask_distributed.LocalCluster(n_workers=2, threads_per_worker=1, processes=True,
                                       dashboard_address=None) as cluster:
        assert cluster.scheduler_address.startswith("tcp://")
        with monkeypatch.context() as here:  # the workers are processes of their own: only this one is patched
            here.setattr(run_truth, "scene_of", _nowhere_here)
            here.setattr(timing, "_rounds", _nowhere_here)
            assert cli.main(["run", *SWEEP, "--scheduler", cluster.scheduler_address, "--out", str(remote)]) == 0
        # Results are keyed by this process's library versions: workers with others are refused.
        with dask_distributed.Client(cluster) as client:
            client.run(exec, "from stereodyn.harness import environment as e; "
                             "e.library_versions = lambda real=e.library_versions: {**real(), 'mujoco': '0.0.1'}")
        capsys.readouterr()
        assert cli.main(["run", *SWEEP, "--scheduler", cluster.scheduler_address, "--out", str(tmp_path / "x")]) == 2
        assert "other library versions: mujoco 0.0.1 (here 4" in capsys.readouterr().err
    expected, got = pd.read_csv(local / "results.csv"), pd.read_csv(remote / "results.csv")
    assert (got.status == "ok").sum() >= 8 + 1  # every simulator run and the truth
    pd.testing.assert_frame_equal(without_timings(got), without_timings(expected))
    assert got[got.status == "ok"].us_per_step.notna().all()
    assert got.timing.str.startswith("best of").any()  # the deciding runs, timed on the workers
    # one record per run; rows skipped up front (Drake's quaternion_free model of this heavy top) are not runs
    ran = got[got.status != "skipped"]
    assert (remote / "report.html").is_file() and len(list((remote / "store").glob("*.json"))) == len(ran)


def test_an_unreachable_scheduler_is_bad_input(tmp_path, capsys, monkeypatch):
    monkeypatch.setattr(stereodyn_distributed, "CONNECT_TIMEOUT_S", 1)
    assert cli.main(["run", "free-asymmetric", "--engines", "mujoco", "--t-end", "0.1", "--quiet",
                     "--scheduler", "tcp://127.0.0.1:9", "--out", str(tmp_path)]) == 2
    err = capsys.readouterr().err
    assert "cannot connect to tcp://127.0.0.1:9" in err and err.count("\n") == 1
