"""Verdicts of a run (issue 11): what a run's tables say about its integrators and its truth, each a pass, a fail or
"not measured", with the rule it was judged by. `stereodyn run` prints them first and writes DIR/verdicts.csv; the
report shows them first; `run --strict` exits 1 when one fails; "What to use" recommends no run of a failed
integrator.

Per integrator (an engine, formulation, integrator and precision, across the run's cases):
- order: the fitted convergence order of every non-chaotic case (convergence.csv) within ORDER_TOLERANCE of the
  declared one (an order measured over a case's first part only says over what span); a family no case gave an order
  is "not measured" with each case's reason (EXCUSES: exact for this motion, at the precision floor, chaotic, no run
  ok), or NO_REASON where nothing excuses it, which --strict fails; where the engine declares a known deviation of
  the order (Offer.deviation) and the fit matches it, `known` (not a failure), and `fixed upstream?` where it
  stopped matching it but meets the declared one;
- bounded energy, for a method that declares energy_bounded: its energy error over ENERGY_RATIO times a short run
  grows at most ENERGY_GROWTH times (no secular trend), on a conservative case, both floored at the round-off of the
  long run's steps (harness.testing.energy_noise: a method at round-off never fails it);
- symplectic, symmetric, stages, geometric, casimir_preserving: each declared property (and the stages, always) by
  the rule of harness.analysis.claims, measured on a few short steps of one or two bodies.
Per case, of the truth (the reference's quaternion Taylor row):
- its conserved invariants (the drift columns) within TRUTH_DRIFT_MAX;
- its distance to the case's exact solution (oracle_err) within TRUTH_ORACLE_MAX;
- its theory checks (checks.csv) within TRUTH_CHECK_TOLERANCE of the closed forms.
"""
from __future__ import annotations

import math
import re
from dataclasses import asdict, dataclass, replace
from pathlib import Path
from typing import Iterable

import numpy as np
import pandas as pd

from ..scenes.cases import CHAOTIC_TAGS  # noqa: F401 (part of this API)
from ..tables import TableError, read_optional
from .fitting import (AGREE, CONVERGENCE_FILE, FIRST_PART, MIN_CASES, MIN_POINTS, NO_EVIDENCE, NOT_MEASURABLE, NOT_YET,
                      SUPERCONVERGENT)
from ..scenes.metrics import DRIFT_COLUMNS
from ..run.results import read_csv_table, with_precision, write_atomic
from .fitting import is_failed  # noqa: F401 (the Pareto table applies it; part of this API)
from ..engines import TRUTH_ENGINE, TRUTH_FORMULATION, TRUTH_INTEGRATOR, get_engine
from ..engines.base import KnownDeviation
from ..engines.declared import known_deviations
from ..precision import FLOAT64
from ..environment import engine_version

VERDICTS_FILE = "verdicts.csv"
COLUMNS = ("verdict", "engine", "formulation", "integrator", "precision", "case", "status", "detail", "rule",
           "engine_version")
PASS, FAIL, UNMEASURED = "pass", "fail", "not measured"
# A declared order that nothing measured (no case's dt list or short ladder gave an order) and no reason excuses:
# `run --strict` fails it as it fails FAIL, yet "What to use" still recommends its runs (no claim was disproved).
NO_REASON = "not measured, no reason"
# Why a case has no fitted order, where the reason excuses it (the words of the convergence note, written by
# harness.fitting and harness.pipeline.dt_ladders' short ladders; fitting.NOTE_GROUPS) -> the reason in a reader's words.
EXCUSES = (("exact for this motion", "exact for this motion"),
           ("round-off for every stable dt", "at the precision floor (error at round-off for every stable dt)"),
           ("error at round-off for every dt up to", "at the precision floor (error at round-off up to the largest "
                                                     "dt whose run finished ok)"),
           ("its error grows exponentially", "chaotic"),
           ("no run ok", "no run finished ok"))
# An engine's declared known deviation (Offer.deviation) that the measurement matches: not a failure (--strict
# passes it), listed in the report with its upstream reference. FIXED: the measurement stopped matching the deviation
# and meets the declared value instead: the deviation's declaration is stale (upstream fixed it?). Neither fails.
KNOWN, FIXED = "known", "fixed upstream?"
# A miss of the order tolerance found on too little evidence (fitting.MIN_POINTS, MIN_CASES) is NOT_ENOUGH, not a
# failure; `run --strict` measures such a claim first (short ladders) and fails what is still NOT_ENOUGH after that.
NOT_ENOUGH = "not enough evidence"
# A claim whose only cases that miss it are still drifting toward it at their finest dt (fitting.NOT_YET: two points
# judged, the slopes moving toward the declared order) and are within ORDER_CASE_TOLERANCE of it: never a failure;
# `run --strict` measures finer first (short ladders) and fails what is still not asymptotic after that.
NOT_ASYMPTOTIC = NOT_YET
STATUSES = (PASS, FAIL, UNMEASURED, NO_REASON, KNOWN, FIXED, NOT_ENOUGH, NOT_ASYMPTOTIC)  # every status a verdict has

# The median of a family's fitted orders over the cases must be within ORDER_TOLERANCE of the declared order, and no
# single case more than ORDER_CASE_TOLERANCE off. The suite's fits (reports/default/convergence.csv, 134 families) lie
# within 0.15 of the declared orders (harness.testing uses 0.3 too); a wrong method is off by a whole order on every
# case. Single cases stray further on a two-point fit from the pre-asymptotic range: the reference's gibbs rk4 on
# lagrange-top over t_end 2 with dt 1e-2, 3e-3 (.ci/run's quick suite) fits 3.41, its error 2.7e-4 through 19 chart
# changes; a defect that only some cases show (a torque handled at the wrong time: a whole order) still fails.
ORDER_TOLERANCE = 0.3
ORDER_CASE_TOLERANCE = 1.0
# Bounded energy: the short run's steps of ENERGY_DT on ENERGY_CASE (a torque-free triaxial body, conservative), and a
# run ENERGY_RATIO times longer. A secular drift grows the error ~ENERGY_RATIO x; a bounded one not at all (the
# suite's energy_bounded methods: 1.0-1.3x, tests/test_geometric.py).
ENERGY_CASE, ENERGY_DT, ENERGY_STEPS, ENERGY_RATIO = "free-asymmetric", 0.01, 200, 20
# The truth's drifts on the default suite are <= 5.5e-13 (hess_drift, reference/default, every formulation), most
# near 1e-15: 1e-11 leaves 20x headroom while a truth off by the 1e-10 asked of it fails.
TRUTH_DRIFT_MAX = 1e-11
# The truth against the exact solutions: <= 7.3e-14 rad measured (dzhanibekov, reference/default).
TRUTH_ORACLE_MAX = 1e-10
# The truth's theory checks (checks.csv error; relative, or absolute where the theory is 0), each bound >= 100x the
# largest measured on the default suite (in brackets).
TRUTH_CHECK_TOLERANCE = {
    "period": 1e-10,                 # [9.2e-13, dzhanibekov: its flips amplify every error]
    "montgomery_phase": 1e-8,        # [4.9e-11 rad, dzhanibekov]
    "lyapunov_exponent": 2e-2,       # [4.6e-5; the check's own rule: 2%, the linearisation's O(angle²)]
    "precession_rate": 1e-10,        # [1.6e-15]
    "tilt_growth_rate": 1e-10,       # [1.4e-13 /s]
    "omega_squared": 1e-10,          # [1.5e-15]
    "precession_axis_drift": 1e-10,  # [4.3e-15]
    "energy_drift": 1e-10,           # [3.8e-16, sliding ladder]
    "constraint_violation": 1e-10,   # [0, sliding ladder]
    "detachment_angle": 1e-10,       # [1.3e-16, sliding ladder]
}
TRUTH = (TRUTH_ENGINE, TRUTH_FORMULATION, TRUTH_INTEGRATOR)
# The verdicts on a claim of the method itself, checked apart from the runs (harness.analysis.claims.CLAIMS too).
METHOD_CLAIMS = ("energy_bounded", "symplectic", "symmetric", "stages", "geometric", "casimir_preserving")


@dataclass(frozen=True)
class Verdict:
    verdict: str          # "order", METHOD_CLAIMS, "truth_invariants", "truth_oracle", "truth_checks"
    engine: str = ""
    formulation: str = ""
    integrator: str = ""
    precision: str = ""
    case: str = ""
    status: str = PASS
    detail: str = ""
    rule: str = ""
    engine_version: str = ""  # the engine's packages as installed, "mujoco 4.0.0" (environment.engine_version)

    @property
    def subject(self) -> str:
        """What was judged, the engine's version included: "integrator mujoco rk4 (mujoco 4.0.0)"."""
        return self._judged + (f" ({self.engine_version})" if self.engine_version else "")

    @property
    def _judged(self) -> str:
        if self.integrator:
            precision = self.precision if self.precision not in ("", FLOAT64) else ""
            return "integrator " + " ".join(x for x in (self.engine, self.formulation, self.integrator, precision)
                                            if x)
        return f"case {self.case}"

    @property
    def line(self) -> str:
        """One line: what was judged, the finding, then the engine version it was judged under."""
        return f"{self._judged} {self.detail}" + (f" [{self.engine_version}]" if self.engine_version else "")


def _fmt_order(x: float) -> str:
    return f"{x:.2f}"


def order_verdicts(convergence: pd.DataFrame, excluded_cases: Iterable[str] = ()) -> list[Verdict]:
    """Per engine/formulation/integrator: the fitted orders of the cases not excluded against the declared order;
    where no case has one, UNMEASURED with each case's reason, or NO_REASON where some case has none (excuse)."""
    excluded = set(excluded_cases)
    out = []
    df = with_precision(convergence).fillna({"formulation": ""})
    rule = (f"fitted on each case's judged range (from the fine end, local slopes within {AGREE:g}); "
            f"|median fitted - declared| <= {ORDER_TOLERANCE:g} over the non-chaotic cases, and <= "
            f"{ORDER_CASE_TOLERANCE:g} on each; a miss of the first on < {MIN_POINTS} asymptotic points a case and "
            f"< {MIN_CASES} cases is {NOT_ENOUGH}, and on slopes still moving toward the declared order "
            f"{NOT_ASYMPTOTIC} (--strict fails either after measuring finer)")
    for (engine, formulation, integrator, precision), group in df.groupby(
            ["engine", "formulation", "integrator", "precision"], sort=False):
        declared = float(group["declared_order"].iloc[0])
        if not math.isfinite(declared):
            continue  # no claim to judge (an engine's integrator of unknown order)
        fitted = group[np.isfinite(group["order"].astype(float)) & ~group["case"].isin(excluded)]
        base = dict(engine=engine, formulation=formulation, integrator=integrator, precision=precision, rule=rule)
        drifting = _drifting(fitted, declared)
        if len(drifting) and len(drifting) == len(fitted):
            out.append(Verdict("order", **base, status=NOT_ASYMPTOTIC, detail=(
                f"declares order {declared:g}; {NOT_YET} on {_cases(drifting)}: " + _shown(drifting, declared)
                + " (--strict measures finer first)")))
            continue
        fitted = fitted.drop(drifting.index)
        if fitted.empty:
            why = "; not measurable in " + precision + " (round-off closes the asymptotic range)" \
                if precision != FLOAT64 and group["note"].fillna("").astype(str).str.contains(
                    NOT_MEASURABLE, regex=False).any() else ""
            out.append(Verdict("order", **base, status=UNMEASURED,
                               detail=f"declares order {declared:g}; no non-chaotic case has a fitted order{why}")
                       if why else _unmeasured(group, declared, excluded, base))
            continue
        orders = fitted["order"].astype(float)
        low, high = float(orders.min()), float(orders.max())
        span = _fmt_order(low) if _fmt_order(low) == _fmt_order(high) else f"{_fmt_order(low)}–{_fmt_order(high)}"
        median = float(orders.median())
        # a special motion the method solves better than in general (fitting.SUPERCONVERGENT: three points or more
        # steeper than declared) is no defect; it still counts in the median, so a method steeper on every case fails
        special = fitted["note"].fillna("").astype(str).str.contains(SUPERCONVERGENT, regex=False) \
            if "note" in fitted else pd.Series(False, index=fitted.index)
        bad = fitted[((orders - declared).abs() > ORDER_CASE_TOLERANCE) & ~special]
        failed_ = abs(median - declared) > ORDER_TOLERANCE or len(bad) > 0
        points, counted, enough = _evidence(fitted)
        detail = (f"declares order {declared:g}, fitted {span} on {len(fitted)} case{'s' * (len(fitted) != 1)}"
                  + (f" (median {median:.2f})" if len(fitted) > 2 else "")
                  + (f" from {int(points.sum())} asymptotic points (at most {int(points.max())} on a case)"
                     if counted else ""))
        if special.any():
            detail += f" ({SUPERCONVERGENT}: " + ", ".join(fitted.loc[special, "case"].astype(str).tolist()) + ")"
        # an order measured over a case's first part only (a long horizon): over what span, in the note's words
        notes = fitted["note"].fillna("").astype(str) if "note" in fitted else pd.Series("", index=fitted.index)
        parts = [f"{case}: {segment}" for case, note in zip(fitted["case"].astype(str), notes)
                 for segment in note.split("; ") if segment.startswith(FIRST_PART)]
        if parts:
            detail += " (" + "; ".join(parts) + ")"
        if len(bad):
            detail += " (off by more than 1 on " + ", ".join(bad["case"].astype(str).tolist()[:5]) + (
                "…" if len(bad) > 5 else "") + ")"
        shown = _shown(fitted, declared)
        detail += f"; {shown}" if shown else ""
        if len(drifting):
            detail += f"; {NOT_YET} (not judged) on {_cases(drifting)}: " + _shown(drifting, declared)
        deviation = _known_deviation(engine, integrator)
        if deviation is not None:
            off = fitted[(orders - deviation.expected).abs() > ORDER_CASE_TOLERANCE]
            matches = abs(median - deviation.expected) <= deviation.tolerance and off.empty
            detail += (f"; known deviation: order {deviation.expected:g} ({deviation.reference})" if matches else
                       f"; stopped matching its known deviation (order {deviation.expected:g}: "
                       f"{deviation.reference})")
            status = KNOWN if matches else FIXED if not failed_ else FAIL
            out.append(Verdict("order", **{**base, "rule": rule + f"; known deviation: |median - "
                                           f"{deviation.expected:g}| <= {deviation.tolerance:g}"},
                               status=status, detail=detail))
            continue
        if failed_ and bad.empty and not enough:
            out.append(Verdict("order", **base, status=NOT_ENOUGH, detail=detail + (
                f"; {NOT_ENOUGH} to fail it: fewer than {MIN_POINTS} asymptotic points on every case and fewer than "
                f"{MIN_CASES} cases (--strict measures more first)")))
            continue
        out.append(Verdict("order", **base, status=FAIL if failed_ else PASS, detail=detail))
    return out


def _drifting(fitted: pd.DataFrame, declared: float) -> pd.DataFrame:
    """The fitted cases still drifting toward the declared order (fitting.NOT_YET) that miss it by more than
    ORDER_TOLERANCE and at most ORDER_CASE_TOLERANCE: not judged (a whole order off fails on any evidence)."""
    if "note" not in fitted:
        return fitted.iloc[:0]
    off = (fitted["order"].astype(float) - declared).abs()
    return fitted[fitted["note"].fillna("").astype(str).str.contains(NOT_YET, regex=False)
                  & (off > ORDER_TOLERANCE) & (off <= ORDER_CASE_TOLERANCE)]


def _cases(rows: pd.DataFrame) -> str:
    return f"{len(rows)} case{'s' * (len(rows) != 1)}"


def _shown(fitted: pd.DataFrame, declared: float, most: int = 2) -> str:
    """The evidence of the cases farthest from the declared order (at most `most`): each case's local slopes and the
    dt range judged, in its note's words (fitting.evidence)."""
    if "note" not in fitted or fitted.empty:
        return ""
    far = (fitted["order"].astype(float) - declared).abs().sort_values(ascending=False, kind="stable").index[:most]
    shown = []
    for index in far:
        segment = next((x for x in str(fitted.at[index, "note"] or "").split("; ") if x.startswith("slopes ")), "")
        judged = next((x for x in str(fitted.at[index, "note"] or "").split("; ") if x.startswith("judged on ")), "")
        if segment:
            shown.append(f"{fitted.at[index, 'case']}: {segment}; {judged}" if judged else
                         f"{fitted.at[index, 'case']}: {segment}")
    more = f" (+{len(fitted) - most} more cases)" if len(fitted) > most and shown else ""
    return "; ".join(shown) + more


def _evidence(fitted: pd.DataFrame) -> tuple[pd.Series, bool, bool]:
    """The asymptotic points of a claim's fitted cases, whether the table counts them (a table of 0.2.0 may not), and
    whether they are enough to judge: MIN_POINTS on some case, or MIN_CASES cases."""
    points = pd.to_numeric(fitted["points"], errors="coerce") if "points" in fitted else pd.Series(dtype=float)
    counted = len(points) == len(fitted) and bool(np.isfinite(points).all())
    return points, counted, not counted or points.max() >= MIN_POINTS or len(fitted) >= MIN_CASES


def weak_evidence(convergence: pd.DataFrame, excluded_cases: Iterable[str] = ()) -> set[tuple[str, str, str]]:
    """The order claims (engine, formulation, integrator) whose fitted cases are too few to judge (_evidence), passed
    or missed, or with a case not yet asymptotic (_drifting): `run --strict` measures them more (short ladders, finer
    steps) before it judges, since a pre-asymptotic pair can fit the declared order by chance as well as miss it."""
    df = with_precision(convergence).fillna({"formulation": ""})
    fitted = df[np.isfinite(df["order"].astype(float)) & np.isfinite(df["declared_order"].astype(float))
                & ~df["case"].isin(set(excluded_cases))]
    return {key for key, group in fitted.groupby(["engine", "formulation", "integrator"], sort=False)
            if not _evidence(group)[2] or len(_drifting(group, float(group["declared_order"].iloc[0])))}


def excuse(row, excluded: set[str]) -> str | None:
    """Why a convergence row (a case of a family) has no order, where that excuses it; None where nothing does."""
    if row["case"] in excluded:
        return "chaotic"
    note = str(row.get("note", "") or "")
    words = next(((marker, words) for marker, words in EXCUSES if marker in note), None)
    if words is None:
        return None
    if words[0] == "no run ok":  # skipped (not run: the engine cannot model the case) is not failed (ran, broke)
        statuses = re.search(r"no run ok: ([a-z, ]+)", note)
        statuses = statuses.group(1).split(", ") if statuses else []
        if statuses == ["skipped"]:
            return "every run skipped (not run, no evidence either way)"
        return "no run finished ok" + (f" ({', '.join(statuses)})" if statuses else "")
    # points that did not run ok beside the ones at round-off (a run budget): the reason rests on those that ran
    unrun = re.search(r"\(dt = [^()]*" + re.escape(NO_EVIDENCE) + r"[^()]*\)", note)
    return words[1] + (f" {unrun.group(0)}" if unrun else "")


def _unmeasured(group: pd.DataFrame, declared: float, excluded: set[str], base: dict) -> Verdict:
    """The order verdict of a family no case gave an order: not measured, with each case's reason (UNMEASURED), or,
    where some case has none, NO_REASON naming the cases and why their points gave no order."""
    reasons = [(str(row["case"]), excuse(row, excluded), row) for _, row in group.iterrows()]
    unexcused = [(case, row) for case, why, row in reasons if why is None]
    if not unexcused:
        return Verdict("order", **base, status=UNMEASURED, detail=f"declares order {declared:g}; not measured: "
                       + "; ".join(f"{case} {why}" for case, why, _ in reasons))
    details = []
    for case, row in unexcused[:3]:
        note = str(row.get("note", "") or "").split(";")[0]
        source = ("its dt list (no short ladder ran: --strict runs them)" if row.get("source", "") == "dt_list"
                  else "a short ladder")
        details.append(f"{case}: {source}: {note}" if note else f"{case}: {source}")
    more = f" (+{len(unexcused) - 3} more)" if len(unexcused) > 3 else ""
    return Verdict("order", **base, status=NO_REASON,
                   detail=f"declares order {declared:g}; not measured, and no reason excuses it: "
                          + "; ".join(details) + more)


def _known_deviation(engine: str, integrator: str) -> KnownDeviation | None:
    """The engine's declared deviation of the integrator's order (engines.declared.known_deviations), if any."""
    try:
        declared = known_deviations(get_engine(engine))
    except (KeyError, ValueError):  # an engine no longer registered: nothing declared
        return None
    return next((d for d in declared if d.integrator == integrator and d.quantity == "order"), None)


def _truth_rows(results: pd.DataFrame) -> pd.DataFrame:
    df = results.fillna({"formulation": ""})
    return df[(df["engine"] == TRUTH[0]) & (df["formulation"] == TRUTH[1]) & (df["integrator"] == TRUTH[2])]


def truth_verdicts(results: pd.DataFrame, checks_table: pd.DataFrame | None) -> list[Verdict]:
    """Per case: the truth's invariants, its distance to an exact solution and its theory checks."""
    out = []
    truth = _truth_rows(results)
    for _, row in truth.iterrows():
        case = str(row["case"])
        if row["status"] != "ok":
            out.append(Verdict("truth_invariants", case=case, status=FAIL, rule="the truth finishes ok",
                               detail=f"truth did not finish: {row['status']} ({row.get('message', '')})"))
            continue
        drifts = {c: float(row[c]) for c in DRIFT_COLUMNS if c in row and np.isfinite(float(row[c]))}
        if drifts:
            worst = max(drifts, key=drifts.get)
            bad = [c for c, v in drifts.items() if v > TRUTH_DRIFT_MAX]
            out.append(Verdict("truth_invariants", case=case, status=FAIL if bad else PASS,
                               rule=f"every drift of the truth <= {TRUTH_DRIFT_MAX:g}",
                               detail=f"truth conserves {len(drifts)} invariants: largest drift {worst} "
                                      f"{drifts[worst]:.2e}" + (f" (over: {', '.join(bad)})" if bad else "")))
        oracle = float(row["oracle_err"]) if "oracle_err" in row else math.nan
        if np.isfinite(oracle):
            out.append(Verdict("truth_oracle", case=case, status=PASS if oracle <= TRUTH_ORACLE_MAX else FAIL,
                               rule=f"oracle_err of the truth <= {TRUTH_ORACLE_MAX:g} rad",
                               detail=f"truth against the exact solution: {oracle:.2e} rad"))
    if checks_table is not None and len(checks_table):
        table = _truth_rows(checks_table)
        for case, group in table.groupby("case", sort=False):
            bad, worst, unmeasured = [], None, []
            for _, row in group.iterrows():
                limit = TRUTH_CHECK_TOLERANCE.get(row["quantity"], math.nan)
                error = float(row["error"])
                if not math.isfinite(error):  # the span is too short for it (checks.py): nothing to judge
                    unmeasured.append(str(row["quantity"]))
                    continue
                if not math.isfinite(limit):
                    continue
                if worst is None or error / limit > worst[0]:
                    worst = (error / limit, row["quantity"], error, limit)
                if not error <= limit:
                    bad.append(f"{row['quantity']} {error:.2e} > {limit:g}")
            if worst is None:
                if unmeasured:
                    out.append(Verdict("truth_checks", case=str(case), status=UNMEASURED,
                                       rule="checks.csv error of the truth within verdicts.TRUTH_CHECK_TOLERANCE",
                                       detail=f"truth's theory checks not measurable over this span: "
                                              f"{', '.join(unmeasured)}"))
                continue
            detail = (f"truth's theory checks: {len(group)} values, "
                      + (f"out of tolerance: {'; '.join(bad)}" if bad
                         else f"closest to its bound: {worst[1]} {worst[2]:.2e} (<= {worst[3]:g})"))
            out.append(Verdict("truth_checks", case=str(case), status=FAIL if bad else PASS, detail=detail,
                               rule="checks.csv error of the truth within verdicts.TRUTH_CHECK_TOLERANCE"))
    return out


def evaluate(out_dir: Path, results: pd.DataFrame, cases: Iterable = (),
             checked: Iterable[Verdict] = ()) -> list[Verdict]:
    """Every verdict of a run folder (convergence.csv and checks.csv when present) and its results table; cases: the
    run's Case objects, whose tags say which are chaotic; checked: the verdicts of the integrators' own check runs
    (energy_bounded and the declared properties: harness.pipeline.checks, which runs them). Writes DIR/verdicts.csv."""
    from ..scenes import checks

    out_dir = Path(out_dir)
    excluded = [c.name for c in cases if set(getattr(c, "tags", ())) & set(CHAOTIC_TAGS)]
    verdicts: list[Verdict] = []
    convergence = read_optional(out_dir / CONVERGENCE_FILE,
                                ("formulation", "note", "source", "engine", "integrator", "case"))
    if convergence is not None and len(convergence):
        verdicts += order_verdicts(convergence, excluded)
    verdicts += checked
    checks_path = out_dir / checks.CHECKS_FILE
    verdicts += truth_verdicts(results, checks.read_checks(checks_path) if checks_path.exists() else None)
    # the engine version each verdict judged (issue 48): a report of MuJoCo 4.0.0 is not read as one of 3.3.7
    verdicts = [replace(v, engine_version=engine_version(v.engine)) if v.engine and not v.engine_version else v
                for v in verdicts]
    write(verdicts, out_dir / VERDICTS_FILE)
    return verdicts


def write(verdicts: list[Verdict], path: Path) -> None:
    df = pd.DataFrame([asdict(v) for v in verdicts], columns=list(COLUMNS))
    write_atomic(path, df.to_csv(index=False))


def read(out_dir: Path) -> list[Verdict] | None:
    """DIR/verdicts.csv, None where the run wrote none; TableError for a status no verdict has (a `garbage` one was
    compared as "better" and rendered: issue 46's eleventh attack, F6)."""
    path = Path(out_dir) / VERDICTS_FILE
    if not path.exists():
        return None
    df = read_csv_table(path, dtype=str, keep_default_na=False)
    verdicts = [Verdict(**{c: row.get(c, "") for c in COLUMNS}) for _, row in df.iterrows()]  # 0.2.0: no precision
    for number, verdict in enumerate(verdicts, 1):
        if verdict.status not in STATUSES:
            raise TableError(f"{path}: row {number}: status = {verdict.status[:40]!r}: must be one of "
                             f"{', '.join(map(repr, STATUSES))}")
    return verdicts


def failed(verdicts: Iterable[Verdict]) -> list[Verdict]:
    return [v for v in verdicts if v.status == FAIL]


def strict_failures(verdicts: Iterable[Verdict]) -> list[Verdict]:
    """What `run --strict` fails on: a failed verdict, a claim nothing measured and no reason excuses, and a claim
    with too little evidence or not yet asymptotic after measuring more."""
    return [v for v in verdicts if v.status in (FAIL, NO_REASON, NOT_ENOUGH, NOT_ASYMPTOTIC)]


def failed_integrators(verdicts: Iterable[Verdict]) -> set[tuple[str, str, str]]:
    """(engine, formulation, integrator) of the integrator verdicts that failed. A failed claim of the method itself
    (energy_bounded, and the properties of harness.analysis.claims) stands for every engine and formulation that ran
    it ("*")."""
    out = set()
    for v in failed(verdicts):
        if v.verdict in METHOD_CLAIMS:
            out.add(("*", "*", v.integrator))
        elif v.integrator:
            out.add((v.engine, v.formulation, v.integrator))
    return out


def summary_lines(verdicts: list[Verdict]) -> list[str]:
    """The terminal's verdict block: the counts, then one line per failed verdict, per claim nothing measured and
    no reason excuses, per known deviation and per deviation that stopped matching."""
    counts = {s: sum(v.status == s for v in verdicts)
              for s in STATUSES}
    head = (f"verdicts: {counts[PASS]} passed, {counts[FAIL]} failed, {counts[UNMEASURED] + counts[NO_REASON]} not "
            f"measured" + (f" ({counts[NO_REASON]} with no reason: --strict fails them)" if counts[NO_REASON] else ""))
    head += f", {counts[NOT_ENOUGH]} with {NOT_ENOUGH} (--strict measures more, then fails them)" \
        if counts[NOT_ENOUGH] else ""
    head += f", {counts[NOT_ASYMPTOTIC]} {NOT_ASYMPTOTIC} (--strict measures finer, then fails them)" \
        if counts[NOT_ASYMPTOTIC] else ""
    head += f", {counts[KNOWN]} known deviations" if counts[KNOWN] else ""
    head += f", {counts[FIXED]} {FIXED}" if counts[FIXED] else ""
    lines = [head]
    words = {FAIL: "failed", NO_REASON: "not measured", NOT_ENOUGH: NOT_ENOUGH, NOT_ASYMPTOTIC: NOT_ASYMPTOTIC}
    lines += [f"verdict {words[v.status]}: {v.line}" for v in strict_failures(verdicts)]
    lines += [f"verdict {v.status}: {v.line}" for v in verdicts if v.status in (KNOWN, FIXED)]
    return lines
