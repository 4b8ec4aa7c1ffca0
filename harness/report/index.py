"""DIR/README.md: what each file of an output folder holds (issue 32), written by the report step last, so it lists
what is there. The columns of each table: the docs site's reference page (tools/docs_reference.py generates it from
the code that declares them)."""
from __future__ import annotations

from pathlib import Path

from ..atomic import write_atomic

INDEX_FILE = "README.md"

# name -> what it holds. A folder's name ends in "/". Order: what a reader opens first.
ENTRIES: dict[str, str] = {
    "report.html": "the report: verdicts, summary, what to use, convergence, each integrator, each case with its "
                   "figures; open it in a browser. It links the PNGs of `figures/`: move the whole folder, or render "
                   "one file with `stereodyn report DIR --self-contained`",
    "report.md": "the same report as Markdown, figures linked from `figures/`",
    "figures/": "the report's PNGs, named CASE-KIND.png: KIND is `work-precision` (error against cost), "
                "`invariants` (drifts against time) or `tolerance` (error against requested tolerance); "
                "`stereodyn compare` adds compare-largest-changes.png, `stereodyn history` history-steps.png",
    "results.csv": "one row per run: what ran, its status and reason, drifts, errors against the truth, cost",
    "verdicts.csv": "one row per verdict: declared against measured (order, bounded energy, the truth's invariants, "
                    "oracles), with its rule",
    "answers.csv": "what to use: per case, scope (one engine or any) and accuracy target, the one answer the report's "
                   "What to use, its Summary and the terminal show (engine, integrator, dt or tolerance, error, cost, "
                   "source: searched by the step-size advice, or listed by the sweep)",
    "pareto.csv": "per case, scope and accuracy target: the cheapest of the runs the sweep and the ladders listed "
                  "that reaches it, at the dt or tolerance it ran with (the work-precision frontier; the advice may "
                  "have searched a larger dt since: answers.csv)",
    "advice.csv": "per laddered family and target: the largest dt (or tolerance) reaching it, checked by runs",
    "convergence.csv": "one row per run family: fitted order, round-off floor, largest stable dt",
    "ladder.csv": "every point of the dt ladders (dt, error, cost)",
    "tolerance.csv": "every point of the tolerance ladders of the adaptive integrators",
    "tolerance_fit.csv": "one row per adaptive method: how the error follows the requested tolerance",
    "checks.csv": "one row per run and quantity measured against its closed form (periods, phases, rates, fitted "
                  "orders)",
    "agreement.csv": "the differences between engines running the same method and dt on a case",
    "runs.json": "the sweep's run keys, its environment (library versions, machine) and code fingerprints",
    "store/": "one JSON record per finished run (rows and series), keyed by a hash; `--resume` reuses it, deleting "
              "it starts afresh",
    "trajectories/": "each run's recorded states (`--save-trajectories`), one .npz per run, and `index.csv`",
    "compare.md": "`stereodyn compare`: this folder against another, metric by metric",
    "compare.html": "`stereodyn compare`'s page, as compare.md",
    "compare.csv": "`stereodyn compare`: every matched row with its ratios",
    "compare-pr.md": "`stereodyn compare --format pr`: a pull-request summary",
    "history.csv": "`stereodyn history`: every series (metric, status, fitted order) of every row over the runs",
    "history_steps.csv": "`stereodyn history`: the steps flagged, worse first",
    "history_points.csv": "`stereodyn history`: the runs in order, with the environment entries that differ",
    "history.md": "`stereodyn history`'s page: the steps and their series",
    "history.html": "`stereodyn history`'s page, as history.md",
    "matrix-run.json": "`stereodyn matrix`: the environment and run arguments of this folder (reused or resumed by the "
                       "next matrix)",
    "MUJOCO_LOG.TXT": "MuJoCo's own warnings of this run (each also in its row's message)",
    INDEX_FILE: "this index",
}
OTHER = "not written by stereodyn"
TITLE = "# What this folder holds"  # also the mark of an index of ours: a README.md without it is never overwritten


def lines(out_dir: Path) -> list[str]:
    """The index of DIR: every file and folder at its top level, known ones described, in ENTRIES' order."""
    present = sorted(f"{p.name}/" if p.is_dir() else p.name for p in Path(out_dir).iterdir()
                     if not p.name.startswith("."))
    if INDEX_FILE not in present:
        present.append(INDEX_FILE)
    order = list(ENTRIES)
    present.sort(key=lambda name: (order.index(name) if name in ENTRIES else len(order), name))
    rows = [f"- `{name}`: {ENTRIES.get(name, OTHER)}" + _count(Path(out_dir) / name) for name in present]
    return [TITLE, "",
            "Written by `stereodyn run` (and `stereodyn report`) when the report is rendered. Every column of every "
            "table: stereodyn's documentation, Reference, Result tables.", "", *rows, ""]


def _count(path: Path) -> str:
    if not path.is_dir():
        return ""
    count = sum(1 for p in path.iterdir() if not p.name.startswith("."))
    return f" ({count} {'entry' if count == 1 else 'entries'})"


def write(out_dir: Path) -> Path | None:
    """Write DIR/README.md; return its path. None where DIR holds a README.md of someone else's (`--out .` in a
    project): that is left as it is."""
    path = Path(out_dir) / INDEX_FILE
    if path.is_file() and not path.read_text(encoding="utf-8", errors="replace").startswith(TITLE):
        return None
    write_atomic(path, "\n".join(lines(out_dir)))
    return path
