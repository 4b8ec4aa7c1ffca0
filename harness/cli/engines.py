"""`stereodyn engines`: every registered engine, its origin, whether it is installed, what it runs."""
from __future__ import annotations


def main(args) -> int:
    from ..engines.catalog import render, rows

    print(render(rows(), wide=args.wide))
    return 0
