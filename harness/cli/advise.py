"""`stereodyn advise CASE --engine E`: the largest step (or tolerance) that reaches each accuracy target, checked by
runs (harness.pipeline.advice)."""
from __future__ import annotations

import math
import sys

from .common import BadInput, budget_options, budgets_of, _count, _list, override, _scale, _targets
from ..engines import engine_names
from ..scenes import cases as case_files


def add_parser(commands) -> None:
    advise = commands.add_parser("advise", help="the largest dt (or tolerance) of an engine's integrators that "
                                                 "reaches an accuracy on a case, checked by runs")
    advise.add_argument("case", metavar="CASE_OR_FILE", help="a suite case name or a .toml path")
    advise.add_argument("--engine", required=True, help="the engine whose integrators to advise on")
    advise.add_argument("--integrator", type=_list, default=None,
                        help="comma-separated (default: the engine's default sweep with a declared order or error "
                             "control)")
    advise.add_argument("--formulation", default=None, help="the engine's model (default quaternion, or its first)")
    advise.add_argument("--target", type=_targets, default=None,
                        help="max attitude error over the case's horizon, rad, comma-separated (default 1e-3,1e-6,1e-9)")
    advise.add_argument("--t-end", type=_scale, default=None, help="simulated span, replacing the case's t_end")
    advise.add_argument("--max-steps", type=_count, default=None, metavar="N",
                        help="smallest dt tried = t_end / N (default 200000)")
    budget_options(advise)  # a hung plug-in's answer names --run-budget (fifth attack: advise had none)
    advise.add_argument("--jobs", type=_count, default=1,
                        help="worker processes, one integrator's search each at a time (default 1: a family's "
                             "search runs point after point)")


def main(args) -> int:
    from ..pipeline import advice as advising
    from ..scenes import scene_of
    from ..analysis.summary import TERMINAL_TARGETS

    if args.engine not in engine_names():
        raise BadInput(f"--engine: unknown engine {args.engine}; valid: {', '.join(engine_names())}")
    case = case_files.find_case(args.case)
    if not scene_of(case).work_precision:  # the step search reads an attitude error's convergence (dt ladders)
        raise BadInput(f"{args.case}: {scene_of(case).title} has no attitude error to advise on")
    if args.t_end is not None:
        args.dt = None
        case = override(case, args)
    max_steps = args.max_steps or ADVISE_MAX_STEPS
    if max_steps < 2 * advising.MIN_STEPS or case.t_end / max_steps < case_files.MIN_SCALE:
        raise BadInput(f"--max-steps: must be >= {2 * advising.MIN_STEPS} and keep t_end / N >= "
                       f"{case_files.MIN_SCALE:g}, got {max_steps}")
    try:
        families = advising.families_to_advise(case, args.engine, args.integrator, args.formulation)
    except ValueError as exc:
        raise BadInput(str(exc)) from None
    if not families:
        from ..engines import get_engine
        from ..engines.declared import rigid_body
        from ..run.plan import Hooks

        engine = get_engine(args.engine)
        ask = Hooks(engine, args.engine)
        ask.model = rigid_body(engine)
        why = ask.reason("unsupported(case)", ask.model.unsupported, case)
        raise BadInput(f"--engine {args.engine}: nothing to advise on case {case.name}" + (f" ({why})" if why else ""))
    targets = tuple(sorted(args.target or TERMINAL_TARGETS, reverse=True))
    say = lambda text: print(f"stereodyn: {text}", file=sys.stderr)  # noqa: E731
    from .. import budget
    from ..run.pool import local_pool

    budget.configure(budgets_of(args))  # here and in the workers (local_pool passes it on)
    with local_pool(args.jobs, len(families)) as pool:  # a plug-in's runs on watched workers, as run's (issue 46, F1)
        table, why = advising.advise(case, families, targets, max_steps, say, pool)
    print("\n".join(advice_lines(case, table, why, families)))
    return 0


ADVISE_MAX_STEPS = 200_000   # advise's smallest dt: t_end / 200000, the full ladders' (RK4's floor is above it)


def advice_lines(case, table, why: dict, families) -> list[str]:
    """`stereodyn advise`'s answer: per family and target, the step (`dt = VALUE`) or tolerance, checked."""
    horizon = case.horizon if case.horizon is not None else case.t_end
    lines = [f"{case.name}: the largest step that keeps the max attitude error over 0 … {horizon:g} s within the "
             "target (checked by runs)"]
    for family, adaptive in families:
        name = " ".join(x for x in (family.engine, family.formulation, family.integrator) if x)
        if family.key in why:
            lines.append(f"{name}: no advice, no fitted order ({why[family.key]})")
            continue
        rows = table[(table["engine"] == family.engine) & (table["formulation"] == family.formulation)
                     & (table["integrator"] == family.integrator)]
        what = "tolerance" if adaptive else "dt"
        for _, row in rows.iterrows():
            head = f"{name}, error <= {row['target']:.0e} rad: "
            if not math.isfinite(row[what]):
                lines.append(head + row["note"])
                continue
            cost = f", {row['us_per_sim_s']:.3g} µs per simulated s" if math.isfinite(row["us_per_sim_s"]) else ""
            fails = (f"; {what} = {row['fails_at']:.4g} gives {_above(row['error_fails'], row['target'])}"
                     if math.isfinite(row["fails_at"]) else "")
            unit = " s" if what == "dt" else ""
            lines.append(head + f"{what} = {row[what]:.4g}{unit} (error {row['error_checked']:.3g}{cost}{fails})"
                         + (f" [{row['note']}]" if row["note"] else ""))
            lines.append(f"    model: error ≈ C {what}^{row['order']:.2f}, estimate {what} = {row['estimate']:.3g}; "
                         f"{int(row['runs'])} check run{'' if int(row['runs']) == 1 else 's'}")
    return lines


def _above(error: float, target: float) -> str:
    """An error that missed the target, with the digits that show it did (1.0003e-06 is not "1e-06")."""
    for digits in (3, 6, 10):
        text = f"{error:.{digits}g}"
        if float(text) > target:
            return text
    return repr(error)
