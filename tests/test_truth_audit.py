"""The truth can be audited: with --save-trajectories the truth row's states are on disk, and its truth_err /
truth_omega_err bound their error against an independent 40-digit Taylor integration (mpmath) done here."""
import json
import math
import shutil

import mpmath as mp
import numpy as np
import pandas as pd
import pytest
from helpers import TIMINGS, store_mtimes

from stereodyn.harness import cli
from stereodyn.harness.scenes.cases import find_case
from stereodyn.harness.run.store import read_manifest
from stereodyn.reference.rotations import attitude_angle, quat_to_matrix
from stereodyn.reference.truth import ANGLE_ROUNDING, UNIT_ROUNDOFF, truth, truth_bound

T_END = 40.0
ORDER = 30          # Taylor order of the mpmath reference
STEP = 0.1          # its largest step (s); the series' radius here is ~1 s, so a step's truncation is < 1e-30


def taylor_reference(inertia: np.ndarray, quat0: np.ndarray, omega0: np.ndarray, times: list[float]):
    """The torque-free body's (q, ω) at `times` (from 0), by Taylor series of order ORDER at mp.dps 40:
    ω' = I⁻¹ ((Iω) × ω), q' = ½ q ⊗ (0, ω), coefficients by Cauchy products (mp.fdot)."""
    with mp.workdps(40):
        sigma = mp.matrix([[mp.mpf(float(v)) for v in row] for row in inertia])
        inverse = sigma ** -1
        q = [mp.mpf(float(v)) for v in quat0]
        norm = mp.sqrt(mp.fsum(v * v for v in q))
        q = [v / norm for v in q]
        w = [mp.mpf(float(v)) for v in omega0]
        t, out = mp.mpf(0), []
        for target in times:
            target = mp.mpf(target)
            pieces = max(1, int(mp.ceil((target - t) / STEP)))
            h = (target - t) / pieces
            for _ in range(pieces if target > t else 0):
                q, w = _taylor_step(sigma, inverse, q, w, h)
            t = target
            out.append((list(q), list(w)))
        return out


def _taylor_step(sigma, inverse, q, w, h):
    Q = [[v] for v in q]               # Q[i][k]: k-th Taylor coefficient of q_i
    W = [[v] for v in w]
    L = [[mp.fsum(sigma[i, j] * w[j] for j in range(3))] for i in range(3)]   # I ω
    for k in range(ORDER):
        rev = [Wi[k::-1] for Wi in W]
        cross = [mp.fdot(L[1], rev[2]) - mp.fdot(L[2], rev[1]),
                 mp.fdot(L[2], rev[0]) - mp.fdot(L[0], rev[2]),
                 mp.fdot(L[0], rev[1]) - mp.fdot(L[1], rev[0])]
        wq, xq, yq, zq = Q
        dq = [-(mp.fdot(xq, rev[0]) + mp.fdot(yq, rev[1]) + mp.fdot(zq, rev[2])),
              mp.fdot(wq, rev[0]) + mp.fdot(yq, rev[2]) - mp.fdot(zq, rev[1]),
              mp.fdot(wq, rev[1]) + mp.fdot(zq, rev[0]) - mp.fdot(xq, rev[2]),
              mp.fdot(wq, rev[2]) + mp.fdot(xq, rev[1]) - mp.fdot(yq, rev[0])]
        for i in range(4):
            Q[i].append(dq[i] / (2 * (k + 1)))
        new_w = [mp.fsum(inverse[i, j] * cross[j] for j in range(3)) / (k + 1) for i in range(3)]
        for i in range(3):
            W[i].append(new_w[i])
        for i in range(3):
            L[i].append(mp.fsum(sigma[i, j] * new_w[j] for j in range(3)))
    return [_horner(c, h) for c in Q], [_horner(c, h) for c in W]


def _horner(coefficients: list, h):
    total = mp.mpf(0)
    for c in reversed(coefficients):
        total = total * h + c
    return total


def exact_angle(q_double: np.ndarray, q_ref: list) -> float:
    """The geodesic angle (rad) between the rotations of a float64 quaternion (taken exactly) and the reference, at 40
    digits: 2 atan2(|vec(q̄ ⊗ r)|, |scalar(q̄ ⊗ r)|) with q normalised."""
    with mp.workdps(40):
        a = [mp.mpf(float(v)) for v in q_double]
        norm = mp.sqrt(mp.fsum(v * v for v in a))
        w1, x1, y1, z1 = (v / norm for v in a)
        w2, x2, y2, z2 = q_ref
        scalar = w1 * w2 + x1 * x2 + y1 * y2 + z1 * z2
        vec = [w1 * x2 - w2 * x1 - (y1 * z2 - z1 * y2), w1 * y2 - w2 * y1 - (z1 * x2 - x1 * z2),
               w1 * z2 - w2 * z1 - (x1 * y2 - y1 * x2)]
        return float(2 * mp.atan2(mp.sqrt(mp.fsum(v * v for v in vec)), abs(scalar)))


@pytest.fixture(scope="module")
def audited_run(tmp_path_factory):
    out = tmp_path_factory.mktemp("audit")
    argv = ["run", "free-asymmetric", "--engines", "reference", "--integrators", "taylor", "--t-end", str(T_END),
            "--save-trajectories", "--jobs", "1", "--quiet", "--out", str(out)]
    assert cli.main(argv) == 0
    return out


def test_the_saved_truth_is_within_its_bound_of_a_40_digit_reference(audited_run):
    df = pd.read_csv(audited_run / "results.csv", dtype={"formulation": str}, keep_default_na=False)
    row = df[(df.formulation == "quaternion") & (df.integrator == "taylor")].iloc[0]
    keys = read_manifest(audited_run)["runs"]
    saved = [np.load(audited_run / "trajectories" / f"{key}.npz") for key in keys]
    assert len(saved) == len(df) and all(s["engine"].shape == () for s in saved)
    truth = next(s for s in saved if str(s["formulation"]) == "quaternion" and str(s["integrator"]) == "taylor")
    assert str(truth["case"]) == "free-asymmetric" and str(truth["engine"]) == "reference"
    assert math.isnan(float(truth["dt"])) and truth["times"][-1] == T_END
    times, quat, omega = truth["times"], truth["quat"], truth["omega"]
    assert quat.shape == (len(times), 4) and omega.shape == (len(times), 3)

    case = find_case("free-asymmetric")
    np.testing.assert_array_equal(omega[0], case.omega0)
    chosen = list(range(0, len(times), 37)) + [len(times) - 1]   # 29 samples, the last at t = 40
    reference = taylor_reference(case.body.inertia, case.quat0, case.omega0, [float(times[i]) for i in chosen])
    exact = [exact_angle(quat[i], ref_q) for i, (ref_q, _) in zip(chosen, reference)]
    ref_quat = np.array([[float(v) for v in ref_q] for ref_q, _ in reference])
    ref_omega = np.array([[float(v) for v in ref_w] for _, ref_w in reference])
    # the float64 check anyone would run: the harness's own attitude_angle on the reference rounded to float64
    measured = attitude_angle(quat_to_matrix(quat[chosen]), quat_to_matrix(ref_quat))
    scale = np.max(np.linalg.norm(omega, axis=1))
    omega_err = np.max(np.linalg.norm(omega[chosen] - ref_omega, axis=1)) / scale
    print(f"truth_err {row.truth_err:.3e}: exact {max(exact):.3e}, float64 {measured.max():.3e}; "
          f"truth_omega_err {row.truth_omega_err:.3e}: {omega_err:.3e}")
    assert max(exact) <= row.truth_err and measured.max() <= row.truth_err
    assert omega_err <= row.truth_omega_err
    # The bound's claim (reference.truth, above ATTITUDE_ALLOWANCE): any float64 comparison, against a reference rounded
    # to float64 (2u) with its own rounding <= ANGLE_ROUNDING, stays below it. Here, without the allowance, truth_err
    # would be 4.1e-15 < exact 3.8e-15 + 2u + ANGLE_ROUNDING = 5.8e-15 (free-asymmetric, t = 40, AMD EPYC).
    assert max(exact) + 2 * UNIT_ROUNDOFF + ANGLE_ROUNDING <= row.truth_err
    with mp.workdps(40):
        exact_omega = max(mp.sqrt(mp.fsum((mp.mpf(float(a)) - b) ** 2 for a, b in zip(omega[i], ref_w)))
                          for i, (_, ref_w) in zip(chosen, reference))
    # likewise for omega: the reference's rounding to float64 moves it by <= u relative (measured 5.7e-16 + u = 6.8e-16
    # against a bound of 1.05e-15, 6.0e-16 without the allowance)
    assert float(exact_omega) / scale + UNIT_ROUNDOFF <= row.truth_omega_err
    # and the bound is not vacuous: the truth is good to ~1e-14 rad (measured 5.7e-15 bound, 1e-15 error here)
    assert row.truth_err < 1e-13 and row.truth_omega_err < 1e-13


def test_attitude_angle_rounding_is_within_its_stated_allowance():
    """ANGLE_ROUNDING (reference.truth) against 40-digit angles of random float64 pairs 1e-16..1e-12 rad apart."""
    rng = np.random.default_rng(2024)
    first = rng.normal(size=(3000, 4))
    first /= np.linalg.norm(first, axis=1, keepdims=True)
    second = first + rng.normal(size=first.shape) * 10.0 ** rng.uniform(-16, -12, size=(len(first), 1))
    second /= np.linalg.norm(second, axis=1, keepdims=True)
    computed = attitude_angle(quat_to_matrix(first), quat_to_matrix(second))
    with mp.workdps(40):
        worst = max(abs(computed[i] - exact_angle(first[i], _unit(second[i]))) for i in range(len(first)))
    assert 0 < worst <= ANGLE_ROUNDING / 1.5  # measured 8.9u over 2e5 pairs (6-8u over 3000); allowance 16u


@pytest.mark.skipif(np.finfo(np.longdouble).eps > 1e-18, reason="needs an extended long double (x86-64, 64 bits)")
def test_truth_err_covers_two_comparisons_at_their_worst_measured_rounding():
    """truth_err = a + the allowance, a the float64 angle between the double and the real128 truth. It must cover our
    comparison's rounding and an auditor's (each at the worst measured here: the float64 attitude_angle against the
    exact angle of 200 000 random pairs 1e-16..1e-12 rad apart, in long double), plus 2u for rounding the real128
    truth to float64 and 2u for the auditor's reference (reference.truth, above ATTITUDE_ALLOWANCE). Measured: worst
    8.8u, so the bound needs >= a + 21.6u; it has a + 36u (a halved allowance, 18u, fails)."""
    rng = np.random.default_rng(2024)
    first = rng.normal(size=(200_000, 4))
    first /= np.linalg.norm(first, axis=1, keepdims=True)
    second = first + rng.normal(size=first.shape) * 10.0 ** rng.uniform(-16, -12, size=(len(first), 1))
    second /= np.linalg.norm(second, axis=1, keepdims=True)
    computed = attitude_angle(quat_to_matrix(first), quat_to_matrix(second))
    p, q = (x.astype(np.longdouble) / np.linalg.norm(x.astype(np.longdouble), axis=1, keepdims=True)
            for x in (first, second))
    (w1, x1, y1, z1), (w2, x2, y2, z2) = p.T, q.T
    vec = np.stack([w1 * x2 - w2 * x1 - (y1 * z2 - z1 * y2), w1 * y2 - w2 * y1 - (z1 * x2 - x1 * z2),
                    w1 * z2 - w2 * z1 - (x1 * y2 - y1 * x2)])
    exact = 2 * np.arctan2(np.sqrt((vec * vec).sum(axis=0)), np.abs(w1 * w2 + x1 * x2 + y1 * y2 + z1 * z2))
    worst = float(np.max(np.abs(computed - exact)))
    assert worst > 4 * UNIT_ROUNDOFF  # the search does find rounding well above a single u
    case = find_case("free-asymmetric")
    times = np.linspace(0.0, 2.0, 11)
    double = truth(case.body, case.quat0, case.omega0, times, precision="double")
    quad = truth(case.body, case.quat0, case.omega0, times, precision="quad")
    a = float(np.max(attitude_angle(quat_to_matrix(double.quat), quat_to_matrix(quad.quat))))
    bound = truth_bound(case.body, case.quat0, case.omega0, times).attitude
    assert bound >= a + 2 * worst + 4 * UNIT_ROUNDOFF, (bound / UNIT_ROUNDOFF, a / UNIT_ROUNDOFF, worst / UNIT_ROUNDOFF)


def _unit(q: np.ndarray) -> list:
    a = [mp.mpf(float(v)) for v in q]
    norm = mp.sqrt(mp.fsum(v * v for v in a))
    return [v / norm for v in a]


SMALL = ["free-asymmetric", "lagrange-top", "hess", "self-excited-conic", "central-field-turning", "--engines",
         "mujoco,reference", "--integrators", "euler,taylor", "--t-end", "1", "--dt", "1e-2", "--jobs", "1", "--quiet"]


# slow (issue 28: the default suite within 8 min on 2 idle cores): 20-80 s at load ~6; `pytest -m slow` runs it
@pytest.mark.slow
def test_every_truth_row_is_certified_by_default_and_not_with_no_certify(tmp_path):
    assert cli.main(["run", *SMALL, "--out", str(tmp_path / "default")]) == 0
    df = pd.read_csv(tmp_path / "default" / "results.csv", dtype={"formulation": str}, keep_default_na=False)
    df = df.replace("", np.nan).astype({c: float for c in ("truth_err", "truth_omega_err")})
    truth = df[(df.engine == "reference") & (df.formulation == "quaternion") & (df.integrator == "taylor")]
    assert len(truth) == 5 and set(truth.status) == {"ok"} and set(df.engine) == {"reference", "mujoco"}
    ran = df[df.status != "skipped"]  # every run carries its case's truth bound; a skipped run has no numbers
    assert len(ran) > len(truth)
    # finite, positive, and at the truth's level (< 1e-13 on every case here; measured 5e-15..7e-14 on the suite)
    for column in ("truth_err", "truth_omega_err"):
        assert np.all(np.isfinite(ran[column])) and np.all(ran[column] > 0) and np.all(ran[column] < 1e-13), column
    assert cli.parser().parse_args(["run", "--certify"]).no_certify is False  # accepted for old scripts: a no-op
    assert cli.main(["run", *SMALL, "--no-certify", "--out", str(tmp_path / "fast")]) == 0
    fast = pd.read_csv(tmp_path / "fast" / "results.csv")
    assert fast.truth_err.isna().all() and fast.truth_omega_err.isna().all()
    assert cli.main(["run", *SMALL, "--certify", "--no-certify", "--out", str(tmp_path / "both")]) == 2


def test_resume_with_save_trajectories_redoes_only_the_runs_whose_states_are_missing(audited_run, tmp_path):
    out = tmp_path / "copy"
    shutil.copytree(audited_run, out)
    states = sorted((out / "trajectories").glob("*.npz"))
    assert len(states) == len(read_manifest(out)["runs"]) >= 2
    records = store_mtimes(out)
    rows = {name: json.loads((out / "store" / name).read_text())["row"] for name in records}
    states[0].unlink()
    argv = ["run", "free-asymmetric", "--engines", "reference", "--integrators", "taylor", "--t-end", str(T_END),
            "--jobs", "1", "--quiet", "--out", str(out), "--resume"]
    assert cli.main(argv) == 0  # without --save-trajectories the stored runs serve as they are
    assert not states[0].exists()
    assert store_mtimes(out) == records
    assert cli.main([*argv, "--save-trajectories"]) == 0
    assert states[0].exists()
    after = store_mtimes(out)
    rewritten = {name for name in records if after[name] != records[name]}
    redone = states[0].name.replace(".npz", ".json")
    assert redone in rewritten
    # any other record rewritten only gained repeats: the redone run's new single time can make another run's time
    # decide an answer (analysis.decisive), and the timing phase then times that one again
    for name in rewritten - {redone}:
        row = json.loads((out / "store" / name).read_text())["row"]
        assert rows[name].get("timing") == "single" and row.get("timing", "").startswith("best of")
        assert {k: v for k, v in row.items() if k not in TIMINGS} == {
            k: v for k, v in rows[name].items() if k not in TIMINGS}
    assert not list(out.rglob(".*.tmp"))
