"""The import paths of 0.2.0 that moved in the layout of issue 20 (DESIGN §1), kept importable as aliases.

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
    "distributed": "run.distributed", "dt_ladders": "analysis.dt_ladders", "plan": "run.plan",
    "processes": "run.processes", "progress": "run.progress", "results": "run.results", "runner": "run.sweep",
    "store": "run.store", "timing": "run.timing", "tolerance_ladders": "analysis.tolerance_ladders",
    "compare": "analysis.compare", "fitting": "analysis.fitting", "gate": "analysis.gate",
    "summary": "analysis.summary", "verdicts": "analysis.verdicts", "workprecision": "analysis.workprecision",
    # not in 0.2.0: for branches begun before these moved
    "pareto": "analysis.pareto", "step_advice": "analysis.step_advice",
}
PACKAGE = "stereodyn.harness"


class _Alias(importlib.abc.MetaPathFinder, importlib.abc.Loader):
    def find_spec(self, fullname, path=None, target=None):
        package, _, leaf = fullname.rpartition(".")
        if package != PACKAGE or leaf not in MOVED:
            return None
        return importlib.machinery.ModuleSpec(fullname, self)

    def create_module(self, spec):
        new = f"{PACKAGE}.{MOVED[spec.name.rpartition('.')[2]]}"
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
