"""--save-trajectories (issue 21 item 6): DIR/trajectories/index.csv maps every row to its file, and each file carries the
truth on the run's own sample times, so any saved row can be compared with the truth sample by sample."""
import math

import numpy as np
import pandas as pd
import pytest

from stereodyn.harness import cli
from stereodyn.harness.grid import time_grid
from stereodyn.harness.scenes.cases import find_case, with_overrides
from stereodyn.reference.rotations import attitude_angle, quat_to_matrix

KEY = ["case", "engine", "formulation", "integrator", "dt"]


def geodesic_angle(q1: np.ndarray, q2: np.ndarray) -> np.ndarray:
    """The angle (rad) between the rotations of two (n, 4) wxyz quaternions, as results.csv measures it (DESIGN §2)."""
    return attitude_angle(quat_to_matrix(q1), quat_to_matrix(q2))


@pytest.fixture(scope="module")
def saved(tmp_path_factory):
    """Two dt (their sample grids differ: 3e-3 does not divide the 1000 samples of 1 s), fixed-step and adaptive runs
    of three engines, and a case with a horizon shorter than t_end (heavy-asymmetric: chaotic)."""
    out = tmp_path_factory.mktemp("saved")
    assert cli.main(["run", "free-asymmetric", "heavy-asymmetric", "--engines", "mujoco,pinocchio,reference",
                     "--integrators", "euler,rk4,taylor,scipy_rk45", "--t-end", "2", "--dt", "1e-2,3e-3",
                     "--save-trajectories", "--no-ladder", "--no-certify", "--jobs", "1", "--quiet",
                     "--out", str(out)]) == 0
    results = pd.read_csv(out / "results.csv", dtype={"formulation": str}, keep_default_na=False)
    index = pd.read_csv(out / "trajectories" / "index.csv", dtype={"formulation": str}, keep_default_na=False)
    return out, results, index


def test_the_index_names_every_rows_file(saved):
    out, results, index = saved
    assert list(index.columns) == [*KEY, "status", "file"]
    assert len(index) == len(results) and not index.duplicated(KEY).any()
    merged = results.merge(index, on=KEY, suffixes=("", "_index"), validate="one_to_one")
    assert len(merged) == len(results) and (merged.status == merged.status_index).all()
    for _, row in merged.iterrows():
        with np.load(out / row.file) as data:  # the file says which row it is, too
            assert [str(data[c]) for c in KEY[:4]] == [row.case, row.engine, row.formulation, row.integrator]
            dt = float(data["dt"])
            assert (math.isnan(dt) and row["dt"] == "") or dt == float(row["dt"])


def test_every_ok_row_matches_its_saved_truth_sample_by_sample(saved):
    out, results, index = saved
    rows = results.merge(index, on=KEY, suffixes=("", "_index"))
    rows = rows[rows.status == "ok"]
    grids = set()
    for _, row in rows.iterrows():
        with np.load(out / row.file) as data:
            times, quat, omega = data["times"], data["quat"], data["omega"]
            truth_quat, truth_omega = data["truth_quat"], data["truth_omega"]
        case = with_overrides(find_case(row.case), t_end=2.0)
        assert truth_quat.shape == quat.shape and truth_omega.shape == omega.shape
        if row["dt"] != "":  # a fixed-step run: its own grid (DESIGN §2), not the truth row's
            np.testing.assert_array_equal(times, time_grid(case.t_end, float(row["dt"]), case.samples).times)
            grids.add(tuple(times))
        # up to the case's horizon (DESIGN §3); without one every sample, to the run's own span steps * dt
        keep = times <= case.horizon * (1 + 1e-12) if case.horizon is not None else np.ones(len(times), bool)
        angle = geodesic_angle(quat[keep], truth_quat[keep])
        if row.attitude_err == "":  # the truth's own row: its file's truth is itself
            assert row.engine == "reference" and row.integrator == "taylor"
            assert np.max(angle) < 1e-13
            continue
        scale = np.max(np.linalg.norm(truth_omega[keep], axis=1))
        omega_err = np.max(np.linalg.norm(omega[keep] - truth_omega[keep], axis=1)) / scale
        # the same numbers as results.csv, recomputed from the file alone (written to 10 digits there: rel 1e-8)
        assert np.max(angle) == pytest.approx(float(row.attitude_err), rel=1e-8, abs=1e-15), row.file
        assert angle[-1] == pytest.approx(float(row.attitude_err_end), rel=1e-8, abs=1e-15), row.file
        assert omega_err == pytest.approx(float(row.omega_err), rel=1e-8, abs=1e-15), row.file
    assert len(grids) == 2  # the two dt's sample grids differ, and each row carries the truth on its own
