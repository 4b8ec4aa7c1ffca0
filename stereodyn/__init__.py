"""stereodyn: a verification and benchmark harness for the dynamics of a rigid body with a fixed point.

The subpackages are built from the repository's top-level folders (pyproject.toml, package-dir):
stereodyn.reference (the mathematics), stereodyn.harness (everything that runs things), stereodyn.cases (the suite).
"""
__version__ = "0.2.0"
