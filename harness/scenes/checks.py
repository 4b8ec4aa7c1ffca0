"""Checks against theory (DESIGN §4, checks.csv): quantities measured from each run's recorded trajectory (every
engine, the truth included) and compared with their closed forms (reference.exact, FORMULARY T8, T9, G5, G10).

Which checks a case gets follows from its body and initial state, not from its name:
* torque-free, triaxial or symmetric: the period of ω(t) and Montgomery's phase (T9);
* torque-free, ω0 within LYAPUNOV_NEAR of the middle axis (a Dzhanibekov flip): the Lyapunov exponent of the
  middle-axis rotation (T8), from the divergence of the run and a rerun from a perturbed ω0;
* a Lagrange top in regular precession: the precession rate (G5); a sleeping top (G above O): the growth rate of a
  tilt, from the run and a rerun with a tilted figure axis, against the linearisation (stable above the threshold);
* a Grioli precession: |ω|² = 2 α cos χ / A_f and the drift of the precession axis, fixed in space (G10).

error is |measured - theory| / |theory|, or |measured - theory| where theory is 0, or the angle between the two for
Montgomery's phase (rad, mod 2π). A run that did not finish ok, or whose span is too short for a measurement, has
measured and error NaN.
"""
from __future__ import annotations

import dataclasses
import math
from pathlib import Path
from typing import Callable

import numpy as np
import pandas as pd
from numpy.polynomial import Polynomial
from scipy.optimize import brentq

from .cases import Case
from ..atomic import write_atomic
from ..errors import raise_if_internal
from ..truth_names import TRUTH_ENGINE, TRUTH_FORMULATION, TRUTH_INTEGRATOR
from ..tables import read_csv_table
from ..trajectory import Status, Trajectory
from ..precision import FLOAT64
from ...reference.exact import ORACLES, free_motion, lagrange_rates, lyapunov_exponent
from ...reference.rotations import quat_conj, quat_mul, quat_to_matrix

ROW_KEY = "checks"      # a run's row carries its check rows under this key, so the result store keeps them with it
CHECKS_FILE = "checks.csv"
COLUMNS = ("case", "engine", "formulation", "integrator", "precision", "dt", "quantity", "theory", "measured",
           "error")
RUN_COLUMNS = COLUMNS[:6]
ANGLE_QUANTITIES = frozenset({"montgomery_phase"})

# Samples per local interpolating polynomial (degree 7): its error is ~ (h |ω|)^8 / 8!, far below the 1e-10 asked of
# the truth for the sample spacings h = t_end / (samples - 1) of the suite (h |ω| <= 0.1).
INTERPOLATION_POINTS = 8
# ω0 within this angle (rad) of the middle axis: a middle-axis case, whose runs first linger near the unstable
# stationary rotation and so show its Lyapunov exponent.
LYAPUNOV_NEAR = 1e-2
# The rerun's ω0 is moved by this times |ω0| along the unstable direction: far above round-off (1e-16), and after a
# growth of e^5 still far below the linear regime's end.
LYAPUNOV_KICK = 1e-9
# The fit ends where the run's ω is this far (angle, rad) from the middle axis: there the exponent of the
# linearisation about the run differs from the stationary one by O(angle²) <= 1e-3 relative, inside the 2% asked.
LINEAR_DEVIATION = 3e-2
# The sleeping top's rerun is tilted by this angle (rad), and the fit ends where the two figure axes are LINEAR_TILT
# apart: nonlinear terms are then O(tilt²) relative.
TILT_KICK = 1e-8
LINEAR_TILT = 1e-3
MIN_FIT_SAMPLES = 10

Rerun = Callable[[Case], Trajectory]


# ------------------------------------------------------------------------------------------------- measurement

def measure(case: Case, traj: Trajectory, rerun: Rerun) -> list[dict]:
    """The check rows {quantity, theory, measured, error} of one run. rerun(case) runs the same engine, integrator
    and dt on another case (a perturbed initial state) and returns its Trajectory on the same grid."""
    rows = []
    for check in applicable(case):
        theory = check.theory(case)
        measured = dict.fromkeys(theory, math.nan)
        if traj.status is Status.OK:
            measured.update(check.measured(case, traj, rerun))
        rows += [{"quantity": quantity, "theory": value, "measured": measured[quantity],
                  "error": error(quantity, value, measured[quantity])} for quantity, value in theory.items()]
    return rows


def error(quantity: str, theory: float, measured: float) -> float:
    if not (math.isfinite(theory) and math.isfinite(measured)):
        return math.nan
    if quantity in ANGLE_QUANTITIES:
        return abs(math.remainder(measured - theory, 2.0 * math.pi))
    return abs(measured - theory) / abs(theory) if theory != 0.0 else abs(measured)


@dataclasses.dataclass(frozen=True)
class Check:
    """theory(case) -> {quantity: value}; measured(case, traj, rerun) -> {quantity: value} (NaN where it cannot)."""

    name: str
    theory: Callable[[Case], dict[str, float]]
    measured: Callable[[Case, Trajectory, Rerun], dict[str, float]]


def applicable(case: Case) -> list[Check]:
    """The checks whose theory holds for the case's body and initial state."""
    if case.body.has_external_torque:
        return []
    body = case.body
    if not body.has_gravity:
        motion = free_motion(body, case.quat0, case.omega0)
        checks = []
        if motion.kind in ("major", "minor", "symmetric") and math.isfinite(motion.period):
            checks.append(FREE_MOTION)
        if motion.kind in ("major", "minor") and _middle_axis_angle(case) <= LYAPUNOV_NEAR:
            checks.append(LYAPUNOV)
        return checks
    if ORACLES["lagrange_precession"].check(body, case.quat0, case.omega0) is None:
        top = _lagrange_top(case)
        if top.sin_tilt > 0.0:
            return [PRECESSION]
        return [SLEEPING_TOP] if top.cos_tilt > 0.0 else []
    if ORACLES["grioli_precession"].check(body, case.quat0, case.omega0) is None:
        return [GRIOLI]
    return []


# --- interpolation of recorded samples -----------------------------------------------------------------------

def _window(n: int, i: int) -> slice:
    """INTERPOLATION_POINTS sample indices around the interval [i, i + 1], shifted to stay inside [0, n)."""
    start = min(max(0, i - INTERPOLATION_POINTS // 2 + 1), max(0, n - INTERPOLATION_POINTS))
    return slice(start, min(n, start + INTERPOLATION_POINTS))


def _interpolant(times: np.ndarray, values: np.ndarray, i: int) -> Polynomial:
    window = _window(len(times), i)
    t = times[window]
    return Polynomial.fit(t, values[window], deg=len(t) - 1)


def zero_crossings(times: np.ndarray, signal: np.ndarray) -> np.ndarray:
    """Times (s) where the sampled signal changes sign, each refined on its local interpolating polynomial."""
    roots = []
    for i in np.flatnonzero(signal[:-1] * signal[1:] < 0.0):
        poly = _interpolant(times, signal, i)
        roots.append(brentq(poly, times[i], times[i + 1], xtol=1e-15, rtol=4 * np.finfo(float).eps))
    return np.array(roots)


def attitude_at(times: np.ndarray, quat: np.ndarray, t: float) -> np.ndarray:
    """The recorded attitude (4,) unit quaternion at time t, interpolated between samples."""
    i = int(np.clip(np.searchsorted(times, t) - 1, 0, len(times) - 2))
    window = _window(len(times), i)
    local = quat[window].copy()
    # a quaternion and its negative are one attitude: make the samples continuous before interpolating
    for j in range(1, len(local)):
        if local[j] @ local[j - 1] < 0.0:
            local[j] = -local[j]
    value = np.array([Polynomial.fit(times[window], local[:, c], deg=len(local) - 1)(t) for c in range(4)])
    return value / np.linalg.norm(value)


def growth_rate(times: np.ndarray, separation: np.ndarray, window: np.ndarray) -> float:
    """Least-squares slope (1/s) of log(separation) over the samples in the window (bool mask); NaN if too few."""
    keep = window & np.isfinite(separation) & (separation > 0.0)
    if np.count_nonzero(keep) < MIN_FIT_SAMPLES:
        return math.nan
    return float(np.polyfit(times[keep], np.log(separation[keep]), 1)[0])


def _initial_stretch(mask: np.ndarray) -> np.ndarray:
    """The samples from the first up to (not including) the first one where mask is False."""
    bad = np.flatnonzero(~mask)
    end = bad[0] if bad.size else len(mask)
    out = np.zeros(len(mask), bool)
    out[:end] = True
    return out


# --- the torque-free body: period and Montgomery's phase (T9) ------------------------------------------------

def _principal(case: Case) -> tuple[np.ndarray, np.ndarray]:
    """Principal moments (ascending) and axes (columns) at O."""
    return np.linalg.eigh(np.asarray(case.inertia, dtype=float))


def _free_theory(case: Case) -> dict[str, float]:
    motion = free_motion(case.body, case.quat0, case.omega0)
    return {"period": motion.period, "montgomery_phase": motion.montgomery_phase}


def _free_measured(case: Case, traj: Trajectory, rerun: Rerun) -> dict[str, float]:
    """The period from the zeros of ω's middle-axis component (those of sn are half a period apart; for a symmetric
    body any axis across the symmetry axis does), and Montgomery's phase: the rotation angle about the run's own
    angular momentum (world) from R(0) to R(T), with T the measured period."""
    _, axes = _principal(case)
    roots = zero_crossings(traj.times, traj.omega @ axes[:, 1])
    if len(roots) < 2:
        return {}
    period = 2.0 * float(roots[-1] - roots[0]) / (len(roots) - 1)
    out = {"period": period}
    if period <= traj.times[-1]:
        start = traj.quat[0] / np.linalg.norm(traj.quat[0])
        momentum = quat_to_matrix(start) @ (case.inertia @ traj.omega[0])
        relative = quat_mul(attitude_at(traj.times, traj.quat, period), quat_conj(start))
        along = float(relative[1:] @ momentum) / float(np.linalg.norm(momentum))
        out["montgomery_phase"] = math.remainder(2.0 * math.atan2(along, relative[0]), 2.0 * math.pi)
    return out


FREE_MOTION = Check("free_motion", _free_theory, _free_measured)


# --- the middle-axis rotation: Lyapunov exponent (T8) --------------------------------------------------------

def _middle_axis_angle(case: Case) -> float:
    _, axes = _principal(case)
    omega = np.asarray(case.omega0, dtype=float)
    speed = float(np.linalg.norm(omega))
    return math.asin(min(1.0, float(np.linalg.norm(np.cross(omega, axes[:, 1]))) / speed)) if speed else math.inf


def unstable_direction(case: Case) -> np.ndarray:
    """Unit δω (3,) body: the eigenvector of the largest real eigenvalue of Euler's equations linearised at ω0,
    δω̇ = σ⁻¹(σδω × ω0 + σω0 × δω)."""
    sigma = np.asarray(case.inertia, dtype=float)
    omega = np.asarray(case.omega0, dtype=float)
    columns = [np.linalg.solve(sigma, np.cross(sigma @ unit, omega) + np.cross(sigma @ omega, unit))
               for unit in np.eye(3)]
    values, vectors = np.linalg.eig(np.column_stack(columns))
    direction = np.real(vectors[:, int(np.argmax(values.real))])
    return direction / np.linalg.norm(direction)


def _lyapunov_theory(case: Case) -> dict[str, float]:
    moments, _ = _principal(case)
    # the stationary rotation with the run's angular momentum: |w| = L / I2
    rate = float(np.linalg.norm(case.inertia @ case.omega0)) / float(moments[1])
    return {"lyapunov_exponent": lyapunov_exponent(case.body, rate)}


def _lyapunov_measured(case: Case, traj: Trajectory, rerun: Rerun) -> dict[str, float]:
    """Slope of log |ω_rerun - ω| while the run is still within LINEAR_DEVIATION of the middle axis."""
    omega0 = np.asarray(case.omega0, dtype=float)
    kick = LYAPUNOV_KICK * float(np.linalg.norm(omega0)) * unstable_direction(case)
    nearby = _rerun(rerun, dataclasses.replace(case, omega0=omega0 + kick))
    if nearby is None:
        return {}
    _, axes = _principal(case)
    speed = np.linalg.norm(traj.omega, axis=1)
    with np.errstate(invalid="ignore"):
        deviation = np.linalg.norm(np.cross(traj.omega, axes[:, 1]), axis=1) / speed
    separation = np.linalg.norm(nearby.omega - traj.omega, axis=1)
    return {"lyapunov_exponent": growth_rate(traj.times, separation, _initial_stretch(deviation <= LINEAR_DEVIATION))}


def _rerun(rerun: Rerun, case: Case) -> Trajectory | None:
    """The rerun's trajectory, or None if it did not finish ok (its failure is the engine's, not the check's)."""
    try:
        nearby = rerun(case)
    except Exception as exc:  # an engine that cannot redo the run leaves the measurement NaN, as a failed run would
        raise_if_internal(exc)
        return None
    return nearby if nearby.status is Status.OK else None


LYAPUNOV = Check("lyapunov", _lyapunov_theory, _lyapunov_measured)


# --- the Lagrange top: precession rate and the sleeping top (G5) ---------------------------------------------

@dataclasses.dataclass(frozen=True)
class _Top:
    k: np.ndarray           # (3,) body, unit, O -> G
    up: np.ndarray          # (3,) world, unit, -d
    east: np.ndarray        # (3,) world, unit, horizontal
    north: np.ndarray       # (3,) world, up × east
    a1: float               # kg m², transverse moment at O
    a3: float               # kg m², moment about k
    alpha: float            # N m, m g |OG|
    cos_tilt: float         # k·up at t = 0
    sin_tilt: float
    spin: float             # rad/s, ω0·k
    rate: float             # rad/s, the state's precession rate φ̇ (ω0 = φ̇ u0 + ψ̇ k)


def _lagrange_top(case: Case) -> _Top:
    body = case.body
    sigma = np.asarray(case.inertia, dtype=float)
    alpha = float(np.linalg.norm(body.weight_moment))
    k = body.weight_moment / alpha
    up = -np.asarray(body.gravity_direction, dtype=float)
    east = np.cross(up, np.eye(3)[int(np.argmin(np.abs(up)))])
    east /= np.linalg.norm(east)
    omega = np.asarray(case.omega0, dtype=float)
    up_body = quat_to_matrix(case.quat0).T @ up
    cos_tilt = float(up_body @ k)
    sin_tilt = float(np.linalg.norm(np.cross(up_body, k)))
    rate = (omega @ up_body - cos_tilt * (omega @ k)) / sin_tilt ** 2 if sin_tilt > 0.0 else 0.0
    transverse = sigma - np.outer(sigma @ k, k)  # σ restricted to k⊥ is A1 times the identity there
    return _Top(k, up, east, np.cross(up, east), float(np.trace(transverse)) / 2.0, float(k @ sigma @ k), alpha,
                cos_tilt, sin_tilt, float(omega @ k), float(rate))


def _figure_axis(traj: Trajectory, k: np.ndarray) -> np.ndarray:
    """(n, 3) world: R(t) k."""
    return quat_to_matrix(traj.quat) @ k


def _precession_theory(case: Case) -> dict[str, float]:
    top = _lagrange_top(case)
    roots = lagrange_rates(case.body, math.atan2(top.sin_tilt, top.cos_tilt), top.spin)
    # the root of G5 this state was set on (the state decides which of the two precessions it is)
    return {"precession_rate": min((r for r in roots if math.isfinite(r)), key=lambda r: abs(r - top.rate))}


def _precession_measured(case: Case, traj: Trajectory, rerun: Rerun) -> dict[str, float]:
    """Least-squares slope of the figure axis's azimuth about the vertical."""
    top = _lagrange_top(case)
    axis = _figure_axis(traj, top.k)
    azimuth = np.unwrap(np.arctan2(axis @ top.north, axis @ top.east))
    return {"precession_rate": float(np.polyfit(traj.times, azimuth, 1)[0])}


PRECESSION = Check("precession", _precession_theory, _precession_measured)


def tilt_exponents(case: Case) -> np.ndarray:
    """The two exponents s (complex, 1/s) of a small tilt u = u_east + i u_north of the sleeping top's figure axis,
    u ∝ e^{s t}: linearising L = A1 n × ṅ + A3 r n about n = up gives A1 ü - i A3 r u̇ - α u = 0."""
    top = _lagrange_top(case)
    return np.roots([top.a1, -1j * top.a3 * top.spin, -top.alpha])


def _sleeping_theory(case: Case) -> dict[str, float]:
    """Re s = √(max(0, 4 A1 α - A3² r²)) / (2 A1): positive below the threshold r_c = 2 √(A1 α) / A3, 0 above."""
    top = _lagrange_top(case)
    return {"tilt_growth_rate": math.sqrt(max(0.0, 4.0 * top.a1 * top.alpha - (top.a3 * top.spin) ** 2))
            / (2.0 * top.a1)}


def tilted_state(case: Case, tilt: float) -> tuple[np.ndarray, np.ndarray]:
    """(quat0, omega0) of the sleeping top with its figure axis tilted by `tilt` (rad) towards east and tilting at
    the rate of the mode of largest real part, u(0) = tilt, u̇(0) = s tilt: one pure exponential to first order."""
    top = _lagrange_top(case)
    exponent = max(tilt_exponents(case), key=lambda s: s.real)
    turn = np.concatenate(([math.cos(tilt / 2.0)], math.sin(tilt / 2.0) * top.north))  # Rot(north, tilt)
    quat0 = quat_mul(turn, case.quat0)
    axis = math.cos(tilt) * top.up + math.sin(tilt) * top.east
    axis_rate = tilt * (exponent.real * top.east + exponent.imag * top.north)
    omega_world = top.spin * axis + np.cross(axis, axis_rate)
    return quat0, quat_to_matrix(quat0).T @ omega_world


def _sleeping_measured(case: Case, traj: Trajectory, rerun: Rerun) -> dict[str, float]:
    """Slope of log(angle between the two runs' figure axes) while that angle is below LINEAR_TILT."""
    quat0, omega0 = tilted_state(case, TILT_KICK)
    nearby = _rerun(rerun, dataclasses.replace(case, quat0=quat0, omega0=omega0))
    if nearby is None:
        return {}
    k = _lagrange_top(case).k
    gap = np.linalg.norm(_figure_axis(nearby, k) - _figure_axis(traj, k), axis=1)
    with np.errstate(invalid="ignore"):
        angle = 2.0 * np.arcsin(np.minimum(1.0, gap / 2.0))
        linear = angle <= LINEAR_TILT
    return {"tilt_growth_rate": growth_rate(traj.times, angle, _initial_stretch(linear))}


SLEEPING_TOP = Check("sleeping_top", _sleeping_theory, _sleeping_measured)


# --- Grioli's precession (G10) -------------------------------------------------------------------------------

def _grioli_theory(case: Case) -> dict[str, float]:
    """|ω|² = 2 α cos χ / A_f with A_f = k·σk, cos χ = A_f / |σk|; the precession axis does not move."""
    body = case.body
    alpha = float(np.linalg.norm(body.weight_moment))
    k = body.weight_moment / alpha
    sigma_k = np.asarray(case.inertia, dtype=float) @ k
    figure_moment = float(k @ sigma_k)
    cos_chi = figure_moment / float(np.linalg.norm(sigma_k))
    return {"omega_squared": 2.0 * alpha * cos_chi / figure_moment, "precession_axis_drift": 0.0}


def _grioli_measured(case: Case, traj: Trajectory, rerun: Rerun) -> dict[str, float]:
    """|ω|² at the sample farthest from theory; the largest distance of the precession axis c = ω/(ω·k) - k, in world
    components, from where it started."""
    theory = _grioli_theory(case)["omega_squared"]
    k = case.body.weight_moment / np.linalg.norm(case.body.weight_moment)
    speed2 = np.sum(traj.omega ** 2, axis=1)
    axis = traj.omega / (traj.omega @ k)[:, None] - k
    axis_world = np.einsum("nij,nj->ni", quat_to_matrix(traj.quat), axis)
    return {"omega_squared": float(speed2[np.argmax(np.abs(speed2 / theory - 1.0))]),
            "precession_axis_drift": float(np.max(np.linalg.norm(axis_world - axis_world[0], axis=1)))}


GRIOLI = Check("grioli", _grioli_theory, _grioli_measured)


# ------------------------------------------------------------------------------------------------- checks.csv

def table(rows: list[dict]) -> pd.DataFrame:
    """checks.csv's table from result rows (each with its ROW_KEY list), in their order (the sweep gives them in the
    results table's: harness.run.results.row_order)."""
    records = [{**{column: row.get(column) for column in RUN_COLUMNS}, **check}
               for row in rows for check in row.get(ROW_KEY) or ()]
    df = pd.DataFrame(records, columns=list(COLUMNS))
    for column in ("dt", "theory", "measured", "error"):
        df[column] = pd.to_numeric(df[column], errors="coerce")  # the store writes NaN as null
    df["formulation"] = df["formulation"].fillna("")
    df["precision"] = df["precision"].fillna(FLOAT64)  # a stored row of 0.2.0 has none: float64
    return df


def write_checks(rows: list[dict], path: Path) -> None:
    """Write checks.csv atomically; full precision, since a period is checked to 1e-10 and more."""
    write_atomic(Path(path), table(rows).to_csv(index=False, float_format="%.17g"))


def read_checks(path: Path) -> pd.DataFrame:
    df = read_csv_table(path, dtype={"formulation": str, "precision": str}, keep_default_na=True)
    if "precision" not in df:  # a checks.csv of 0.2.0: float64 runs
        df["precision"] = FLOAT64
    return df.fillna({"formulation": "", "precision": FLOAT64})


# ------------------------------------------------------------------------------------------------- the report

def _truth_mask(df: pd.DataFrame) -> pd.Series:
    return ((df["engine"] == TRUTH_ENGINE) & (df["formulation"] == TRUTH_FORMULATION)
            & (df["integrator"] == TRUTH_INTEGRATOR))


def _label(row) -> str:
    parts = [row["engine"], row.get("formulation") or "", row["integrator"]]
    dt = row.get("dt")
    if dt is not None and isinstance(dt, float) and math.isfinite(dt):
        parts.append(f"dt={dt:g}")
    return " ".join(p for p in parts if isinstance(p, str) and p)


def _num(value, spec: str = ".2e") -> str:
    try:
        value = float(value)
    except (TypeError, ValueError):
        return "-"
    return "-" if math.isnan(value) else format(value, spec)


def summary_rows(checks: pd.DataFrame) -> tuple[list[str], list[list[str]]]:
    """Per case and quantity: theory, the truth's measurement and error, and the spread of the other runs' errors."""
    header = ["case", "quantity", "theory", "truth measured", "truth error", "other runs", "smallest error",
              "largest error (run)"]
    rows = []
    truth = _truth_mask(checks)
    for (case, quantity), group in checks.groupby(["case", "quantity"], sort=False):
        own = group[truth[group.index]]
        others = group[~truth[group.index]]
        measured = others[np.isfinite(others["error"])]
        worst = measured.loc[measured["error"].idxmax()] if len(measured) else None
        rows.append([case, quantity, _num(group["theory"].iloc[0], ".10g"),
                     _num(own["measured"].iloc[0], ".10g") if len(own) else "-",
                     _num(own["error"].iloc[0]) if len(own) else "-", f"{len(measured)} of {len(others)}",
                     _num(measured["error"].min()) if len(measured) else "-",
                     "-" if worst is None else f"{_num(worst['error'])} ({_label(worst)})"])
    return header, rows


def oracle_rows(df: pd.DataFrame) -> tuple[list[str], list[list[str]]]:
    """Per case with an exact solution: the truth's oracle_err (DESIGN §4) and the other runs' spread."""
    header = ["case", "truth oracle_err", "other runs", "smallest oracle_err", "largest oracle_err (run)"]
    rows = []
    with_oracle = df[np.isfinite(df["oracle_err"])] if "oracle_err" in df else df.iloc[:0]
    truth = _truth_mask(with_oracle)
    for case, group in with_oracle.groupby("case", sort=False):
        own = group[truth[group.index]]
        others = group[~truth[group.index]]
        worst = others.loc[others["oracle_err"].idxmax()] if len(others) else None
        rows.append([case, _num(own["oracle_err"].iloc[0]) if len(own) else "-", str(len(others)),
                     _num(others["oracle_err"].min()) if len(others) else "-",
                     "-" if worst is None else f"{_num(worst['oracle_err'])} ({_label(worst)})"])
    return header, rows
