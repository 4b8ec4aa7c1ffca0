"""`stereodyn integrators`: every integrator `run --integrators` accepts."""
from __future__ import annotations



def main(args) -> int:
    from ..report.method import integrator_rows, listing

    print(listing(integrator_rows(), wide=args.wide))
    return 0
