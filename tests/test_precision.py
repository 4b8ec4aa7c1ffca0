"""Precision as a dimension (issue 23 item 2): the plan runs an engine's precisions as rows of their own, keyed apart
everywhere; a result folder or baseline of 0.2.0 (no precision column) reads as float64 and still passes check and
compare; the order fitter uses the family's own eps."""
from __future__ import annotations

import json
import math

import numpy as np
import pandas as pd
import pytest

from stereodyn.harness import cli
from stereodyn.harness.analysis import compare, fitting, gate
from stereodyn.harness.engines.base import EPS, FLOAT32, FLOAT64, Engine, Offer, prepare_keywords
from stereodyn.harness.run import plan as planning
from stereodyn.harness.scenes.cases import find_case, with_overrides

SWEEP = ["lagrange-top", "--engines", "mujoco", "--t-end", "0.5", "--dt", "1e-2,5e-3", "--jobs", "1", "--quiet",
         "--no-ladder"]


@pytest.fixture(scope="module")
def folders(tmp_path_factory):
    """A run of this version, and the same folder as 0.2.0 wrote it: no precision column anywhere."""
    new = tmp_path_factory.mktemp("new")
    assert cli.main(["run", *SWEEP, "--out", str(new)]) == 0
    old = tmp_path_factory.mktemp("old")
    for name in ("results.csv", "checks.csv", "convergence.csv", "runs.json"):
        text = (new / name).read_text()
        if name.endswith(".csv"):
            df = pd.read_csv(new / name, keep_default_na=False)
            assert (df["precision"] == FLOAT64).all()
            text = df.drop(columns="precision").to_csv(index=False)
        (old / name).write_text(text)
    return new, old


def test_a_0_2_0_folder_and_baseline_pass_check_and_compare(folders, tmp_path, capsys):
    new, old = folders
    old_baseline, new_baseline = tmp_path / "old.json", tmp_path / "new.json"
    assert cli.main(["baseline", str(old), "--out", str(old_baseline)]) == 0
    assert cli.main(["baseline", str(new), "--out", str(new_baseline)]) == 0
    assert all("precision" not in row or row["precision"] == FLOAT64
               for row in json.loads(old_baseline.read_text())["rows"])
    # strip the key a 0.2.0 baseline never had, as 0.2.0 wrote it
    data = json.loads(old_baseline.read_text())
    data["rows"] = [{k: v for k, v in row.items() if k != "precision"} for row in data["rows"]]
    old_baseline.write_text(json.dumps(data))
    capsys.readouterr()
    assert cli.main(["check", str(new), "--baseline", str(old_baseline)]) == 0
    assert cli.main(["check", str(old), "--baseline", str(new_baseline)]) == 0
    a, _ = compare.load(old_baseline)
    b, _ = compare.load(new)
    changes = compare.row_changes(a, b)
    # every row matched (none only in A or only in B), each as float64
    assert len(changes) == len(b) and (changes["status_a"] != "-").all() and (changes["status_b"] != "-").all()
    assert set(changes["precision"]) == {FLOAT64}


def test_a_float32_row_is_another_key(folders):
    new, _ = folders
    row = pd.read_csv(new / "results.csv").iloc[0].to_dict()
    assert gate._key(row) != gate._key({**row, "precision": FLOAT32})
    assert gate._key({k: v for k, v in row.items() if k != "precision"}) == gate._key(row)  # absent = float64


class TwoPrecisions(Engine):
    """An engine declaring float64 and float32 for one integrator: the plan runs both."""

    name = "two_precisions"

    def integrators(self):
        return ("euler", "rk4")

    def offer(self, integrator):
        return Offer(precisions=(FLOAT64, FLOAT32) if integrator == "rk4" else (FLOAT64,))

    def unsupported(self, case):
        return None


def test_the_plan_runs_each_declared_precision(monkeypatch):
    engine = TwoPrecisions()
    monkeypatch.setattr(planning, "get_engine", lambda name: engine)
    case = with_overrides(find_case("free-asymmetric"), dt=[1e-2, 5e-3])
    specs, _ = planning.plan([case], ["two_precisions"], None)
    found = sorted((s.integrator, s.dt, s.precision) for s in specs)
    assert found == [("euler", 5e-3, FLOAT64), ("euler", 1e-2, FLOAT64), ("rk4", 5e-3, FLOAT32),
                     ("rk4", 5e-3, FLOAT64), ("rk4", 1e-2, FLOAT32), ("rk4", 1e-2, FLOAT64)]
    rows = [planning.base_row(s, None) for s in specs]
    assert len({gate._key(r) for r in rows}) == len(rows)  # float32 and float64 rows never collide
    # prepare gets precision= only from an engine that declares another precision (a 0.2.0 plug-in never does)
    assert prepare_keywords(engine, "", "rk4", FLOAT32) == {"precision": FLOAT32}
    assert prepare_keywords(engine, "", "euler", FLOAT64) == {}


def _points(errors, steps):
    return pd.DataFrame({"dt": [0.04, 0.02, 0.01, 0.005], "steps": steps, "status": "ok", "state_err": errors})


def test_the_fitter_uses_the_familys_eps():
    """First-order errors 4e-3 .. 5e-4 over 500 .. 4000 steps: float64's round-off (30 eps steps <= 3e-11) leaves
    them asymptotic (order 1); float32's (30 x 1.2e-7 x steps: 1.8e-3 at the coarsest, 1.4e-2 at the finest) leaves
    one point: no order, the named reason instead of a failure."""
    points = _points([4e-3, 2e-3, 1e-3, 5e-4], [500, 1000, 2000, 4000])
    f64 = fitting.fit(points, 1.0)
    assert f64["order"] == pytest.approx(1.0) and f64["points"] == 4
    f32 = fitting.fit(points, 1.0, FLOAT32)
    assert math.isnan(f32["order"]) and f32["note"].startswith(f"{fitting.NOT_MEASURABLE} {FLOAT32}")
    assert fitting.note_group(f32["note"]).startswith("not measurable in float32")
    assert EPS[FLOAT32] / EPS[FLOAT64] == pytest.approx(2.0 ** 29)
    # errors well above float32's round-off are fitted in float32 too
    coarse = _points([2.4e-2, 1.2e-2, 6e-3, 3e-3], [25, 50, 100, 200])
    assert fitting.fit(coarse, 1.0, FLOAT32)["order"] == pytest.approx(1.0)
    assert np.isfinite(fitting.fit(coarse, 1.0)["order"])
