"""Cross-engine agreement (agreement.csv): for every pair of runs of the same method (engines.declared.method:
harness.engines.methods' vocabulary) and dt on a case, on two different engines, the largest state difference over
the run.

Two engines that run the same map agree to round-off (MuJoCo's Euler and Pinocchio's symplectic Euler: 4e-13 rad);
a difference above that is a finding: another map under the same name (MJX's RK4 is MuJoCo 3.17's, not 4.0's), other
coordinates (Drake's roll-pitch-yaw model), or another precision (float32). The difference is measured as errors are
(harness.scenes.metrics.errors, the first run as the reference), up to the case's horizon.
"""
from __future__ import annotations

import math
from itertools import combinations
from pathlib import Path

import numpy as np
import pandas as pd

from ..precision import FLOAT64
from ..run.results import read_csv_table, write_atomic
from ..scenes.metrics import errors
from ..trajectory import Trajectory

AGREEMENT_FILE = "agreement.csv"
RUN = ("engine", "formulation", "integrator", "precision")
COLUMNS = ("case", "method", "dt", *(f"{c}_a" for c in RUN), *(f"{c}_b" for c in RUN), "attitude_diff",
           "attitude_diff_end", "omega_diff", "state_diff")


def table(entries: list[dict]) -> pd.DataFrame:
    """agreement.csv's rows from the kept states of a sweep's runs. entries: dicts with case, method, dt, engine,
    formulation, integrator, precision, rank (the run's place in the results table: the earlier run is `a`),
    horizon (s or None), times (n,) s, quat (n, 4) wxyz body -> world, omega (n, 3) rad/s body frame, all of one
    case and dt on the same sample times. Only runs that stayed finite are compared."""
    groups: dict[tuple, list[dict]] = {}
    for entry in entries:
        if entry["method"] and np.isfinite(entry["quat"]).all() and np.isfinite(entry["omega"]).all():
            groups.setdefault((entry["case"], entry["method"], float(entry["dt"])), []).append(entry)
    rows = []
    for (case, method, dt), runs in groups.items():
        runs.sort(key=lambda e: e["rank"])
        for a, b in combinations(runs, 2):
            if a["engine"] == b["engine"] or len(a["times"]) != len(b["times"]):
                continue
            diff = errors(Trajectory(b["times"], b["quat"], b["omega"]), a["quat"], a["omega"], a["horizon"])
            rows.append({"case": case, "method": method, "dt": dt,
                         **{f"{c}_a": a[c] for c in RUN}, **{f"{c}_b": b[c] for c in RUN},
                         "attitude_diff": diff["attitude_err"], "attitude_diff_end": diff["attitude_err_end"],
                         "omega_diff": diff["omega_err"],
                         "state_diff": max(diff["attitude_err"], diff["omega_err"])})
    return pd.DataFrame(rows, columns=list(COLUMNS))


def write(out_dir: Path, entries: list[dict]) -> Path:
    path = Path(out_dir) / AGREEMENT_FILE
    write_atomic(path, table(entries).to_csv(index=False, float_format="%.6g"))
    return path


def read(out_dir: Path) -> pd.DataFrame | None:
    """DIR/agreement.csv, or None where the run wrote none."""
    path = Path(out_dir) / AGREEMENT_FILE
    if not path.exists():
        return None
    text = {f"{c}_{s}": str for c in RUN for s in "ab"}
    df = read_csv_table(path, dtype={**text, "case": str, "method": str}, keep_default_na=True)
    return df.fillna({c: FLOAT64 if c.startswith("precision") else "" for c in text})


def summary(df: pd.DataFrame) -> pd.DataFrame:
    """One row per method and pair of runs (formulations folded: the largest over them): how many case-dt pairs,
    the largest state difference and where, the median. Sorted by method, then the largest difference."""
    pair = ["method", "engine_a", "integrator_a", "precision_a", "engine_b", "integrator_b", "precision_b"]
    rows = []
    for key, group in df.groupby(pair, sort=False):
        worst = group.loc[group["state_diff"].astype(float).idxmax()] if group["state_diff"].notna().any() \
            else group.iloc[0]
        rows.append({**dict(zip(pair, key)), "pairs": len(group), "state_diff_max": float(worst["state_diff"]),
                     "at": f"{worst['case']} dt={worst['dt']:g}" + "".join(
                         f" ({worst[f'formulation_{s}']})" for s in "ab" if worst[f"formulation_{s}"]),
                     "state_diff_median": float(group["state_diff"].median())})
    out = pd.DataFrame(rows, columns=[*pair, "pairs", "state_diff_max", "at", "state_diff_median"])
    return out.sort_values(["method", "state_diff_max"], ascending=[True, False], kind="stable",
                           na_position="last").reset_index(drop=True) if len(out) else out


def run_name(engine: str, integrator: str, precision: str) -> str:
    return " ".join(x for x in (engine, integrator, precision if precision != FLOAT64 else "") if x)


def headline(df: pd.DataFrame) -> list[str]:
    """Sentences for the largest difference of each pair of engines: 'mjx rk4 against mujoco rk4: 1.8e-03 on
    heavy-asymmetric dt=0.01'."""
    lines = []
    for _, row in summary(df).iterrows():
        if math.isfinite(row["state_diff_max"]):
            lines.append(f"{run_name(row['engine_b'], row['integrator_b'], row['precision_b'])} against "
                         f"{run_name(row['engine_a'], row['integrator_a'], row['precision_a'])}: "
                         f"{row['state_diff_max']:.2g} on {row['at']}")
    return lines
