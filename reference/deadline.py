"""The wall-time deadline's exception, on its own so that the harness's budgets import it without the truth (a leaf:
harness/budget.py sits low in the import graph, tests/test_import_chain.py)."""
from __future__ import annotations


class OutOfTime(Exception):
    """A heyoka propagation stopped at its wall-time deadline (step_callback); the harness names the budget."""
