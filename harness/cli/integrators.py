"""`stereodyn integrators`: every integrator `run --integrators` accepts."""
from __future__ import annotations


def add_parser(commands) -> None:
    listed = commands.add_parser("integrators", help="list every integrator `run --integrators` accepts, with its "
                                                     "metadata and origin (built in, or the plug-in's distribution)")
    # 100 columns by default (issue 32)
    listed.add_argument("--wide", action="store_true", help="every column and reason in full, however wide")


def main(args) -> int:
    from ..report.method import integrator_rows, listing

    print(listing(integrator_rows(), wide=args.wide))
    return 0
