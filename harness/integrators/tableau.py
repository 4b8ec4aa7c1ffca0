"""The explicit Runge–Kutta (Butcher) tableau and the built-in ones, on their own: the methods on the group
(harness.integrators.lie) and on a formulation's coordinates (harness.integrators.vector) both step from it, so the
vector methods do not import the group methods (and stay low in the import graph, tests/test_import_chain.py)."""
from __future__ import annotations

import math
import numbers
from dataclasses import dataclass


@dataclass(frozen=True)
class ButcherTableau:
    """An explicit Runge–Kutta tableau. a: (s, s) strictly lower triangular; b: (s,) weights; c: (s,) nodes."""

    a: tuple[tuple[float, ...], ...]
    b: tuple[float, ...]
    c: tuple[float, ...]

    def __post_init__(self) -> None:
        # Entries as floats, in tuples (a plug-in's lists of lists were exit 3 in the stepper, which adds tuples; NaN
        # or inf passed every check below: issue 46's thirteenth attack)
        for field in ("a", "b", "c"):
            object.__setattr__(self, field, _floats(getattr(self, field), field, 2 if field == "a" else 1))
        # Each refusal names the row (counted from 1, as printed tableaux are) and the condition it breaks: the
        # registry's one line about a plug-in that does not load quotes it.
        s = len(self.b)
        if len(self.c) != s or len(self.a) != s or any(len(row) != s for row in self.a):
            raise ValueError(f"tableau shapes disagree: a {[len(r) for r in self.a]}, b {s}, c {len(self.c)}")
        upper = next(((i, j) for i in range(s) for j in range(i, s) if self.a[i][j] != 0.0), None)
        if upper is not None:
            i, j = upper
            raise ValueError(f"tableau is not explicit: row {i + 1}: a[{i + 1}][{j + 1}] = {float(self.a[i][j])!r} "
                             "on or above the diagonal (a must be strictly lower triangular)")
        # Consistency (c_i = sum_j a_ij, sum_i b_i = 1), to round-off in the decimal coefficients.
        for i, (row, ci) in enumerate(zip(self.a, self.c)):
            if abs(sum(row) - ci) > 1e-14:
                raise ValueError(f"tableau is not consistent: row {i + 1}: c_{i + 1} = {float(ci)!r} but the row of "
                                 f"a sums to {float(sum(row))!r} (need c_i = sum_j a_ij)")
        if abs(sum(self.b) - 1.0) > 1e-14:
            raise ValueError(f"tableau is not consistent: the weights b sum to {float(sum(self.b))!r} (need "
                             "sum_i b_i = 1)")

    @property
    def stages(self) -> int:
        return len(self.b)


def _floats(value, field: str, depth: int) -> tuple:
    """value as nested tuples of floats (depth 1: a vector, 2: a matrix), each entry a finite real number."""
    if not isinstance(value, (tuple, list)):
        rows = " of rows" if depth == 2 else ""
        raise ValueError(f"tableau {field} = {type(value).__name__}: must be a tuple{rows}")
    if depth == 2:
        return tuple(_floats(row, f"{field}[{i + 1}]", 1) for i, row in enumerate(value))
    entries = []
    for j, x in enumerate(value):
        x = float(x) if isinstance(x, numbers.Real) and not isinstance(x, bool) else math.nan  # numpy's too
        if not math.isfinite(x):
            raise ValueError(f"tableau {field}[{j + 1}]: must be a finite number")
        entries.append(x)
    return tuple(entries)


EULER_TABLEAU = ButcherTableau(a=((0.0,),), b=(1.0,), c=(0.0,))

CLASSICAL_RK4 = ButcherTableau(
    a=((0.0, 0.0, 0.0, 0.0),
       (0.5, 0.0, 0.0, 0.0),
       (0.0, 0.5, 0.0, 0.0),
       (0.0, 0.0, 1.0, 0.0)),
    b=(1.0 / 6.0, 1.0 / 3.0, 1.0 / 3.0, 1.0 / 6.0),
    c=(0.0, 0.5, 0.5, 1.0),
)
