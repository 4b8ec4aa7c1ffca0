"""`stereodyn export CASE --format mjcf|urdf`: write the engine model of a case."""
from __future__ import annotations

import sys

from . import output_file
from ..scenes import cases as case_files


def main(args) -> int:
    from ..export import export
    from ..run.results import write_atomic

    if args.out is not None:
        output_file(args.out, "--out")
    text = export(case_files.find_case(args.case), args.format, args.integrator, args.dt)
    if args.out is None:
        sys.stdout.write(text)
    else:
        write_atomic(args.out, text)
        print(f"wrote {args.out}", file=sys.stderr)
    return 0
