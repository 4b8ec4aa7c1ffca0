import os

import pytest

# No figures unless a test asks for them (--figures): drawing is most of a small sweep's report, and most tests read
# only the tables (measured on this suite's run-heavy files, 2 cores: 83 s of CPU with figures, 64 s without).
# Set at import, so that module fixtures and the commands tests start as subprocesses inherit it.
os.environ["STEREODYN_FIGURES"] = "0"

# The longest files first (their module fixtures and tests: pytest --durations on 2 idle cores, 2026-11-26, 15-50 s
# each): pytest-xdist's --dist loadfile hands files to its workers in collection order, so the long ones start early
# and the short ones fill the end, instead of one worker finishing a long file while the other waits (~40 s).
LONGEST_FIRST = ("test_hung_engines.py", "test_figures_readable.py", "test_engine_plugins.py", "test_verdicts.py",
                 "test_oracle_cases.py", "test_report.py", "test_trajectories.py", "test_ci_recipe.py",
                 "test_extremes.py", "test_readme_plugin.py", "test_report_sections.py", "test_runner.py",
                 "test_store.py", "test_truth_audit.py", "test_tolerance_ladders.py", "test_pareto.py")


def pytest_collection_modifyitems(session, config, items):
    rank = {name: i for i, name in enumerate(LONGEST_FIRST)}
    items.sort(key=lambda item: rank.get(item.path.name, len(LONGEST_FIRST)))  # stable: each file keeps its order


@pytest.fixture(autouse=True)
def _scratch_cwd(tmp_path, monkeypatch):
    """Every test runs in its own folder, so MuJoCo's MUJOCO_LOG.TXT and default outputs never land in the checkout."""
    monkeypatch.chdir(tmp_path)


@pytest.fixture(scope="module", autouse=True)
def _module_runs_in_process():
    """As _runs_in_process (below) for the module fixtures, a file's shared sweep: they are set up before any function
    fixture."""
    with pytest.MonkeyPatch.context() as patch:
        patch.setenv("STEREODYN_IN_PROCESS", "1")
        yield


@pytest.fixture(autouse=True)
def _runs_in_process(monkeypatch):
    """--jobs 1 runs in the test's own process (harness.run.pool.in_process), so that what a test patches holds in
    the runs, and no test pays a worker's start-up (~3 s of imports). The tests of the watched worker
    (tests/test_hung_engines.py) take this away."""
    monkeypatch.setenv("STEREODYN_IN_PROCESS", "1")
