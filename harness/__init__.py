"""Everything that runs things: cases, engines, integrators, sweeps, metrics, store, reports, gate, CLI."""
if __name__ != "stereodyn.harness":  # a checkout's folder imported by its bare name (import harness): refuse, loudly
    raise ImportError(f"'harness' is stereodyn's folder and imports as 'stereodyn.harness', not as {__name__!r}; "
                      "install stereodyn (pip install -e . in a checkout) and import stereodyn.harness")

import importlib
import importlib.abc
import importlib.util
import sys
import warnings

# Module paths of 0.2.0 that moved (old -> new, relative to stereodyn.harness). Importing an old path gives the new
# module itself (one object: a monkeypatch through either name reaches both), with a DeprecationWarning. No file
# stays at the old path, so git follows each move as a rename.
MOVED = {
    "compare": "analysis.compare",
    "fitting": "analysis.fitting",
    "gate": "analysis.gate",
    "pareto": "analysis.pareto",  # (not in 0.2.0: for branches that began before the move)
    "summary": "analysis.summary",
    "verdicts": "analysis.verdicts",
    "workprecision": "analysis.workprecision",
}


class _MovedModules(importlib.abc.MetaPathFinder, importlib.abc.Loader):
    """The import hook behind MOVED."""

    def find_spec(self, fullname, path=None, target=None):
        old = fullname.removeprefix(__name__ + ".")
        if old != fullname and old in MOVED:
            return importlib.util.spec_from_loader(fullname, self)
        return None

    def create_module(self, spec):
        new = f"{__name__}.{MOVED[spec.name.removeprefix(__name__ + '.')]}"
        warnings.warn(f"{spec.name} moved to {new} (stereodyn 0.3); import it from there", DeprecationWarning,
                      stacklevel=2)
        module = importlib.import_module(new)
        spec.loader_state = module.__spec__  # the import system sets __spec__ to this alias's: exec_module puts it back
        return module

    def exec_module(self, module):  # the new module ran when it was imported
        module.__spec__ = module.__spec__.loader_state


if not any(isinstance(finder, _MovedModules) for finder in sys.meta_path):
    sys.meta_path.append(_MovedModules())
