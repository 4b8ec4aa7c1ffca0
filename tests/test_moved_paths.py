"""0.2.0's import paths of the modules moved by the layout of issue 20 keep working (harness/moved.py): the old name
gives the module at its new path, the same object, with a DeprecationWarning naming the new path; run_sweep's 0.2.0
arguments still run a sweep, with a DeprecationWarning naming SweepOptions."""
import importlib
import subprocess
import sys

import pandas as pd
import pytest
from helpers import TIMINGS

from stereodyn.harness.moved import MOVED
from stereodyn.harness.run.sweep import SweepOptions, run_sweep
from stereodyn.harness.scenes.cases import find_case, with_overrides


@pytest.mark.parametrize("old", sorted(MOVED))
def test_an_old_path_is_the_new_module(old):
    new = importlib.import_module(f"stereodyn.harness.{MOVED[old]}")
    sys.modules.pop(f"stereodyn.harness.{old}", None)  # an earlier import may have cached the alias
    with pytest.warns(DeprecationWarning, match=f"stereodyn.harness.{MOVED[old]}"):
        alias = importlib.import_module(f"stereodyn.harness.{old}")
    assert alias is new
    assert new.__spec__.name == new.__name__ == f"stereodyn.harness.{MOVED[old]}"  # not the alias's spec


def test_a_plugin_import_of_0_2_0_works_in_a_fresh_interpreter():
    code = ("import warnings; warnings.simplefilter('error')\n"
            "try:\n    from stereodyn.harness.cases import Case\nexcept DeprecationWarning as w:\n    print(w)\n"
            "warnings.simplefilter('ignore')\n"
            "from stereodyn.harness.cases import Case\nfrom stereodyn.harness import runner\n"
            "print(Case.__module__, runner.__name__)\n")
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True).stdout.split("\n")
    assert out[0] == "stereodyn.harness.cases is deprecated: import stereodyn.harness.scenes.cases"
    assert out[1] == "stereodyn.harness.scenes.cases stereodyn.harness.run.sweep"


def test_no_module_of_the_package_imports_an_old_path():
    code = ("import warnings; warnings.simplefilter('error', DeprecationWarning)\n"
            "import stereodyn.harness.cli, stereodyn.harness.analysis.workprecision, stereodyn.harness.analysis.verdicts\n"
            "import stereodyn.harness.cli.run, stereodyn.harness.cli.advise, stereodyn.harness.pipeline.advice\n"
            "import stereodyn.harness.report.build, stereodyn.harness.testing, stereodyn.harness.engines.reference\n")
    subprocess.run([sys.executable, "-c", code], check=True)


def test_run_sweep_with_0_2_0_arguments_warns_and_sweeps_as_with_options(tmp_path):
    case = with_overrides(find_case("free-asymmetric"), t_end=0.2, dt=[1e-2, 5e-3])
    new = run_sweep([case], SweepOptions(["pinocchio"], tmp_path / "new", ["euler", "rk4"], jobs=1, certify=False))
    with pytest.warns(DeprecationWarning, match=r"run_sweep\(cases, SweepOptions\("):
        old = run_sweep([case], ["pinocchio"], ["euler", "rk4"], tmp_path / "old", jobs=1, certify=False)
    assert len(new) == 4 and set(new["status"]) == {"ok"}  # 2 integrators x 2 dts
    pd.testing.assert_frame_equal(old.drop(columns=TIMINGS), new.drop(columns=TIMINGS))
    with pytest.raises(TypeError, match="unexpected arguments"):  # options and 0.2.0's arguments: not both
        run_sweep([case], SweepOptions(["pinocchio"], tmp_path / "both"), jobs=1)


def test_names_that_moved_to_the_pipeline_are_forwarded_with_a_warning():
    """analysis.workprecision.analyse and the verdicts' check runs moved to harness.pipeline in issue 29 (analysis runs
    nothing): the old attribute is the new object, with a DeprecationWarning naming it (harness/moved.py: forwarded)."""
    from stereodyn.harness.analysis import verdicts, workprecision
    from stereodyn.harness.pipeline import checks, work_precision

    with pytest.warns(DeprecationWarning, match=r"use stereodyn\.harness\.pipeline\.work_precision\.analyse"):
        assert workprecision.analyse is work_precision.analyse
    with pytest.warns(DeprecationWarning, match=r"use stereodyn\.harness\.pipeline\.checks\.energy_verdicts"):
        assert verdicts.energy_verdicts is checks.energy_verdicts
    with pytest.raises(AttributeError, match="has no attribute 'no_such_name'"):
        workprecision.no_such_name  # noqa: B018
