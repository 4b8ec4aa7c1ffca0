"""`stereodyn cases`: list the suite's cases with their tags."""
from __future__ import annotations

from ..scenes import cases as case_files


def add_parser(commands) -> None:
    commands.add_parser("cases", help="list the suite's cases with tags")


def main(args) -> int:
    for case in case_files.load_suite():
        print(f"{case.name:20s} [{', '.join(case.tags)}]  {case.description}")
    return 0
