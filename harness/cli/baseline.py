"""`stereodyn baseline DIR --out FILE`: the regression baseline of DIR/results.csv."""
from __future__ import annotations

from .common import _allow_partial, GATE_MODES, output_file, _path, warn


def add_parser(commands) -> None:
    baseline = commands.add_parser("baseline", help="write the regression baseline of DIR/results.csv")
    baseline.add_argument("dir", type=_path)
    baseline.add_argument("--out", type=_path, required=True, metavar="FILE", help="baseline file to write (JSON)")
    baseline.add_argument("--mode", choices=GATE_MODES, default=GATE_MODES[0],
                          help="what `check` will compare against it, recorded in the file: same-machine (the "
                               "default; the same machine and library versions, factor 1.05) or cross-machine "
                               "(another CPU or versions, factor 2)")
    _allow_partial(baseline)


def main(args) -> int:
    from ..analysis import gate
    from ..run.store import read_manifest, reading

    output_file(args.out, "--out")
    with reading(args.dir, args.allow_partial) as warnings:  # never a folder a command is writing, nor unfinished
        manifest = read_manifest(args.dir) or {}
        table, orders = gate.read_table(args.dir), gate.read_orders(args.dir)
    warn(warnings)  # once the tables read: a folder that cannot be read is one line, the error
    rows = gate.write_baseline(table, args.out, gate.recorded_environment(manifest), orders, args.mode)
    print(f"wrote {args.out} ({rows} rows, {0 if orders is None else len(orders)} fitted orders; "
          f"{args.mode} mode: check allows {gate.MODES[args.mode].factor:g} x baseline + "
          f"{gate.MODES[args.mode].floor:g})")
    return 0
