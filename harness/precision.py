"""Floating-point precision of a run (results.csv `precision`, Offer.precisions): part of a row's identity. A table
without the column (stereodyn 0.2.0) holds float64 runs. A leaf module: the result tables and the engines import it."""
from __future__ import annotations

import numpy as np

FLOAT64, FLOAT32 = "float64", "float32"
PRECISIONS = (FLOAT64, FLOAT32)
# Unit round-off of each precision: the order fitter's round-off margin uses the row's own (harness.analysis.fitting).
EPS = {FLOAT64: float(np.finfo(np.float64).eps), FLOAT32: float(np.finfo(np.float32).eps)}
