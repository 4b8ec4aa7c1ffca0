"""python -m stereodyn: the command line."""
from stereodyn.harness.cli import main

if __name__ == "__main__":
    raise SystemExit(main())
