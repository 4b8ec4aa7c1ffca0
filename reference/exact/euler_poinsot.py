"""0.2.0's path of the torque-free body in closed form: its home is reference/torque_free.py (outside this package, so
that the splitting integrator imports the free flow without every exact solution); its names stay importable here."""
from ..torque_free import (SEPARATRIX_TOL, FreeMotion, euler_poinsot_check, euler_poinsot_solve,  # noqa: F401
                           free_motion, montgomery_phase, period, precession_per_period, separatrix_check,
                           separatrix_distance, separatrix_omega, solid_angle)
