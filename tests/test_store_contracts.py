"""The result store's contracts on a bare folder (harness.run.store): readers share a folder, writers do not; what a
record must be to be reused; what makes a run's key; the completion mark. Found by the mutation check
(tools/mutants.py, docs/mutants.md)."""
from __future__ import annotations

import json
import math
import shutil

import pytest

from stereodyn.harness.run import store
from stereodyn.harness.run.store import FolderNotReady, Store, StoreBusy, completeness, reading, run_identity, run_key
from stereodyn.harness.scenes.cases import find_case, with_overrides


def test_two_readers_of_one_folder_do_not_refuse_each_other(tmp_path):
    (tmp_path / store.STORE_DIR).mkdir()
    with reading(tmp_path, allow_partial=True), reading(tmp_path, allow_partial=True):
        pass  # two `check`s of one folder (two CI jobs) at once


def test_a_second_store_of_a_folder_is_refused_while_one_writes(tmp_path):
    with Store(tmp_path):
        with pytest.raises(StoreBusy):
            Store(tmp_path).__enter__()
        with pytest.raises(StoreBusy):
            with reading(tmp_path):
                pass


def _manifest(folder, **fields):
    (folder / "results.csv").write_text("case\n")
    (folder / store.MANIFEST).write_text(json.dumps({"format": store.FORMAT, "environment": {}, "runs": [], **fields}))


def test_the_completion_mark_decides_who_may_read(tmp_path):
    _manifest(tmp_path, complete=False)
    with pytest.raises(FolderNotReady, match="unfinished sweep"):
        completeness(tmp_path)
    assert completeness(tmp_path, allow_partial=True) == [f"{tmp_path}: an unfinished sweep, read as it is "
                                                          "(--allow-partial)"]
    store.mark_complete(tmp_path)
    assert completeness(tmp_path) == []
    (tmp_path / store.MANIFEST).unlink()
    assert [w.split(": ", 1)[1] for w in completeness(tmp_path)] == [
        "no completion mark (written by stereodyn 0.2.0 or elsewhere): read as it is"]


def test_a_manifest_whose_mark_is_not_a_boolean_counts_as_absent(tmp_path):
    _manifest(tmp_path, complete="yes")
    assert store.read_manifest(tmp_path) is None


ROW = {"case": "c", "engine": "mujoco", "formulation": None, "integrator": "rk4", "precision": "float64",
       "status": "ok", "energy_drift": math.inf, "attitude_err": 1e-6}
IDENTITY = {"engine": "mujoco", "formulation": None, "integrator": "rk4", "precision": "float64"}


def test_a_stored_row_reads_back_as_written(tmp_path):
    with Store(tmp_path) as records:
        records.put("k1", IDENTITY, ROW, None)
        row = records.get("k1")["row"]
    assert row["energy_drift"] == math.inf and row["formulation"] == "" and row["attitude_err"] == 1e-6


@pytest.mark.parametrize("column", ["integrator", "precision", "formulation"])
def test_a_record_whose_row_is_another_runs_is_absent(tmp_path, column):
    with Store(tmp_path) as records:
        records.put("k1", IDENTITY, {**ROW, column: "other"}, None)
        assert records.get("k1") is None


def test_a_record_under_another_key_is_absent(tmp_path):
    with Store(tmp_path) as records:
        records.put("k1", IDENTITY, ROW, None)
        shutil.copy(records.path("k1"), records.path("k2"))
        assert records.get("k2") is None and records.get("k1") is not None


def test_the_key_changes_with_the_horizon_and_the_certification():
    case = find_case("free-asymmetric")

    def key(c=case, certify=True):
        return run_key(run_identity(c, "mujoco", "", "rk4", 0.01, certify, {"numpy": "2"}))
    assert key() != key(with_overrides(case, t_end=case.t_end / 2))
    assert key() != key(certify=False)
    assert key() == key(with_overrides(case, dt=[0.5]))  # the sweep's other steps are not this run's content


@pytest.mark.parametrize("edit", [
    lambda record: record["row"].pop("attitude_err"),               # a metric deleted: an ok row with it empty
    lambda record: record["row"].__setitem__("extra", 1.0),         # a key added
    lambda record: record.__setitem__("extra", 1),                  # at the top level
    lambda record: record["identity"].__setitem__("dt", 0.5),       # the identity of another run
    lambda record: record.pop("seal"),                              # a record without its seal
], ids=["metric deleted", "row key added", "top key added", "identity edited", "no seal"])
def test_a_record_not_exactly_as_put_wrote_it_is_absent(tmp_path, edit):
    """Issue 46's ninth attack, F3: --resume reused a record whose attitude_err was deleted (an ok row with it empty,
    which check then failed), or that held an extra key, or whose identity's dt no longer matched. A record carries
    a seal (store.seal) over what the results are made of; one that does not match counts as absent. Break-checked:
    without the seal's check in well_formed each is read back."""
    import json

    with Store(tmp_path) as records:
        records.put("k1", IDENTITY, ROW, None)
        path = records.path("k1")
        record = json.loads(path.read_text())
        edit(record)
        path.write_text(json.dumps(record))
        assert records.get("k1") is None
        records.put("k1", IDENTITY, ROW, {"t": [0.0, 1.0]})
        assert records.get("k1") is not None  # as put wrote it, with or without a series
