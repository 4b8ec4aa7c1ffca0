"""0.2.0's import paths of the modules moved by the layout of issue 20 keep working (harness/moved.py): the old name
gives the module at its new path, the same object, with a DeprecationWarning naming the new path."""
import importlib
import subprocess
import sys

import pytest

from stereodyn.harness.moved import MOVED


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
            "import stereodyn.harness.cli.run, stereodyn.harness.cli.advise, stereodyn.harness.analysis.advice\n"
            "import stereodyn.harness.report.build, stereodyn.harness.testing, stereodyn.harness.engines.reference\n")
    subprocess.run([sys.executable, "-c", code], check=True)
