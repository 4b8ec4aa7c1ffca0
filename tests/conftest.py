import pytest


@pytest.fixture(autouse=True)
def _scratch_cwd(tmp_path, monkeypatch):
    """Every test runs in its own folder, so MuJoCo's MUJOCO_LOG.TXT and default outputs never land in the checkout."""
    monkeypatch.chdir(tmp_path)
