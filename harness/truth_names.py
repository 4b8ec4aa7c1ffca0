"""The truth of every case: its engine, formulation and adaptive integrator (the one spelling of the truth engine's
name outside its adapter). A leaf module of names, outside the engines package, so that a run's key (run.spec) and
the theory checks (scenes.checks) read them without running the engine registry (harness/engines/__init__.py)."""
TRUTH_ENGINE, TRUTH_FORMULATION, TRUTH_INTEGRATOR = "reference", "quaternion", "taylor"
