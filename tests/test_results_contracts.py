"""results.csv as every reader reads it (harness.run.results.read_results, frame): what is refused with one line naming
the row and column, and what is read. Found by the mutation check (tools/mutants.py, docs/mutants.md)."""
from __future__ import annotations

import math

import pytest

from stereodyn.harness.run import results
from stereodyn.harness.run.results import TableError, frame, read_results

HEADER = "case,engine,formulation,integrator,precision,dt,status,wall_s,energy_drift,attitude_err"
GOOD = "c,mujoco,,rk4,float64,0.01,ok,0.5,1e-9,1e-6"


def _read(tmp_path, *rows: str, header: str = HEADER):
    path = tmp_path / "results.csv"
    path.write_text("\n".join([header, *rows]) + "\n")
    return read_results(path)


@pytest.mark.parametrize("row, words", [
    ("c,mujoco,,rk4,float64,inf,ok,0.5,1e-9,1e-6", "row 1, column dt: 'inf': must be finite"),
    ("c,,,rk4,float64,0.01,ok,0.5,1e-9,1e-6", "row 1, column engine: empty"),
    ("c,  ,,rk4,float64,0.01,ok,0.5,1e-9,1e-6", "row 1, column engine: empty"),
    ("c,mujoco,,rk4,float64,0.01,bogus,0.5,1e-9,1e-6", "row 1, column status: 'bogus' is not a status"),
    ("c,mujoco,,rk4,float64,0.01,ok,0.5,inf,1e-6", "row 1, column energy_drift: 'inf': must be finite"),
    ("c,mujoco,,rk4,float64,0.01,ok,0.5,1e-9,-inf", "row 1, column attitude_err: '-inf': must be finite"),
    ("c,mujoco,,rk4,float64,0.01,ok,0.5", "row 1: 8 fields, the header has 10"),
])
def test_a_row_every_reader_must_refuse_is_one_line_naming_it(tmp_path, row, words):
    with pytest.raises(TableError, match=None) as caught:
        _read(tmp_path, GOOD.replace("c,", "b,", 1), row)
    message = str(caught.value)
    assert words.replace("row 1", "row 2") in message and "\n" not in message


def test_a_table_larger_than_the_limit_is_refused(tmp_path, monkeypatch):
    from stereodyn.harness import tables  # the reader of every table (issue 28 moved it out of harness/run/results.py)

    monkeypatch.setattr(tables, "MAX_TABLE_BYTES", 100)
    with pytest.raises(TableError, match="larger than 100 bytes"):
        _read(tmp_path, *[GOOD] * 3)  # 224 bytes


def test_nan_text_is_a_missing_number_and_an_empty_precision_is_float64(tmp_path):
    df = _read(tmp_path, "c,mujoco,,rk4,,0.01,ok,nan,1e-9,1e-6")
    assert math.isnan(df["wall_s"].iloc[0]) and df["precision"].iloc[0] == "float64"


def test_rows_are_ordered_by_engine_before_integrator():
    rows = [{"case": "c", "engine": e, "integrator": i, "_engine_rank": er, "_integrator_rank": ir}
            for e, i, er, ir in (("pinocchio", "euler", 1, 0), ("mujoco", "rk4", 0, 3), ("mujoco", "euler", 0, 0))]
    df = frame(rows)
    assert list(zip(df["engine"], df["integrator"])) == [("mujoco", "euler"), ("mujoco", "rk4"),
                                                          ("pinocchio", "euler")]


def test_steps_that_differ_in_the_fourth_digit_are_two_rows_not_a_duplicate(tmp_path):
    """A key compares dt to 10 significant digits (results.dt_key): dt = 0.001 and 0.001001 are two runs, and one key
    twice is refused. Break-check (tools/mutants.py results-10): 3 digits read the pair as a duplicate."""
    df = _read(tmp_path, GOOD.replace("0.01", "0.001", 1), GOOD.replace("0.01", "0.001001", 1))
    assert sorted(df["dt"]) == [0.001, 0.001001]
    with pytest.raises(TableError, match="duplicate key"):
        _read(tmp_path, GOOD, GOOD)


def test_a_table_cut_inside_its_last_field_is_refused(tmp_path):
    """A file cut inside its last row's last field has every field but no newline after it (stereodyn ends every
    table with one): refused, naming the row. The cut tables of tests/test_faults.py lose whole fields since the
    committed report was regenerated (2026-12-02), which the field count already refuses; this keeps the newline rule
    pinned (mutant tables-5)."""
    from stereodyn.harness.tables import read_csv_table

    path = tmp_path / "notes.csv"
    path.write_text("case,note\nfree-asymmetric,settled\nlagrange-top,pre-asymptotic\n")
    assert len(read_csv_table(path)) == 2
    path.write_text("case,note\nfree-asymmetric,settled\nlagrange-top,pre-asym")
    with pytest.raises(TableError, match=r"notes\.csv: row 2: no newline at its end"):
        read_csv_table(path)
