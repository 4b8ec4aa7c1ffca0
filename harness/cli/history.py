"""`stereodyn history DIR ...`: result folders or baselines lined up in order, every series with its steps flagged."""
from __future__ import annotations

import math
import os
import subprocess
from contextlib import ExitStack
from pathlib import Path

from ..words import one_line
from .common import _allow_partial, BadInput, _path, _steps, warn


def load_point(path: Path, label: str, held: ExitStack, allow_partial: bool, warnings: list[str],
               written: Path | None = None):
    """A result folder (read only when no command writes it, and complete) or a baseline file as a history Point;
    `written`: the folder this command writes (and has locked), whose own completeness is read without a lock."""
    import pandas as pd

    from ..analysis import compare, gate
    from ..analysis.history import Point
    from ..run.store import STORE_DIR, completeness, reading

    if path.is_dir():
        own = written is not None and os.path.realpath(path) == os.path.realpath(written)
        warnings += (completeness(path, allow_partial) if own and (path / STORE_DIR).is_dir()
                     else held.enter_context(reading(path, allow_partial)))
    table, environment = compare.load(path)
    if path.is_dir():
        orders = gate.read_orders(path)
        orders = (pd.DataFrame() if orders is None else
                  orders.rename(columns={"order": "fitted", "declared_order": "declared"}))
    else:
        orders = pd.DataFrame(gate.read_baseline_file(path).orders)
    return Point(one_line(label), str(path), table, orders, environment)  # a CR in a label broke history_points.csv


def labels(paths: list[Path]) -> list[str]:
    """Each path's name, made unique by its place where two share one."""
    names = [p.stem if p.is_file() else p.name or str(p) for p in paths]
    return [f"{n} ({i})" if names.count(n) > 1 else n for i, n in enumerate(names, 1)]


def commits(repo: Path) -> list[str]:
    """The repository's commits, oldest first (every branch, topological order)."""
    try:
        done = subprocess.run(["git", "-C", str(repo), "rev-list", "--topo-order", "--reverse", "--all"],
                              capture_output=True, text=True, timeout=60)
    except (OSError, subprocess.TimeoutExpired) as exc:
        raise BadInput(f"--repo {repo}: cannot run git ({exc})") from None
    if done.returncode != 0:
        said = done.stderr.strip().splitlines()
        raise BadInput(f"--repo {repo}: not a git repository ({said[-1] if said else f'git exited {done.returncode}'})")
    return done.stdout.split()


def build(points: list, by: str, out: Path, factor: float, order_step: float, commit_list=None) -> tuple:
    """Order the points, compute the history and write it: (pages, steps table)."""
    from ..analysis import history
    from ..report import history as page

    try:
        points = history.order(points, by, commit_list)
    except ValueError as exc:
        from ..run.store import manifest_problem

        why = next((manifest_problem(Path(p.path)) for p in points if str(exc).startswith(f"{p.path}:")
                    and Path(p.path).is_dir()), None)  # a garbled runs.json is named as such, not as a missing date
        raise BadInput(f"--by {by}: {why}, so --by {by} cannot place it" if why else f"--by {by}: {exc}") from None
    table, steps = history.history(points, factor, order_step)
    listed = history.points_table(points, steps).assign(ordered_by=by)
    return page.write(out, table, steps, listed), steps, points


def check_steps(args) -> None:
    for option, value, low in (("--step-factor", args.step_factor, 1.0), ("--order-step", args.order_step, 0.0)):
        if not (math.isfinite(value) and value > low):
            raise BadInput(f"{option}: must be a finite number > {low:g}, got {value:g}")


def add_parser(commands) -> None:
    history = commands.add_parser("history", help="result folders or baselines in order (commit, date, an engine's "
                                                   "version): each metric, status and fitted order over the "
                                                   "sequence, steps flagged (OUT/history.html, OUT/history*.csv)")
    history.add_argument("dirs", type=_path, nargs="+", metavar="DIR", help="result folders or baseline files")
    history.add_argument("--by", default="date", metavar="date|commit|given|PACKAGE",
                         help="order by runs.json's date (default), git commit (in --repo's history), as given, or "
                              "the version of a package the environment records (e.g. mujoco)")
    history.add_argument("--repo", type=_path, default=Path("."), help="the git repository for --by commit")
    history.add_argument("--out", type=_path, default=Path("history"), help="where to write (default ./history)")
    _steps(history)
    _allow_partial(history)


def main(args) -> int:
    from .common import output_folder
    from ..report import index
    from ..run.store import STORE_DIR, folder_lock

    check_steps(args)
    if len(args.dirs) < 2:
        raise BadInput(f"history: needs at least two result folders or baselines, got {len(args.dirs)}")
    real = [os.path.realpath(path) for path in args.dirs]
    twice = next((path for path, name in zip(args.dirs, real) if real.count(name) > 1), None)
    if twice is not None:  # one run counted twice would look like a series that did not move
        raise BadInput(f"history: {twice} given twice (each run once)")
    commit_list = commits(args.repo) if args.by == "commit" else None
    out = output_folder(args.out, "--out", store=False)
    warnings: list[str] = []
    with ExitStack() as held:
        if (out / STORE_DIR).is_dir():  # a result folder: locked as `run` locks it while history writes there
            held.enter_context(folder_lock(out))
        points = [load_point(path, label, held, args.allow_partial, warnings, out)
                  for path, label in zip(args.dirs, labels(args.dirs))]
        warn(warnings)
        pages, steps, ordered = build(points, args.by, out, args.step_factor, args.order_step, commit_list)
        if (out / index.INDEX_FILE).is_file():  # a result folder's index now lists history's files too
            index.write(out)
    print(f"{len(ordered)} runs in order ({args.by}): {', '.join(one_line(p.label) for p in ordered)}")
    worse = steps[steps["direction"] == "worse"] if len(steps) else steps
    print(f"{len(steps)} steps flagged, {len(worse)} worse" + (":" if len(worse) else ""))
    for _, step in worse.head(10).iterrows():
        print(one_line(f"  {step['case']} {step['engine']} {step['formulation']} {step['integrator']} "
                       f"dt={step['dt'] or '-'} {step['quantity']}: {step['change']} at {step['label']}"))
    print(f"wrote {pages[0]} and {pages[1]}")
    return 0
