"""The time grid of a run: fixed steps, and the step indices at which states are recorded (DESIGN §4)."""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np


@dataclass(frozen=True, eq=False)
class TimeGrid:
    """steps fixed steps of dt seconds; states recorded after the step indices sample_steps.

    sample_steps: (n,) int, increasing, 0 and steps included (0 = the initial state).
    times: (n,) s, sample_steps * dt: the truth and the oracles are evaluated at exactly these times.
    """

    dt: float
    steps: int
    sample_steps: np.ndarray
    times: np.ndarray

    @property
    def t_end(self) -> float:
        """The span actually simulated, steps * dt (may differ from the requested t_end by < dt/2)."""
        return self.steps * self.dt


def time_grid(t_end: float, dt: float, samples: int) -> TimeGrid:
    """steps = round(t_end / dt) (at least 1); samples at round(j * steps / (samples - 1)), duplicates removed."""
    steps = max(1, int(round(t_end / dt)))
    samples = max(2, samples)
    idx = np.unique(np.round(np.arange(samples) * steps / (samples - 1)).astype(np.int64))
    idx.setflags(write=False)
    times = idx * dt
    times.setflags(write=False)
    return TimeGrid(dt=float(dt), steps=steps, sample_steps=idx, times=times)
