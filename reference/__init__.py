"""The mathematics: formulations, rotations and charts, integrals, exact solutions, the truth. Never imports harness."""
if __name__ != "stereodyn.reference":  # a checkout's folder imported by its bare name (import reference): refuse, loudly
    raise ImportError(f"'reference' is stereodyn's folder and imports as 'stereodyn.reference', not as {__name__!r}; "
                      "install stereodyn (pip install -e . in a checkout) and import stereodyn.reference")
