"""`stereodyn check DIR --baseline FILE`: exit 1 when a row got worse than the baseline."""
from __future__ import annotations

import dataclasses
import math
import os
from pathlib import Path

from .common import _allow_partial, BadInput, GATE_MODES, output_file, _path, warn

STEP_SUMMARY = "GITHUB_STEP_SUMMARY"  # set by GitHub Actions: a file whose markdown the job's page shows


def add_parser(commands) -> None:
    gate = commands.add_parser("check", help="exit 1 and print the rows of DIR that got worse than the baseline")
    gate.add_argument("dir", type=_path)
    gate.add_argument("--baseline", type=_path, required=True, metavar="FILE")
    _allow_partial(gate)
    gate.add_argument("--tolerances", type=_path, default=None, metavar="FILE.toml",
                       help="[default] factor/floor, [metric.NAME] factor/floor, [time] factor")
    gate.add_argument("--mode", choices=GATE_MODES, default=None,
                       help="the default tolerance: same-machine (factor 1.05) or cross-machine (factor 2); default: "
                            "the mode the baseline records (cross-machine for a baseline that records none)")
    gate.add_argument("--factor", type=float, default=None,
                       help="a drift or error may grow to factor * baseline + floor (default: the mode's, every "
                            "metric)")
    gate.add_argument("--floor", type=float, default=None, help="absolute floor (default 1e-12, every metric)")
    gate.add_argument("--time-factor", type=float, default=None,
                       help="also fail when us_per_step exceeds this factor times the baseline's (only on one idle "
                            "machine: a loaded one moves timings by more, docs/DESIGN.md §4, Baselines)")
    gate.add_argument("--junit", type=_path, default=None, metavar="FILE",
                       help="also write JUnit XML: one test case per baseline row and fitted order")
    gate.add_argument("--quiet", action="store_true", help="print nothing on success, only the failures otherwise")


def main(args) -> int:
    from ..analysis import gate

    # An infinite factor or floor would pass any drift (--factor inf passed a 1e6x regression): finite only.
    for option, value in (("--factor", args.factor), ("--time-factor", args.time_factor)):
        if value is not None and not (math.isfinite(value) and value >= 1.0):
            raise BadInput(f"{option}: must be a finite number >= 1, got {value:g}")
    if args.floor is not None and not (math.isfinite(args.floor) and args.floor >= 0.0):
        raise BadInput(f"--floor: must be a finite number >= 0, got {args.floor:g}")
    if args.junit is not None:
        output_file(args.junit, "--junit")
        if _reads(args, args.junit):
            raise BadInput(f"--junit {args.junit}: a file of the folder checked, the baseline or the tolerance file; "
                           "give a new path or one outside them")
    from ..run.store import manifest_problem, read_manifest, reading

    base = gate.read_baseline_file(args.baseline)
    # The mode sets the default tolerance; a tolerance file, then --factor/--floor, refine it.
    mode = args.mode or base.applied_mode
    source = ("--mode" if args.mode else "the baseline's" if base.mode
              else "the baseline records none: stereodyn 0.2's factor 2")
    tolerances = gate.Tolerances(gate.MODES[mode])
    if args.tolerances is not None:
        tolerances = gate.read_tolerances(args.tolerances, tolerances)
    if args.factor is not None or args.floor is not None:  # the command line overrides the file, for every metric
        override = {k: v for k, v in (("factor", args.factor), ("floor", args.floor)) if v is not None}
        tolerances = dataclasses.replace(
            tolerances, default=dataclasses.replace(tolerances.default, **override),
            per_metric=tuple((m, dataclasses.replace(t, **override)) for m, t in tolerances.per_metric))
    if args.time_factor is not None:
        tolerances = dataclasses.replace(tolerances, time_factor=args.time_factor)
    baseline = base.rows
    with reading(args.dir, args.allow_partial) as warnings:  # never a folder a command is writing, nor unfinished
        current = gate.read_table(args.dir)
        orders = gate.read_orders(args.dir) if base.orders else None
        manifest = read_manifest(args.dir)
        environment = gate.recorded_environment(manifest) if manifest else None
    used = sorted({m for row in baseline for m in gate.metric_columns(row) if row.get(m) is not None})
    missing = [m for m in used if m not in current.columns]
    if missing:  # else every row would read as NaN, i.e. worse
        raise BadInput(f"{args.dir / 'results.csv'}: missing columns {', '.join(missing)} (the baseline has them)")
    warn(warnings)  # once the tables read: a folder that cannot be read is one line, the error
    changes = gate.environment_changes(base.environment, environment, manifest_problem(args.dir))
    context = [f"environment: {', '.join(changes)}" if changes else "environment: as in the baseline",
               gate.mode_line(mode, source, tolerances, changes)]
    verdict = gate.Verdict(len(baseline), len(base.orders), tuple(gate.compare(current, baseline, tolerances)),
                           tuple(gate.compare_orders(orders, base.orders)), gate.new_rows(current, baseline))
    headline = verdict.headline(str(args.baseline))
    findings = [*verdict.findings, *verdict.order_findings]
    groups = gate.summary(findings)
    if args.junit is not None or os.environ.get(STEP_SUMMARY):
        _write_ci(args, base, verdict, headline, context, groups)
    if not args.quiet:
        print("\n".join(context))
    if findings:
        print("\n".join(groups))
        print(gate.findings_table(findings))
    if findings or not args.quiet:
        print(headline)
    return 0 if verdict.passed else 1


def _write_ci(args, base, verdict, headline: str, context: list[str], groups: list[str]) -> None:
    """--junit FILE (an unwritable one was refused before the check), and the step summary when GitHub's variable
    names a file (appended, as GitHub expects; one that cannot be written is a warning: the gate's status stands)."""
    from ..atomic import append_regular
    from ..report.check import junit, step_summary
    from ..run.results import write_atomic

    if args.junit is not None:
        try:
            write_atomic(args.junit, junit(base, verdict, headline))
        except OSError as exc:
            raise BadInput(f"--junit {args.junit}: cannot write ({exc.strerror or exc})") from None
    path = os.environ.get(STEP_SUMMARY)
    if path and _reads(args, Path(path)):  # appended to the results.csv it checked, which every reader then refused
        warn([f"{STEP_SUMMARY}={path}: a file of the folder checked, the baseline or the tolerance file; the "
              "summary is not written"])
    elif path:
        try:  # a FIFO there (nothing reading it) would block check for ever: a regular file or a new path only
            append_regular(Path(path), step_summary(verdict, headline, context, groups))
        except OSError as exc:
            warn([f"{STEP_SUMMARY}={path}: cannot append the summary ({exc.strerror or exc})"])


def _reads(args, path: Path) -> bool:
    """Whether path is a file check reads or the run wrote: the baseline, the tolerance file, a file that exists in
    the folder checked (issue 46's fourteenth attack: GITHUB_STEP_SUMMARY=DIR/results.csv got the summary appended to
    the table it had checked, which every reader then refused). A new path in the folder is no file of it."""
    target = os.path.realpath(path)
    folder = os.path.realpath(args.dir).rstrip(os.sep) + os.sep
    inputs = [os.path.realpath(p) for p in (args.baseline, args.tolerances) if p is not None]
    return target in inputs or (target.startswith(folder) and os.path.lexists(target))
