"""`stereodyn engines`: every registered engine, its origin, whether it is installed, what it runs."""
from __future__ import annotations


def add_parser(commands) -> None:
    engines = commands.add_parser("engines", help="list every registered engine: origin (built in, or the plug-in's "
                                                  "distribution and version), installed or the install command, "
                                                  "models, integrators, precision")
    # 100 columns by default (issue 32)
    engines.add_argument("--wide", action="store_true", help="every column and reason in full, however wide")


def main(args) -> int:
    from ..engines.catalog import render, rows

    print(render(rows(), wide=args.wide))
    return 0
