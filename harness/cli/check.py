"""`stereodyn check DIR --baseline FILE`: exit 1 when a row got worse than the baseline."""
from __future__ import annotations

import dataclasses
import math

from . import BadInput, warn


def main(args) -> int:
    from ..analysis import gate

    tolerances = gate.Tolerances()
    if args.tolerances is not None:
        tolerances = gate.read_tolerances(args.tolerances)
    # An infinite factor or floor would pass any drift (--factor inf passed a 1e6x regression): finite only.
    for option, value in (("--factor", args.factor), ("--time-factor", args.time_factor)):
        if value is not None and not (math.isfinite(value) and value >= 1.0):
            raise BadInput(f"{option}: must be a finite number >= 1, got {value:g}")
    if args.floor is not None and not (math.isfinite(args.floor) and args.floor >= 0.0):
        raise BadInput(f"--floor: must be a finite number >= 0, got {args.floor:g}")
    if args.factor is not None or args.floor is not None:  # the command line overrides the file, for every metric
        override = {k: v for k, v in (("factor", args.factor), ("floor", args.floor)) if v is not None}
        tolerances = dataclasses.replace(
            tolerances, default=dataclasses.replace(tolerances.default, **override),
            per_metric=tuple((m, dataclasses.replace(t, **override)) for m, t in tolerances.per_metric))
    if args.time_factor is not None:
        tolerances = dataclasses.replace(tolerances, time_factor=args.time_factor)
    from ..run.store import read_manifest, reading

    base = gate.read_baseline_file(args.baseline)
    baseline = base.rows
    with reading(args.dir, args.allow_partial) as warnings:  # never a folder a command is writing, nor unfinished
        current = gate.read_table(args.dir)
        orders = gate.read_orders(args.dir) if base.orders else None
        environment = (read_manifest(args.dir) or {}).get("environment")
    used = sorted({m for row in baseline for m in gate.metric_columns(row) if row.get(m) is not None})
    missing = [m for m in used if m not in current.columns]
    if missing:  # else every row would read as NaN, i.e. worse
        raise BadInput(f"{args.dir / 'results.csv'}: missing columns {', '.join(missing)} (the baseline has them)")
    warn(warnings)  # once the tables read: a folder that cannot be read is one line, the error
    changes = gate.environment_changes(base.environment, environment)
    print(f"environment: {', '.join(changes)}" if changes else "environment: as in the baseline")
    findings = gate.compare(current, baseline, tolerances)
    order_findings = gate.compare_orders(orders, base.orders)
    extra = gate.new_rows(current, baseline)
    note = f"; {extra} rows not in the baseline (not checked)" if extra else ""
    if findings or order_findings:
        for line in gate.summary(findings + order_findings):
            print(line)
        print(gate.findings_table(findings + order_findings))
        worse = len({f.key for f in findings if f.what != "missing"})
        gone = sum(f.what == "missing" for f in findings)
        parts = []
        if worse:
            parts.append(f"{worse} of {len(baseline)} baseline rows got worse than {args.baseline} allows")
        if gone:
            parts.append(f"{gone} of {len(baseline)} baseline rows missing")
        if order_findings:
            parts.append(f"{len(order_findings)} of {len(base.orders)} fitted orders fell")
        print(f"check failed: {'; '.join(parts)}{note}")
        return 1
    orders_note = f", {len(base.orders)} fitted orders" if base.orders else ""
    print(f"check passed: {len(baseline)} baseline rows{orders_note}, none worse{note}")
    return 0
