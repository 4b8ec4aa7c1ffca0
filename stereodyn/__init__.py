"""stereodyn: a verification and benchmark harness for the dynamics of a rigid body with a fixed point.

The subpackages are built from the repository's top-level folders (pyproject.toml, package-dir):
stereodyn.reference (the mathematics), stereodyn.harness (everything that runs things), stereodyn.cases (the suite).
"""
import os as _os

__version__ = "0.2.0"

# A pool worker of a sweep ties itself to its parent and ignores Ctrl-C here, its first stereodyn line, before the
# seconds of imports that precede its pool initializer (harness/run/processes.py).
if _os.environ.get("STEREODYN_POOL_PARENT"):
    from stereodyn.harness.run import processes as _processes

    if _processes.is_worker():
        _processes.worker_started()
