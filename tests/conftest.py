import os

import pytest

# No figures unless a test asks for them (--figures): drawing is most of a small sweep's report, and most tests read
# only the tables (measured on this suite's run-heavy files, 2 cores: 83 s of CPU with figures, 64 s without).
# Set at import, so that module fixtures and the commands tests start as subprocesses inherit it.
os.environ["STEREODYN_FIGURES"] = "0"


@pytest.fixture(autouse=True)
def _scratch_cwd(tmp_path, monkeypatch):
    """Every test runs in its own folder, so MuJoCo's MUJOCO_LOG.TXT and default outputs never land in the checkout."""
    monkeypatch.chdir(tmp_path)


@pytest.fixture(autouse=True)
def _runs_in_process(monkeypatch):
    """--jobs 1 runs in the test's own process (harness.run.pool.in_process), so that what a test patches holds in
    the runs, and no test pays a worker's start-up (~3 s of imports). The tests of the watched worker
    (tests/test_hung_engines.py) take this away."""
    monkeypatch.setenv("STEREODYN_IN_PROCESS", "1")
