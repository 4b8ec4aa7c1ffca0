"""The truth of every case: its engine, formulation and adaptive integrator (the one spelling of the truth engine's
name outside its adapter). A module of names only, so that a run's key (run.spec) and the theory checks
(scenes.checks) read them without the engine registry."""
TRUTH_ENGINE, TRUTH_FORMULATION, TRUTH_INTEGRATOR = "reference", "quaternion", "taylor"
