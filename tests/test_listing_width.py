"""`stereodyn integrators` and `stereodyn engines` fit 100 columns; `--wide` gives everything (issue 32: 330 and 374
columns before, wrapped in an 80-column terminal)."""
import pytest

from stereodyn.harness import cli


@pytest.mark.parametrize("command", ["integrators", "engines"])
def test_the_listings_fit_100_columns_and_wide_has_everything(command, capsys):
    assert cli.main([command]) == 0
    narrow = capsys.readouterr().out.splitlines()
    assert narrow and max(map(len, narrow)) <= 100, max(narrow, key=len)
    assert cli.main([command, "--wide"]) == 0
    wide = capsys.readouterr().out
    assert max(map(len, wide.splitlines())) > 100  # the descriptions, the missing modules: more than fits
    if command == "integrators":
        # the description has no room beside the longest names (it needs 20 columns): --wide has it
        assert narrow[0].split()[:7] == ["name", "state_space", "order", "stages", "sweep", "claims", "origin"]
        rk4 = next(line.split() for line in narrow if line.split()[:2] == ["rk4", "lie"])
        assert rk4[2:6] == ["4", "4", "yes", "..g.."]  # order, stages, default sweep, claims: on the group only
        strang = next(line.split() for line in narrow if line.split()[:2] == ["strang_free_flow", "lie"])
        assert strang[4:6] == ["no", "srgec"], strang  # declares all five, and stays out of the default sweep
        assert "Munthe-Kaas" in wide  # rk4's description, in full
    else:
        assert any(line.startswith("mujoco: built in; installed") for line in narrow)
        assert "    " in "\n".join(narrow)  # a long integrator list wraps under its heading
