"""`stereodyn engines`: every registered engine, its origin, whether it is installed, what it runs."""
from __future__ import annotations


def main(args) -> int:
    from ..engines.catalog import render, rows

    print(render(rows()))
    return 0
