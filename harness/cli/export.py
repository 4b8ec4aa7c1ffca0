"""`stereodyn export CASE --format mjcf|urdf`: write the engine model of a case."""
from __future__ import annotations

import sys

from .common import output_file, _path, _scale
from ..scenes import cases as case_files


def add_parser(commands) -> None:
    export = commands.add_parser("export", help="write the engine model of a case (MJCF for MuJoCo, URDF)")
    export.add_argument("case", metavar="CASE", help="a suite case name or a .toml path")
    export.add_argument("--format", required=True, help="a model format of an engine: mjcf (MuJoCo), urdf (Pinocchio)")
    export.add_argument("--out", type=_path, default=None, metavar="FILE", help="default: standard output")
    export.add_argument("--integrator", default=None, help="MJCF only: MuJoCo integrator (default rk4)")
    export.add_argument("--dt", type=_scale, default=None, help="MJCF only: timestep (default: the case's first dt)")


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
