"""Floating-point precision of a run (results.csv `precision`, Offer.precisions): part of a row's identity. A table
without the column (stereodyn 0.2.0) holds float64 runs. A leaf module: the result tables and the engines import it."""
from __future__ import annotations

import numpy as np

FLOAT64, FLOAT32 = "float64", "float32"
PRECISIONS = (FLOAT64, FLOAT32)


def precisions_problem(precisions) -> str | None:
    """Why a declared set of precisions (Offer.precisions, a scene model's precisions()) is none a plan can use (a
    precision named twice wrote two rows under one key), or None."""
    ok = isinstance(precisions, (tuple, list)) and precisions and all(p in PRECISIONS for p in precisions) \
        and len(set(precisions)) == len(precisions)
    return None if ok else f"must name each of {', '.join(PRECISIONS)} at most once, at least one"
# Unit round-off of each precision: the order fitter's round-off margin uses the row's own (harness.analysis.fitting).
EPS = {FLOAT64: float(np.finfo(np.float64).eps), FLOAT32: float(np.finfo(np.float32).eps)}
