"""The truth's names, importable from here as before (their home: harness/truth_names.py, outside this package)."""
from ..truth_names import TRUTH_ENGINE, TRUTH_FORMULATION, TRUTH_INTEGRATOR  # noqa: F401 (re-exported)
