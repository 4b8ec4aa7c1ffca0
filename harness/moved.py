"""The import paths of 0.2.0 that moved in the layout of issue 20 (DESIGN §1), and those that moved to the pipeline
layer in issue 29, kept importable as aliases.

`import stereodyn.harness.cases` (a plug-in's `from stereodyn.harness.cases import Case`) gives the module at its new
path, the same object, so attributes, monkeypatching and pickling agree, with a DeprecationWarning naming the new path.
An alias is a finder entry rather than a file at the old path, so that git still sees each move as a rename.
"""
from __future__ import annotations

import importlib
import importlib.abc
import importlib.machinery
import sys
import warnings

MOVED = {  # old module under stereodyn.harness -> its path now
    "cases": "scenes.cases", "checks": "scenes.checks", "metrics": "scenes.metrics", "oracles": "scenes.oracles",
    "series": "scenes.series", "sliding_ladder": "scenes.sliding_ladder",
    "distributed": "run.distributed", "dt_ladders": "pipeline.dt_ladders", "plan": "run.plan",
    "processes": "run.processes", "progress": "run.progress", "results": "run.results", "runner": "run.sweep",
    "store": "run.store", "timing": "run.timing", "tolerance_ladders": "pipeline.tolerance_ladders",
    "compare": "analysis.compare", "fitting": "analysis.fitting", "gate": "analysis.gate",
    "summary": "analysis.summary", "verdicts": "analysis.verdicts", "workprecision": "analysis.workprecision",
    # not in 0.2.0: for branches begun before these moved
    "pareto": "analysis.pareto", "step_advice": "analysis.step_advice",
    # issue 29: the modules of analysis/ that ran simulations are the pipeline's (their pure tables and rules stay in
    # analysis: ladders.py, step_advice.py)
    "analysis.dt_ladders": "pipeline.dt_ladders", "analysis.tolerance_ladders": "pipeline.tolerance_ladders",
    "analysis.advice": "pipeline.advice",
}
PACKAGE = "stereodyn.harness"


class _Alias(importlib.abc.MetaPathFinder, importlib.abc.Loader):
    def find_spec(self, fullname, path=None, target=None):
        if not fullname.startswith(PACKAGE + ".") or fullname[len(PACKAGE) + 1:] not in MOVED:
            return None
        return importlib.machinery.ModuleSpec(fullname, self)

    def create_module(self, spec):
        new = f"{PACKAGE}.{MOVED[spec.name[len(PACKAGE) + 1:]]}"
        warnings.warn(f"{spec.name} is deprecated: import {new}", DeprecationWarning, stacklevel=2)
        module = importlib.import_module(new)
        spec.loader_state = module.__spec__
        return module

    def exec_module(self, module):
        # already executed at its new path; the import machinery stamped the alias's spec on it: give it back
        module.__spec__ = module.__spec__.loader_state


def install() -> None:
    if not any(isinstance(finder, _Alias) for finder in sys.meta_path):
        sys.meta_path.append(_Alias())


def forwarded(module: str, name: str, moved: dict[str, str]):
    """A module's __getattr__ for names that moved out of it (moved: name -> its module now, under stereodyn.harness):
    the object at its new home, with a DeprecationWarning naming it; AttributeError for any other name. The import is
    by name, at the first use: an analysis module never imports the pipeline (tests/test_layers.py)."""
    if name not in moved:
        raise AttributeError(f"module {module!r} has no attribute {name!r}")
    new = f"{PACKAGE}.{moved[name]}"
    warnings.warn(f"{module}.{name} is deprecated: use {new}.{name}", DeprecationWarning, stacklevel=2)
    return getattr(importlib.import_module(new), name)
