"""The suite's case files (TOML), shipped as package data. No logic."""
if __name__ != "stereodyn.cases":  # a checkout's folder imported by its bare name (import cases): refuse, loudly
    raise ImportError(f"'cases' is stereodyn's folder and imports as 'stereodyn.cases', not as {__name__!r}; "
                      "install stereodyn (pip install -e . in a checkout) and import stereodyn.cases")
