import numpy as np

from stereodyn.harness.grid import time_grid


def test_steps_and_samples_follow_the_contract():
    grid = time_grid(20.0, 3e-3, 1000)
    assert grid.steps == 6667                      # round(20 / 3e-3)
    assert grid.t_end == 6667 * 3e-3               # the actual span, not the requested one
    assert grid.sample_steps[0] == 0 and grid.sample_steps[-1] == grid.steps
    assert len(grid.sample_steps) == 1000
    expected = np.round(np.arange(1000) * 6667 / 999).astype(int)
    np.testing.assert_array_equal(grid.sample_steps, expected)
    np.testing.assert_array_equal(grid.times, grid.sample_steps * 3e-3)


def test_more_samples_than_steps_records_every_step_once():
    grid = time_grid(1.0, 0.25, 1000)
    np.testing.assert_array_equal(grid.sample_steps, [0, 1, 2, 3, 4])
