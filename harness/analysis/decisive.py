"""Which runs' times decide something (issue 29 item 3): the runs of a sweep worth timing with repeats.

A sweep's time is read by the "What to use" table (analysis.pareto: its winners, tie-mates and the cheaper runs it
names not recommended), by an advice row (analysis.advice: it times the advised runs that have only a single time
itself), by no verdict (analysis.verdicts reads no time), and by the gate's time check (analysis.gate: only the rows
timed with repeats). So only the Pareto table's candidates that could win or tie a cell need repeats; every other run
keeps the single timed run it got first.

The rule, from single times (one timed run after the warm-up, alone on the machine): a candidate (ok, finite error,
not the exact reference row pareto leaves out) is decisive when its single time is at most MARGIN times the fastest
single time among the runs of its own case and engine that reach the smallest accuracy target it reaches. Its engine's
scope is the one that binds: a run that wins or ties a cell of the `any` scope is within TIE_MAX_RATIO of the fastest
there, hence of its own engine's fastest. Runs of other engines, the ladders' points and the verdicts only remove
candidates from a cell, so leaving them out makes the rule more inclusive, never less.
"""
from __future__ import annotations

import math

import numpy as np
import pandas as pd

from .pareto import ACCURACY_TARGETS, TIE_MAX_RATIO

# One single time against a best of 3 of the same run: two idle default runs timed the same run up to 2x apart
# (harness.run.timing.measure_interleaved), so a single time is taken to be within 2x of the best of 3. A run more
# than TIE_MAX_RATIO x 2 slower than the fastest of its cell, by single times, can then neither win nor tie it.
SINGLE_NOISE = 2.0
MARGIN = TIE_MAX_RATIO * SINGLE_NOISE

_NEEDED = ("case", "engine", "dt", "status", "attitude_err", "us_per_sim_s")


def decisive(runs: pd.DataFrame, margin: float = MARGIN) -> set:
    """The index labels of the runs whose time can change a "What to use" cell. runs: one row per run, columns case,
    engine, dt (NaN: adaptive), status, attitude_err (rad) and us_per_sim_s (µs of stepping per simulated second, a
    single time). margin: how many times slower than its cell's fastest a run may be and still count."""
    missing = [c for c in _NEEDED if c not in runs]
    if missing:
        raise KeyError(f"decisive: runs lack column(s) {', '.join(missing)}")
    err = runs["attitude_err"].to_numpy(float)
    cost = runs["us_per_sim_s"].to_numpy(float)
    # pareto.pareto's candidates: ok, a finite error and time; not the adaptive row whose error is exactly 0 (the
    # reference its errors are measured against)
    candidate = ((runs["status"] == "ok").to_numpy() & np.isfinite(err) & np.isfinite(cost)
                 & ~(runs["dt"].isna().to_numpy() & (err == 0.0)) & (err <= max(ACCURACY_TARGETS)))
    targets = np.sort(np.asarray(ACCURACY_TARGETS, dtype=float))
    # the smallest target each candidate reaches (the tightest cell it enters: the fewest rivals there)
    tightest = np.full(len(runs), math.nan)
    where = np.searchsorted(targets, err[candidate], side="left")
    tightest[candidate] = targets[np.minimum(where, targets.size - 1)]
    chosen = set()
    keys = runs["case"].astype(str) + "\x00" + runs["engine"].astype(str)
    for _, members in pd.Series(np.arange(len(runs)))[candidate].groupby(keys[candidate].to_numpy()):
        rows = members.to_numpy()
        for i in rows:
            rivals = rows[err[rows] <= tightest[i]]
            if cost[i] <= margin * cost[rivals].min():
                chosen.add(runs.index[i])
    return chosen


def deciding_points(results: pd.DataFrame, points: list[dict], margin: float = MARGIN) -> set[int]:
    """The indices of the ladder points (ladder.csv's and tolerance.csv's rows, each with the single time of its
    worker: us_per_sim_s) whose time can change a "What to use" cell, pareto's other candidates, the sweep's runs
    (results.csv: wall_s, single or best of N), being their rivals."""
    if not points:
        return set()
    own = pd.DataFrame([{c: p.get(c, math.nan) for c in _NEEDED} for p in points], columns=list(_NEEDED))
    sweep = results.reindex(columns=[*_NEEDED[:-1], "wall_s", "t_end"])
    sweep = sweep.assign(us_per_sim_s=sweep["wall_s"].astype(float) / sweep["t_end"].astype(float) * 1e6)
    both = pd.concat([own, sweep[list(_NEEDED)]], ignore_index=True)  # the points first: labels 0 .. len(points) - 1
    return {int(label) for label in decisive(both, margin) if label < len(points)}
