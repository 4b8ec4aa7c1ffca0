"""Write the suite's cases with exact solutions (cases/*.toml, DESIGN §3) from the constructors of reference.exact.

    python tools/make_oracle_cases.py            write (or rewrite) the files
    python tools/make_oracle_cases.py --check    exit 1 if a committed file differs from what this script writes

Floats are written with repr(), so a file reads back to the very numbers computed here. The unstable motions use
parameters that are exact in binary (FORMULARY §6): their conditions then hold exactly, not to rounding, and the
double-precision truth follows the exact solution until round-off has grown. Each horizon below was measured: the
truth stays within 1e-11 rad of the exact solution up to it (tests/test_oracle_cases.py checks it in the sweep).
"""
from __future__ import annotations

import argparse
import math
import re
import sys
import tomllib
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from stereodyn.reference.body import RigidBody
from stereodyn.reference.euler_poisson import downward_vertical
from stereodyn.reference.exact import (Setup, free_motion, grioli_body, grioli_precession, hess_grioli_body, lagrange_precession,
                             lagrange_rates, lyapunov_exponent, separatrix_distance, sleeping_top_threshold,
                             staude_rate_squared)
from stereodyn.reference.rotations import matrix_to_quat, zxz_to_matrix

CASES_DIR = Path(__file__).resolve().parent.parent / "cases"
HEADER = "# Written by tools/make_oracle_cases.py from reference.exact: edit that script and rerun it, not this file.\n"
T_END = 20.0
DT = (1e-2, 3e-3)  # two steps keep the default suite within minutes on two cores
SAMPLES = 1000
G = 9.81
IDENTITY = np.array([1.0, 0.0, 0.0, 0.0])
HALF_TURN_X = np.array([0.0, 1.0, 0.0, 0.0])  # exact: R = diag(1, -1, -1)
# A generic attitude for the torque-free bodies (their motion in the body does not depend on it).
FREE_ATTITUDE = matrix_to_quat(zxz_to_matrix(0.3, 1.2, -0.4))
# The sleeping tops and the regular precession share the body of cases/lagrange-top.toml.
TOP = RigidBody(np.diag([1.0, 1.0, 0.4]), 1.0, np.array([0.0, 0.0, 0.2]), G)
# FORMULARY G11's Hess body A1 = 5/4, A3 = 1, A1' = 1/2 (so A2 = 3/2), α = m g |OG| = 3/4, every number exact; |OG|
# = 1/4 with g = 3 (|OG| = 1, g = 3/4 would break the triangle inequality about the centre of mass).
HESS_GRIOLI = hess_grioli_body(1.25, 1.0, 0.5, 1.0, 0.25, 3.0)


@dataclass(frozen=True)
class CaseSpec:
    """One case file. horizon_note: why the horizon (a comment in the file)."""

    stem: str
    description: str
    tags: tuple[str, ...]
    body: RigidBody
    quat0: np.ndarray
    omega0: np.ndarray
    oracle: str | None = None
    horizon: float | None = None
    horizon_note: str = ""
    t_end: float = T_END


def _free(moments) -> RigidBody:
    return RigidBody(np.diag(moments), 1.0, np.zeros(3))


def _on(setup: Setup) -> tuple[RigidBody, np.ndarray, np.ndarray]:
    return setup.body, setup.quat0, setup.omega0


def _free_case(stem: str, moments, omega0, family: str, tags=("free", "oracle", "integrable"), **extra) -> CaseSpec:
    body = _free(moments)
    omega0 = np.asarray(omega0, dtype=float)
    motion = free_motion(body, FREE_ATTITUDE, omega0)
    description = (f"Torque-free body, principal moments {_plain(moments)}, {family}: period T = {motion.period:.6g} "
                   f"s, Montgomery phase {motion.montgomery_phase:.6g} rad (FORMULARY T9)")
    return CaseSpec(stem, description, tags, body, FREE_ATTITUDE, omega0, "euler_poinsot", **extra)


def specs() -> list[CaseSpec]:
    out = [
        _free_case("euler-poinsot-major", (2.7, 1.9, 1.1), (1.0, 0.2, 0.3), "ω circulating about the largest axis"),
        _free_case("euler-poinsot-minor", (2.7, 1.9, 1.1), (0.1, 0.3, 1.2), "ω circulating about the smallest axis"),
        _free_case("euler-poinsot-symmetric", (2.0, 2.0, 1.0), (0.3, -0.5, 1.1), "symmetric (A1 = A2)"),
    ]

    # Dzhanibekov: ω0 2^-10 rad off the middle axis (separatrix distance ~7e-7): flips every half period. The flips
    # amplify the truth's round-off (measured: 7e-14 rad after the first flip at t ~ 5, 1e-11 at the second, t ~ 13).
    dzhanibekov = _free((3.0, 2.0, 1.0))
    omega0 = np.array([3.0 * 2.0 ** -10, 3.0, 0.0])
    motion = free_motion(dzhanibekov, FREE_ATTITUDE, omega0)
    out.append(CaseSpec(
        "dzhanibekov",
        f"Dzhanibekov flip: torque-free body (3, 2, 1) spun 2^-10 rad off the middle axis, separatrix distance "
        f"{separatrix_distance(dzhanibekov, omega0):.3g}: period T = {motion.period:.6g} s, Lyapunov exponent of the "
        f"middle-axis rotation {lyapunov_exponent(dzhanibekov, 3.0):.6g} /s (FORMULARY T8)",
        ("free", "oracle", "unstable"), dzhanibekov, FREE_ATTITUDE, omega0, "euler_poinsot", 10.0,
        "the second flip (t ~ 13) amplifies the truth's round-off to 1e-11"))

    # The separatrix, exactly: I1 (I1 - I2) ω1² = I3 (I2 - I3) ω3² with (2.25, 2, 1) and ω3 = 0.75 ω1.
    separatrix = _free((2.25, 2.0, 1.0))
    omega0 = np.array([0.5, -1.0, -0.375])
    speed = math.sqrt(float(np.sum((np.diag(separatrix.inertia) * omega0) ** 2))) / 2.0
    out.append(CaseSpec(
        "separatrix",
        f"The separatrix (FORMULARY T8) of the torque-free body (2.25, 2, 1), exact in binary: ω tends to the middle "
        f"axis at |ω| -> {speed:.6g} rad/s, Lyapunov exponent {lyapunov_exponent(separatrix, speed):.6g} /s",
        ("free", "oracle", "unstable"), separatrix, IDENTITY, omega0, "euler_poinsot_separatrix", T_END,
        "unstable: the truth leaves the separatrix like 1e-16 e^(0.39 t), 4e-14 rad at t = 20, 1e-11 at t ~ 34"))

    setup = lagrange_precession(TOP, 0.6, 15.0, "slow", heading=0.3)
    slow, fast = lagrange_rates(TOP, 0.6, 15.0)
    out.append(CaseSpec(
        "lagrange-precession",
        f"Lagrange top (A1 = A2 = 1, A3 = 0.4, com 0.2 on the axis) in regular precession (FORMULARY G5): tilt 0.6 "
        f"rad, spin 15 rad/s, the slow precession rate {slow:.6g} rad/s (fast root {fast:.6g})",
        ("heavy-top", "oracle", "integrable"), *_on(setup), "lagrange_precession"))

    threshold = sleeping_top_threshold(TOP)
    for stem, factor, side, horizon, note, tags in (
            ("sleeping-top-stable", 1.01, "above", None, "", ("heavy-top", "oracle")),
            ("sleeping-top-unstable", 0.99, "below", T_END,
             "unstable, but the state is exact (ω ∥ k, R0 = I): measured 1e-14 rad at t = 30",
             ("heavy-top", "oracle", "unstable"))):
        setup = lagrange_precession(TOP, 0.0, factor * threshold)
        out.append(CaseSpec(
            stem,
            f"Sleeping top (centre of mass straight above O), spin {factor:g} x the threshold r_c = "
            f"{threshold:.6g} rad/s: {side} it, so linearly {'stable' if factor > 1 else 'unstable'} (FORMULARY G5)",
            tags, *_on(setup), "lagrange_precession", horizon, note))

    # Staude: every number exact in binary, γ = H0 = (0, 0, -1), Ω² = w1 / σ13 = 1 (tests/test_exact_heavy.py).
    staude = RigidBody(np.array([[2.0, 0.0, 0.25], [0.0, 1.5, 0.0], [0.25, 0.0, 1.0]]), 1.0,
                       np.array([0.25, 0.0, 0.5]), 1.0)
    omega0 = np.array([0.0, 0.0, 1.0])
    out.append(CaseSpec(
        "staude-rotation",
        f"Staude permanent rotation (FORMULARY G9) about the vertical, Ω² = {staude_rate_squared(staude, -omega0):g} "
        f"(rad/s)², non-principal inertia, exact in binary",
        ("heavy-top", "oracle", "unstable"), staude, IDENTITY, omega0, "staude_rotation", T_END,
        "unstable: round-off grows like e^(0.43 t), 3e-14 rad at t = 20, 2e-12 at t = 30"))

    grioli = grioli_body((2.5625, 2.0, 1.0), 1.0, 0.625, G)
    setup = grioli_precession(grioli, 1.0, heading=0.7)
    out.append(CaseSpec(
        "grioli-precession",
        "Grioli's regular precession of the asymmetric heavy top (FORMULARY G10): principal moments (2.5625, 2, 1), "
        "centre of mass 0.625 along the normal (0.6, 0, 0.8) of a circular section, |ω|² = 2 α cos χ / A_f",
        ("heavy-top", "oracle", "integrable"), *_on(setup), "grioli_precession"))

    # K·k = 0 and K·H = 0 exactly: ω0 = ḃ1 (0, 1, A1'/A3) with b2 = 0, G straight below O (H0 = k).
    out.append(CaseSpec(
        "hess-grioli",
        "Hess–Grioli non-regular precession (FORMULARY G11): Hess body A1 = 5/4, A2 = 3/2, A3 = 1, A1' = 1/2, "
        "α = 3/4, from G below O with ḃ1 = 1 rad/s (a swing of ~80 degrees), exact in binary",
        ("heavy-top", "oracle", "unstable"), HESS_GRIOLI, HALF_TURN_X, np.array([0.0, 1.0, 0.5]), "hess_grioli",
        T_END, "unstable, but the state is exact: measured 1e-14 rad at t = 30"))
    out.append(CaseSpec(
        "mlodzejowski",
        "Mlodzejowski rotation (FORMULARY G11): the Hess body swinging about its horizontal middle axis as a compound "
        "pendulum, from G below O at 1 rad/s, exact in binary",
        ("heavy-top", "oracle", "unstable"), HESS_GRIOLI, HALF_TURN_X, np.array([1.0, 0.0, 0.0]), "mlodzejowski",
        T_END, "unstable, but the state is exact: measured 5e-15 rad at t = 30"))

    # Goryachev–Chaplygin: ω3 chosen so that the vertical angular momentum K·H is zero (FORMULARY G8).
    chaplygin = RigidBody(np.diag([4.0, 4.0, 1.0]), 1.0, np.array([0.5, 0.0, 0.0]), G)
    quat0 = matrix_to_quat(zxz_to_matrix(0.2, 1.0, 0.4))
    vertical = downward_vertical(chaplygin, quat0[None])[0]
    omega0 = np.array([0.5, -0.3, 0.0])
    omega0[2] = -4.0 * (omega0[0] * vertical[0] + omega0[1] * vertical[1]) / vertical[2]
    out.append(CaseSpec(
        "goryachev-chaplygin",
        "Goryachev–Chaplygin top (FORMULARY G8): A1 = A2 = 4 A3, centre of mass in the equatorial plane, zero "
        "vertical angular momentum; no exact solution, its integral is the check",
        ("heavy-top", "integrable"), chaplygin, quat0, omega0))

    # Hess's invariant relation K·k = 0 (FORMULARY G7's exact body: A = (6, 5, 3), α k = (1/2, 0, 1)), off the
    # Hess–Grioli motions (K·H ≠ 0). The manifold is transversally unstable: |K·k| ~ 7e-14 |K| by t = 20 in the truth.
    hess = RigidBody(np.diag([6.0, 5.0, 3.0]), 1.0, np.array([0.5, 0.0, 1.0]), 1.0)
    out.append(CaseSpec(
        "hess",
        "Hess invariant relation K·k = 0 (FORMULARY G7): principal moments (6, 5, 3), α k = (1/2, 0, 1), exact in "
        "binary; no exact solution, the relation is the check",
        ("heavy-top", "invariant-relation", "unstable"), hess, matrix_to_quat(zxz_to_matrix(0.3, 0.9, -0.2)),
        np.array([0.5, 1.0, -0.5])))
    return out


def _plain(values) -> str:
    return "(" + ", ".join(f"{v:g}" for v in values) + ")"


def _floats(values) -> str:
    return "[" + ", ".join(repr(float(v)) for v in np.asarray(values, dtype=float).ravel()) + "]"


def render(spec: CaseSpec) -> str:
    """The TOML text of one case (DESIGN §3)."""
    body = spec.body
    inertia = np.asarray(body.inertia, dtype=float)
    lines = [HEADER.rstrip("\n"), f"description = {_string(spec.description)}",
             "tags = [" + ", ".join(_string(tag) for tag in spec.tags) + "]", "", "[body]",
             f"mass = {float(body.mass)!r}", f"com = {_floats(body.com)}"]
    if np.count_nonzero(inertia - np.diag(np.diag(inertia))) == 0:
        lines.append(f"principal_moments = {_floats(np.diag(inertia))}")
    else:
        rows = [_floats(row) for row in inertia]
        lines.append("inertia = [" + (",\n           ".join(rows)) + "]")
    if body.gravity != 0.0:
        lines += ["", "[gravity]", f"g = {float(body.gravity)!r}", f"direction = {_floats(body.gravity_direction)}"]
    lines += ["", "[initial]", f"attitude = {{ quaternion = {_floats(spec.quat0)} }}",
              f"omega = {_floats(spec.omega0)}", "", "[run]", f"t_end = {spec.t_end!r}",
              f"dt = {_floats(DT)}", f"samples = {SAMPLES}"]
    if spec.oracle is not None:
        lines += ["", "[expect]", f"oracle = {_string(spec.oracle)}"]
        if spec.horizon is not None:
            lines.append(f"horizon = {spec.horizon!r}" + (f"   # {spec.horizon_note}" if spec.horizon_note else ""))
    return "\n".join(lines) + "\n"


def _string(text: str) -> str:
    if '"' in text or "\\" in text:
        raise ValueError(f"keep quotes and backslashes out of case text: {text!r}")
    return f'"{text}"'


# Numbers the script computes (e.g. a precession rate through arctan and sqrt) may differ in the last bits between
# CPUs and libm builds: lagrange-precession.toml's omega[0] differs by 1 ulp between the machine that wrote it and an
# AMD EPYC with AVX-512. --check therefore compares the text with every float literal masked exactly (keys,
# structure, comments), and every float literal (comments included) and parsed float within this many ulps.
CHECK_ULPS = 4
_FLOAT = re.compile(r"(?<![\w.])[-+]?(?:\d+\.\d*(?:[eE][-+]?\d+)?|\d+[eE][-+]?\d+|inf|nan)\b")


def _close(committed, written) -> bool:
    if isinstance(committed, dict):
        return isinstance(written, dict) and committed.keys() == written.keys() \
            and all(_close(committed[key], written[key]) for key in committed)
    if isinstance(committed, list):
        return isinstance(written, list) and len(committed) == len(written) \
            and all(_close(a, b) for a, b in zip(committed, written))
    if isinstance(committed, float) and isinstance(written, float):
        if math.isnan(committed) or math.isnan(written) or math.isinf(committed) or math.isinf(written):
            return committed == written or (math.isnan(committed) and math.isnan(written))
        return abs(committed - written) <= CHECK_ULPS * math.ulp(max(abs(committed), abs(written)))
    return type(committed) is type(written) and committed == written


def same_case_text(committed: str, written: str) -> bool:
    """The committed file is what the script writes: the same text outside float literals, and the same parsed
    values with floats within CHECK_ULPS ulps."""
    if _FLOAT.sub("#", committed) != _FLOAT.sub("#", written):
        return False
    literals = [float(x) for x in _FLOAT.findall(committed)], [float(x) for x in _FLOAT.findall(written)]
    if not _close(*literals):  # the literals in comments too, which the parsed values below do not see
        return False
    try:
        return _close(tomllib.loads(committed), tomllib.loads(written))
    except tomllib.TOMLDecodeError:
        return False


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--check", action="store_true", help="compare with the committed files, write nothing")
    parser.add_argument("--out", type=Path, default=CASES_DIR, help=f"folder (default {CASES_DIR})")
    args = parser.parse_args(argv)
    from stereodyn.harness.scenes.cases import load_case  # validates every file as the suite will, [expect] oracle
    # included

    stale = []
    for spec in specs():
        path = args.out / f"{spec.stem}.toml"
        text = render(spec)
        if args.check:
            if not path.is_file() or not same_case_text(path.read_text(encoding="utf-8"), text):
                stale.append(path.name)
            continue
        path.write_text(text, encoding="utf-8")
        load_case(path)
        print(f"wrote {path}")
    if stale:
        print(f"out of date (rerun tools/make_oracle_cases.py): {', '.join(stale)}", file=sys.stderr)
        return 1
    return 0


if __name__ == "__main__":
    sys.exit(main())
