"""Everything that runs things: cases, engines, integrators, sweeps, metrics, store, reports, gate, CLI."""
if __name__ != "stereodyn.harness":  # a checkout's folder imported by its bare name (import harness): refuse, loudly
    raise ImportError(f"'harness' is stereodyn's folder and imports as 'stereodyn.harness', not as {__name__!r}; "
                      "install stereodyn (pip install -e . in a checkout) and import stereodyn.harness")
