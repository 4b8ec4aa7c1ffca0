"""`stereodyn matrix SPEC ... [-- RUN ARGUMENTS]`: the same runs in one isolated environment per package
specification (uv, harness/run/environments.py), then the history over the environments and a compare of each
neighbouring pair. Written to OUT: matrix.csv (one row per environment: ok, or why not), orders.csv (every fitted
order side by side), runs/N-NAME/ (each environment's result folder and its log), history.* and compare/N-M/."""
from __future__ import annotations

import hashlib
import itertools
import json
import math
import re
import shutil
import signal
import subprocess
from contextlib import ExitStack
from pathlib import Path

from ..atomic import write_atomic
from ..words import one_line
from .common import BadInput, check_options, Parser, output_folder, _path, select_cases, _steps, warn

# The quick suite (README, "Regression CI"; .ci/run gates it against reports/baselines/quick.json).
QUICK = ("free-asymmetric", "lagrange-top", "kovalevskaya", "heavy-asymmetric", "--t-end", "2", "--dt", "1e-2,3e-3")
RUN_STAMP = "matrix-run.json"  # in a run folder: the environment and arguments it was run with (reused if the same)
RUNS_SEAL = "runs.json sha256"  # in the stamp: the folder's runs.json as the matrix's run left it
ORDERS_SHOWN = 20


def environments(specs: list[str], cross: bool) -> list[tuple[str, tuple[str, ...]]]:
    """(label, requirements) per environment: each SPEC is one environment's space-separated requirements; --cross:
    each SPEC is one requirement, and every combination of one per package is an environment."""
    from packaging.requirements import InvalidRequirement, Requirement

    parsed = []
    for spec in specs:
        items = spec.split()
        if not items:
            raise BadInput("matrix: an empty SPEC")
        for item in items:
            try:
                Requirement(item)
            except InvalidRequirement as exc:
                raise BadInput(f"matrix: SPEC {spec!r}: {item!r} is not a requirement ({exc})") from None
        parsed.append(tuple(items))
    if not cross:
        labels = [" ".join(items) for items in parsed]
        twice = sorted({label for label in labels if labels.count(label) > 1})
        if twice:
            raise BadInput(f"matrix: SPEC {twice[0]!r} given twice")
        return list(zip(labels, parsed))
    groups: dict[str, list[str]] = {}
    for items in parsed:
        if len(items) != 1:
            raise BadInput(f"matrix --cross: SPEC {' '.join(items)!r}: one requirement per SPEC (the cross product "
                           "combines them)")
        groups.setdefault(Requirement(items[0]).name.lower(), []).append(items[0])
    return [(" ".join(combo), tuple(combo)) for combo in itertools.product(*groups.values())]


def slug(index: int, label: str) -> str:
    return f"{index}-" + (re.sub(r"[^A-Za-z0-9.=+-]+", "-", label).strip("-")[:60] or "env")


# Run arguments that make `stereodyn run` print and exit without a result (argparse's help, and any prefix of it).
_NO_RESULT = ("-h", "--help")


def run_arguments(args) -> list[str]:
    given = list(QUICK) if args.run_args is None else list(args.run_args)
    for option in ("--out", "--resume"):
        if any(a == option or a.startswith(option + "=") for a in given):
            raise BadInput(f"matrix: {option} after --: the matrix chooses each run's folder (OUT/runs/N-NAME)")
    for a in given:
        if a in _NO_RESULT or (len(a) >= 3 and "--help".startswith(a)):  # --h too: run has no other --h option
            raise BadInput(f"matrix: {a} after --: prints the run's help and runs nothing (see stereodyn run --help)")
    return given


class _RunParser(Parser):
    """`stereodyn run`'s parser whose error is the matrix's bad input (one line naming the arguments after --)."""

    def error(self, message: str):
        raise BadInput(f"matrix: after --: {' '.join(message.split())} (see stereodyn run --help)")


def check_run_arguments(argv: list[str]) -> None:
    """Refuse, before anything is built, run arguments this stereodyn's `run` refuses before it runs (an unknown
    option, a value out of its rule, a case it does not have): each environment's run would fail the same, a `run
    failed` row per environment after minutes of installs (issue 46's fourth attack, F6). Only where every environment
    runs this stereodyn (no --stereodyn): another version may take other arguments. Engine and integrator names are
    the environment's to judge (its engines are its packages')."""
    from ..scenes.cases import CaseError
    from .dispatch import command

    top = _RunParser(prog="stereodyn")
    command("run").add_parser(top.add_subparsers(dest="command", required=True))  # by name, as the entry point does
    parsed = top.parse_args(["run", *argv])
    try:
        check_options(parsed)
        select_cases(parsed)
    except (BadInput, CaseError) as exc:
        raise BadInput(f"matrix: after --: {exc}") from None


def command(python: Path, argv: list[str], folder: Path) -> list[str]:
    """The run in an environment: its Python's `stereodyn run ARGV --out FOLDER`."""
    return [str(python), "-m", "stereodyn", "run", *argv, "--out", str(folder)]


def _seal(folder: Path) -> str | None:
    """sha256 of the folder's runs.json (None where it has none): what the matrix's run left there."""
    try:
        return hashlib.sha256((folder / "runs.json").read_bytes()).hexdigest()
    except OSError:
        return None


def _stamp(folder: Path) -> dict | None:
    try:
        stamp = json.loads((folder / RUN_STAMP).read_text())
    except (OSError, ValueError):
        return None
    return stamp if isinstance(stamp, dict) else None


def run_in(environment, folder: Path, argv: list[str], rerun: bool) -> tuple[str, str, bool]:
    """`stereodyn run ARGV --out FOLDER` with the environment's Python: (status, reason, reused). A folder from an
    earlier matrix with the same environment (its cache key) and arguments is reused when it finished, resumed
    (`run --resume`: its stored runs kept) when it was interrupted, unless rerun; any other is emptied, never while
    another command writes it (its lock: StoreBusy, one line)."""
    from ..run import environments as envs
    from ..run.store import folder_lock

    stamp = {"environment": environment.path.name, "run": argv}
    earlier = None if rerun else _stamp(folder)
    same = earlier is not None and {k: earlier.get(k) for k in stamp} == stamp
    # reused only as the matrix's run left it: another command run into the folder since (other arguments, or
    # interrupted there) changed its runs.json, and it was reused as "ok" (issue 46's eleventh attack, F4)
    if same and earlier.get("complete", True) and (folder / "results.csv").is_file() \
            and earlier.get(RUNS_SEAL) == _seal(folder):
        return "ok", "", True
    resume = same and (folder / "store").is_dir()
    if folder.exists() and not resume:
        with folder_lock(folder):  # never a folder a run still writes (an earlier matrix's, or one by hand)
            shutil.rmtree(folder)
    folder.mkdir(parents=True, exist_ok=True)
    write_atomic(folder / RUN_STAMP, json.dumps({**stamp, "complete": False}) + "\n")  # before: an interrupt resumes
    log = folder.parent / f"{folder.name}.log"
    with open(log, "a" if resume else "w") as out:
        done = envs.owned(command(environment.python, argv + (["--resume"] if resume else []), folder), stdout=out,
                          stderr=subprocess.STDOUT, death_signal=signal.SIGTERM)  # a run ends its workers and theirs
    if done.returncode in (130, 143):  # interrupted or terminated there: the matrix is too
        raise KeyboardInterrupt
    if done.returncode == 3:  # a bug in stereodyn is never a row (harness/errors.py), in an environment's run neither
        from ..errors import InternalError

        raise InternalError(f"stereodyn run in the environment {environment.path} ended with exit 3 ({log})",
                            log.read_text(errors="replace")[-8000:])
    if done.returncode != 0:
        lines = [line for line in log.read_text(errors="replace").splitlines() if line.strip()]
        return "run failed", f"stereodyn run exited {done.returncode}: {lines[-1] if lines else 'no output'} " \
                             f"({log})", False
    if not (folder / "results.csv").is_file():  # exit 0 and no table: the run's arguments ran nothing
        return "run failed", f"stereodyn run exited 0 but wrote no results.csv ({log})", False
    write_atomic(folder / RUN_STAMP, json.dumps({**stamp, "complete": True, RUNS_SEAL: _seal(folder)}) + "\n")
    return "ok", "", False


def add_parser(commands) -> None:
    matrix = commands.add_parser("matrix", help="the same runs in one isolated environment per package "
                                                "specification (uv), then their history and a compare of each "
                                                "neighbouring pair; run arguments after --")
    matrix.add_argument("specs", nargs="+", metavar="SPEC",
                        help="one environment's requirements, space-separated ('mujoco==3.3.7', 'mujoco==4.0.0 "
                             "pin==3.4.0')")
    matrix.add_argument("--cross", action="store_true",
                        help="one environment per combination of the specs' packages (a cross product)")
    matrix.add_argument("--out", type=_path, default=Path("matrix"), help="where to write (default ./matrix)")
    matrix.add_argument("--stereodyn", default=None, metavar="PATH_OR_REQUIREMENT",
                        help="the stereodyn installed in each environment (default: this checkout's source, or "
                             "stereodyn==VERSION)")
    matrix.add_argument("--overlay", action="store_true",
                        help="install only the specs over this environment's packages (their new dependencies at "
                             "this environment's versions): fast, not isolated")
    matrix.add_argument("--rerun", action="store_true",
                        help="run again where an earlier matrix ran the same environment and arguments (default: "
                             "reuse its results)")
    _steps(matrix)
    matrix.set_defaults(run_args=None)


def main(args) -> int:
    from ..run import environments as envs
    from ..run.store import folder_lock
    from .history import check_steps

    check_steps(args)
    matrix = environments(args.specs, args.cross)
    argv = run_arguments(args)
    if args.stereodyn is None:
        check_run_arguments(argv)
    try:
        envs.uv_binary()
    except envs.UvMissing as exc:
        raise BadInput(str(exc)) from None
    out = output_folder(args.out, "--out")
    # SIGTERM is Ctrl-C's (harness.cli.dispatch): the run or install under way ends with the matrix (envs.owned)
    with folder_lock(out):  # one matrix at a time in OUT: its runs' folders are its own
        return _matrix(args, matrix, argv, out)


def _matrix(args, matrix: list, argv: list[str], out: Path) -> int:
    import pandas as pd

    from ..analysis import history as analysis
    from ..report.compare import compare
    from ..run import environments as envs
    from .history import build, load_point

    rows, points = [], []
    for index, (label, requirements) in enumerate(matrix, 1):
        print(f"[{index}/{len(matrix)}] {label}: environment ...", flush=True)
        environment = envs.build(requirements, args.stereodyn, args.overlay)
        row = {"environment": label, "requirements": " ".join(requirements), "status": "ok", "reason": "",
               "cached": environment.cached, "path": str(environment.path), "results": ""}
        if environment.reason:
            row.update(status="install failed", reason=environment.reason)
        else:
            folder = out / "runs" / slug(index, label)
            status, reason, reused = run_in(environment, folder, argv, args.rerun)
            row.update(status=status, reason=reason, results=str(folder), reused=reused)
        rows.append(row)
        where = ("cached" if environment.cached else "not built" if environment.reason else "built") \
            + (", runs reused" if row.get("reused") else "")
        print(f"[{index}/{len(matrix)}] {label}: {row['status']} ({where})"
              + (f": {one_line(row['reason'])}" if row["reason"] else ""), flush=True)
    table = pd.DataFrame(rows)
    ran = [r for r in rows if r["status"] == "ok"]
    warnings: list[str] = []
    with ExitStack() as held:
        points = [load_point(Path(r["results"]), r["environment"], held, False, warnings) for r in ran]
    warn(warnings)
    if len(points) >= 2:
        pages, steps, _ = build(points, "given", out, args.step_factor, args.order_step)
        for a, b in zip(points, points[1:]):
            first, second = ran[points.index(a)], ran[points.index(b)]
            target = out / "compare" / f"{rows.index(first) + 1}-{rows.index(second) + 1}"
            compare(Path(a.path), Path(b.path), target)
            print(f"compare {a.label} -> {b.label}: {target / 'compare.md'}")
        print(f"history: {pages[1]} ({len(steps)} steps flagged)")
    else:  # an earlier matrix's history in this folder is not this one's
        for name in ("history.csv", "history_steps.csv", "history_points.csv", "history.md", "history.html"):
            (out / name).unlink(missing_ok=True)
        print(f"history: none (a history needs two environments that ran; {len(points)} did)")
    orders = analysis.orders_side_by_side(points)
    write_atomic(out / "orders.csv", orders.to_csv(index=False, float_format="%.4g"))
    write_atomic(out / "matrix.csv", table.to_csv(index=False))
    _print_orders(orders, [p.label for p in points], args.order_step)
    print(f"wrote {out / 'matrix.csv'} ({len(ran)} of {len(rows)} environments ran) and {out / 'orders.csv'}")
    return 0


def _print_orders(orders, labels: list[str], step: float) -> None:
    """The fitted orders that differ between the environments (by more than the history's order step, or fitted in
    some and not others)."""
    if len(labels) < 2 or orders.empty:
        return
    values = orders[labels].astype(float)
    spread = values.max(axis=1) - values.min(axis=1)
    differ = orders[(spread >= step) | (values.isna().any(axis=1) & values.notna().any(axis=1))]
    print(f"fitted orders that differ between environments ({len(differ)} of {len(orders)} run families):")
    for _, row in differ.head(ORDERS_SHOWN).iterrows():
        family = " ".join(str(row[c]) for c in ("case", "engine", "formulation", "integrator") if row[c])
        cells = ", ".join(f"{label} {'-' if math.isnan(row[label]) else f'{row[label]:.2f}'}" for label in labels)
        print(f"  {family} (declared {row['declared']:g}): {cells}")
    if len(differ) > ORDERS_SHOWN:
        print(f"  ... and {len(differ) - ORDERS_SHOWN} more in orders.csv")
