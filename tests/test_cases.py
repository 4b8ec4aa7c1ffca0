"""Case files (DESIGN §3): the shipped suite parses to the exact values, and every rule rejects bad input with a
message naming the file, the key and the rule."""
from __future__ import annotations

import math
from importlib.resources import files
from pathlib import Path

import numpy as np
import pytest

from stereodyn.harness.scenes.cases import (ORACLES, CaseError, find_case, load_case, load_suite, suite_dir,
                           with_overrides)
from stereodyn.reference.exact import ORACLES as EXACT_SOLUTIONS
from stereodyn.reference.torque_models import BodyTorque, CentralField

# A valid case (a Kovalevskaya top with every optional table but [central_field]); the bad files below are edits of it.
BASE = """\
name = "base"
description = "a valid case"
tags = ["heavy-top"]

[body]
mass = 1.0
com = [0.1, 0.0, 0.0]
principal_moments = [2.0, 2.0, 1.0]

[gravity]
g = 9.81
direction = [0.0, 0.0, -1.0]

[body_torque]
axis = [0.0, 0.0, 1.0]
a = 0.6
b = -0.2

[initial]
attitude = { euler_zxz = [0.2, 1.0, 0.4] }
omega = [0.5, -0.3, 1.5]

[run]
t_end = 20.0
dt = [1e-2, 3e-3, 1e-3]
samples = 500

[expect]
horizon = 10.0
"""

# A torque-free body whose state is on the exact Euler–Poinsot motion (DESIGN §3 [expect] oracle).
FREE = """\
[body]
mass = 1.0
com = [0.0, 0.0, 0.0]
principal_moments = [2.7, 1.9, 1.1]

[initial]
attitude = { quaternion = [1.0, 0.0, 0.0, 0.0] }
omega = [1.0, 0.2, 0.3]

[run]
t_end = 5.0
dt = 0.01

[expect]
oracle = "euler_poinsot"
"""

# Issue 5's scenes (external torques, the sliding ladder) have their own spans: tests/test_torques.py, test_ladder.py.
ISSUE5 = ["central-field-fixed", "central-field-turning", "constant-torque-uniform", "generalized-precession",
          "self-excited-conic", "self-excited-spinup", "self-excited-uniform", "sliding-ladder"]
SUITE = sorted(["dzhanibekov", "euler-poinsot-major", "euler-poinsot-minor", "euler-poinsot-symmetric",
                "free-asymmetric", "goryachev-chaplygin", "grioli-precession", "heavy-asymmetric", "hess", "hess-grioli",
                "kovalevskaya", "lagrange-precession", "lagrange-top", "mlodzejowski", "separatrix",
                "sleeping-top-stable", "sleeping-top-unstable", "staude-rotation", *ISSUE5])

CENTRAL = """\
[body]
mass = 1.0
com = [0.0, 0.0, 0.0]
principal_moments = [2.0, 1.5, 1.0]

[central_field]
mu = 1.0
radius = 10.0
direction = [0.0, 0.0, 1.0]
orbit_rate = 0.1

[initial]
attitude = { quaternion = [1.0, 0.0, 0.0, 0.0] }
omega = [0.3, -0.2, 1.0]

[run]
t_end = 5.0
dt = 0.01
"""


def edit(text: str, *replacements: tuple[str, str]) -> str:
    for old, new in replacements:
        assert old in text, old   # a test whose edit silently did nothing would test nothing
        text = text.replace(old, new, 1)
    return text


def write(tmp_path: Path, text: str, name: str = "bad.toml") -> Path:
    path = tmp_path / name
    path.write_text(text, encoding="utf-8")
    return path


def rejects(path: Path, key: str, rule_part: str) -> CaseError:
    with pytest.raises(CaseError) as info:
        load_case(path)
    err = info.value
    assert (err.path, err.key) == (str(path), key), str(err)
    assert rule_part in err.rule, str(err)
    assert str(err) == f"{path}: {key}: {err.rule}"
    assert "\n" not in str(err)
    return err


def rz(a: float) -> np.ndarray:
    c, s = math.cos(a), math.sin(a)
    return np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]])


def rx(a: float) -> np.ndarray:
    c, s = math.cos(a), math.sin(a)
    return np.array([[1.0, 0.0, 0.0], [0.0, c, -s], [0.0, s, c]])


def quat_matrix(q: np.ndarray) -> np.ndarray:
    """Rotation matrix (body -> world) of a unit scalar-first quaternion."""
    w, x, y, z = q
    return np.array([[1 - 2 * (y * y + z * z), 2 * (x * y - w * z), 2 * (x * z + w * y)],
                     [2 * (x * y + w * z), 1 - 2 * (x * x + z * z), 2 * (y * z - w * x)],
                     [2 * (x * z - w * y), 2 * (y * z + w * x), 1 - 2 * (x * x + y * y)]])


# ------------------------------------------------------------------------------------------------------ the suite

def test_suite_dir_is_the_cases_package():
    assert suite_dir() == Path(str(files("stereodyn.cases")))
    assert sorted(p.name for p in suite_dir().glob("*.toml")) == sorted(f"{name}.toml" for name in SUITE)


def test_suite_loads_sorted_by_name():
    suite = load_suite()
    assert [case.name for case in suite] == SUITE
    for case in suite:
        assert case.description and case.tags
        if case.name in ISSUE5:
            continue
        assert case.t_end == 20.0 and case.samples == 1000
        assert case.path == suite_dir() / f"{case.name}.toml"
        assert abs(np.linalg.norm(case.quat0) - 1.0) < 1e-15


def test_free_asymmetric_values():
    case = find_case("free-asymmetric")
    assert case.tags == ("free", "integrable")
    assert case.mass == 1.0 and case.gravity == 0.0
    np.testing.assert_array_equal(case.inertia, np.diag([2.0, 1.5, 1.0]))
    np.testing.assert_array_equal(case.com, [0.0, 0.0, 0.0])
    np.testing.assert_array_equal(case.gravity_direction, [0.0, 0.0, -1.0])
    np.testing.assert_array_equal(case.omega0, [0.4, 0.1, 2.0])
    assert case.dt == (1e-2, 3e-3, 1e-3)
    assert case.oracle is None and case.horizon is None and case.torques == ()
    assert not case.body.has_gravity


def test_zxz_attitude_is_rz_rx_rz():
    case = find_case("free-asymmetric")
    phi, theta, psi = 0.3, 0.8, -0.5
    # by hand: q = qz(phi) qx(theta) qz(psi)
    expected = np.array([math.cos(theta / 2) * math.cos((phi + psi) / 2),
                         math.sin(theta / 2) * math.cos((phi - psi) / 2),
                         math.sin(theta / 2) * math.sin((phi - psi) / 2),
                         math.cos(theta / 2) * math.sin((phi + psi) / 2)])
    np.testing.assert_allclose(case.quat0, expected, rtol=0, atol=1e-15)
    # a few ulps of the matrix products
    np.testing.assert_allclose(quat_matrix(case.quat0), rz(phi) @ rx(theta) @ rz(psi), rtol=0, atol=2e-15)


def test_lagrange_top_values():
    case = find_case("lagrange-top")
    assert case.tags == ("heavy-top", "integrable")
    np.testing.assert_array_equal(case.inertia, np.diag([1.0, 1.0, 0.4]))
    np.testing.assert_array_equal(case.com, [0.0, 0.0, 0.2])
    assert case.gravity == 9.81
    np.testing.assert_array_equal(case.gravity_direction, [0.0, 0.0, -1.0])
    np.testing.assert_allclose(case.quat0, [math.cos(0.3), math.sin(0.3), 0.0, 0.0], rtol=0, atol=1e-16)
    np.testing.assert_array_equal(case.omega0, [0.5, 0.0, 15.0])
    assert case.dt == (1e-2, 3e-3, 1e-3)


def test_kovalevskaya_values():
    case = find_case("kovalevskaya")
    a1, a2, a3 = np.diag(case.inertia)
    assert a1 == a2 == 2 * a3 == 2.0
    np.testing.assert_array_equal(case.com, [0.1, 0.0, 0.0])
    assert case.gravity == 9.81
    np.testing.assert_allclose(quat_matrix(case.quat0), rz(0.2) @ rx(1.0) @ rz(0.4), rtol=0, atol=2e-15)
    np.testing.assert_array_equal(case.omega0, [0.5, -0.3, 1.5])


def test_heavy_asymmetric_values():
    case = find_case("heavy-asymmetric")
    assert case.tags == ("heavy-top", "chaotic")
    np.testing.assert_array_equal(case.inertia, [[2.0, 0.1, -0.05], [0.1, 1.6, 0.08], [-0.05, 0.08, 1.1]])
    np.testing.assert_array_equal(case.com, [0.1, -0.05, 0.25])
    assert case.dt == (0.3, 1e-2, 3e-3, 1e-3)
    assert case.horizon == 10.0 and case.oracle is None
    np.testing.assert_allclose(quat_matrix(case.quat0), rz(0.1) @ rx(0.7) @ rz(0.3), rtol=0, atol=2e-15)


def test_arrays_are_read_only():
    case = find_case("kovalevskaya")
    for array in (case.inertia, case.com, case.quat0, case.omega0, case.gravity_direction):
        with pytest.raises(ValueError):
            array[0] = 0.0


# ------------------------------------------------------------------------------------------- valid optional parts

def test_base_parses_every_table(tmp_path):
    case = load_case(write(tmp_path, BASE))
    assert case.name == "base" and case.description == "a valid case" and case.tags == ("heavy-top",)
    assert case.torque(BodyTorque) == BodyTorque(axis=(0.0, 0.0, 1.0), a=0.6, b=-0.2)
    assert case.oracle is None and case.horizon == 10.0 and case.samples == 500
    assert load_case(write(tmp_path, FREE, "free.toml")).oracle == "euler_poinsot"


def test_defaults(tmp_path):
    text = edit(BASE, ('name = "base"\ndescription = "a valid case"\ntags = ["heavy-top"]\n', ""),
                ("samples = 500\n", ""), ('direction = [0.0, 0.0, -1.0]\n', ""))
    case = load_case(write(tmp_path, text, "my-stem.toml"))
    assert case.name == "my-stem" and case.description == "" and case.tags == ()
    assert case.samples == 1000
    np.testing.assert_array_equal(case.gravity_direction, [0.0, 0.0, -1.0])


def test_central_field_parses(tmp_path):
    case = load_case(write(tmp_path, CENTRAL))
    assert case.torque(CentralField) == CentralField(mu=1.0, radius=10.0, direction=(0.0, 0.0, 1.0), orbit_rate=0.1)
    assert case.dt == (0.01,)   # a single number is a one-step sweep
    np.testing.assert_array_equal(case.quat0, [1.0, 0.0, 0.0, 0.0])


def test_gibbs_attitude(tmp_path):
    q = np.array([0.3, -0.4, 0.5])
    case = load_case(write(tmp_path, edit(BASE, ("{ euler_zxz = [0.2, 1.0, 0.4] }", "{ gibbs = [0.3, -0.4, 0.5] }"))))
    np.testing.assert_allclose(case.quat0, np.concatenate(([1.0], q)) / math.sqrt(1 + q @ q), rtol=0, atol=1e-16)
    skew = np.array([[0.0, -q[2], q[1]], [q[2], 0.0, -q[0]], [-q[1], q[0], 0.0]])
    expected = np.eye(3) + 2.0 / (1.0 + q @ q) * (skew + skew @ skew)   # FORMULARY F1
    np.testing.assert_allclose(quat_matrix(case.quat0), expected, rtol=0, atol=1e-15)


def test_nearly_unit_quaternion_is_normalised(tmp_path):
    w = math.cos(0.3) * (1 + 1e-11)
    text = edit(BASE, ("{ euler_zxz = [0.2, 1.0, 0.4] }", f"{{ quaternion = [{w!r}, {math.sin(0.3)!r}, 0.0, 0.0] }}"))
    case = load_case(write(tmp_path, text))
    assert abs(np.linalg.norm(case.quat0) - 1.0) < 1e-15
    np.testing.assert_allclose(case.quat0, [math.cos(0.3), math.sin(0.3), 0.0, 0.0], rtol=0, atol=1e-11)


def test_nearly_unit_direction_is_normalised(tmp_path):
    case = load_case(write(tmp_path, edit(BASE, ("direction = [0.0, 0.0, -1.0]", "direction = [0.0, 0.0, -1.0000000001]"))))
    np.testing.assert_array_equal(case.gravity_direction, [0.0, 0.0, -1.0])


def test_planar_body_allowed(tmp_path):
    # a thin plate: A3 = A1 + A2 exactly, at O = G
    text = edit(BASE, ("principal_moments = [2.0, 2.0, 1.0]", "principal_moments = [1.0, 0.5, 1.5]"),
                ("com = [0.1, 0.0, 0.0]", "com = [0.0, 0.0, 0.0]"))
    load_case(write(tmp_path, text))


def test_every_available_oracle_is_named_by_a_suite_case():
    """Every exact solution of reference.exact is a DESIGN oracle name, and the suite has a case on each (loading
    the suite checks each case's state against its oracle's conditions)."""
    assert set(EXACT_SOLUTIONS) <= set(ORACLES)
    assert {case.oracle for case in load_suite()} - {None} == set(EXACT_SOLUTIONS)


def test_an_oracle_without_an_exact_solution_is_not_available_yet(tmp_path):
    for oracle in sorted(set(ORACLES) - set(EXACT_SOLUTIONS)):  # self_excited_*: no constructor in reference.exact
        rejects(write(tmp_path, edit(FREE, ('"euler_poinsot"', f'"{oracle}"'))), "expect.oracle", "not available yet")


@pytest.mark.parametrize("edits, rule", [
    ([('"euler_poinsot"', '"grioli_precession"')], "conditions of 'grioli_precession': the body has no weight moment"),
    ([('"euler_poinsot"', '"euler_poinsot_separatrix"')], "is off the separatrix"),
    # ω0 = (0.5, 1, 0.375) is on the separatrix of (2.25, 2, 1) exactly: that motion has its own oracle
    ([("principal_moments = [2.7, 1.9, 1.1]", "principal_moments = [2.25, 2.0, 1.0]"),
      ("omega = [1.0, 0.2, 0.3]", "omega = [0.5, 1.0, 0.375]")], "that is euler_poinsot_separatrix"),
])
def test_an_oracle_whose_conditions_fail_is_an_error(tmp_path, edits, rule):
    rejects(write(tmp_path, edit(FREE, *edits)), "expect.oracle", rule)


def test_an_oracle_with_a_body_torque_is_an_error(tmp_path):
    rejects(write(tmp_path, edit(BASE, ("horizon = 10.0", 'oracle = "lagrange_precession"\nhorizon = 10.0'))),
            "expect.oracle", "no exact solution here models [body_torque]")


def test_self_excited_oracles_accept_a_body_torque_and_check_it(tmp_path):
    spun = find_case("self-excited-spinup").path.read_text()
    assert load_case(write(tmp_path, spun)).oracle == "self_excited_spinup"
    rejects(write(tmp_path, spun.replace("b = -0.2", "b = 0.2")), "expect.oracle", "a > 0 > b")


def test_precession_torque_rules(tmp_path):
    text = find_case("generalized-precession").path.read_text()
    rejects(write(tmp_path, text.replace("theta = 0.7", "theta = 3.5")), "precession_torque.theta", "(0, pi)")
    rejects(write(tmp_path, text + "[gravity]\ng = 9.81\n"), "precession_torque", "must be the only torque")


# ---------------------------------------------------------------------------------------------------- bad input

def test_missing_file(tmp_path):
    rejects(tmp_path / "nowhere.toml", "-", "file not found")


def test_invalid_toml(tmp_path):
    err = rejects(write(tmp_path, edit(BASE, ("mass = 1.0", "mass = = 1.0"))), "-", "invalid TOML: ")
    assert "line 6" in err.rule


@pytest.mark.parametrize("old, new, key", [
    ('description = "a valid case"', 'descripton = "typo"', "descripton"),
    ("mass = 1.0", "mass = 1.0\nmas = 1.0", "body.mas"),
    ("g = 9.81", "g = 9.81\ngg = 1.0", "gravity.gg"),
    ("a = 0.6", "a = 0.6\nc = 1.0", "body_torque.c"),
    ("omega = [0.5, -0.3, 1.5]", "omega = [0.5, -0.3, 1.5]\nomega_world = [0.0, 0.0, 1.0]", "initial.omega_world"),
    ("{ euler_zxz = [0.2, 1.0, 0.4] }", "{ euler_xyz = [0.2, 1.0, 0.4] }", "initial.attitude.euler_xyz"),
    ("samples = 500", "samples = 500\nrepeats = 3", "run.repeats"),
    ("horizon = 10.0", "horizon = 10.0\ntolerance = 1e-3", "expect.tolerance"),
    ("[run]", "[damping]\nc = 0.1\n\n[run]", "damping"),
])
def test_unknown_key(tmp_path, old, new, key):
    rejects(write(tmp_path, edit(BASE, (old, new))), key, "unknown key")


def test_unknown_key_in_central_field(tmp_path):
    rejects(write(tmp_path, edit(CENTRAL, ("mu = 1.0", "mu = 1.0\nJ2 = 0.001"))), "central_field.J2", "unknown key")


@pytest.mark.parametrize("old, key", [
    ("mass = 1.0\n", "body.mass"),
    ("com = [0.1, 0.0, 0.0]\n", "body.com"),
    ("g = 9.81\n", "gravity.g"),
    ("b = -0.2\n", "body_torque.b"),
    ("omega = [0.5, -0.3, 1.5]\n", "initial.omega"),
    ("t_end = 20.0\n", "run.t_end"),
    ("dt = [1e-2, 3e-3, 1e-3]\n", "run.dt"),
])
def test_missing_required_key(tmp_path, old, key):
    rejects(write(tmp_path, edit(BASE, (old, ""))), key, "required key missing")


def test_missing_required_table(tmp_path):
    text = edit(BASE, ("[initial]\nattitude = { euler_zxz = [0.2, 1.0, 0.4] }\nomega = [0.5, -0.3, 1.5]\n", ""))
    rejects(write(tmp_path, text), "initial", "required key missing")


def test_missing_inertia(tmp_path):
    rejects(write(tmp_path, edit(BASE, ("principal_moments = [2.0, 2.0, 1.0]\n", ""))), "body.inertia", "exactly one of")


def test_both_inertia_and_principal_moments(tmp_path):
    text = edit(BASE, ("principal_moments = [2.0, 2.0, 1.0]",
                       "principal_moments = [2.0, 2.0, 1.0]\ninertia = [[2.0, 0.0, 0.0], [0.0, 2.0, 0.0], [0.0, 0.0, 1.0]]"))
    rejects(write(tmp_path, text), "body.inertia", "not both")


def test_inertia_not_symmetric(tmp_path):
    text = edit(BASE, ("principal_moments = [2.0, 2.0, 1.0]",
                       "inertia = [[2.0, 0.1, 0.0], [0.1000001, 2.0, 0.0], [0.0, 0.0, 1.0]]"))
    rejects(write(tmp_path, text), "body.inertia", "inertia must be symmetric")


def test_inertia_not_positive_definite(tmp_path):
    # symmetric, but eigenvalues 2.5, 1.5, ... with a negative one from the large off-diagonal entry
    text = edit(BASE, ("principal_moments = [2.0, 2.0, 1.0]",
                       "inertia = [[1.0, 1.5, 0.0], [1.5, 1.0, 0.0], [0.0, 0.0, 1.0]]"))
    rejects(write(tmp_path, text), "body.inertia", "inertia must be positive definite")


def test_principal_moment_not_positive(tmp_path):
    text = edit(BASE, ("principal_moments = [2.0, 2.0, 1.0]", "principal_moments = [2.0, 0.0, 1.0]"))
    rejects(write(tmp_path, text), "body.principal_moments[1]", "must be > 0")


def test_triangle_inequality_broken_at_o(tmp_path):
    text = edit(BASE, ("principal_moments = [2.0, 2.0, 1.0]", "principal_moments = [1.0, 1.0, 2.5]"))
    rejects(write(tmp_path, text), "body.principal_moments", "inertia about O must satisfy the triangle inequality")


def test_triangle_inequality_broken_at_centre_of_mass_only(tmp_path):
    moments_o, mass, com = np.array([1.0, 1.0, 1.9]), 1.0, np.array([0.0, 0.0, 0.5])
    moments_g = np.linalg.eigvalsh(np.diag(moments_o) - mass * (com @ com * np.eye(3) - np.outer(com, com)))
    # the premise: fine about O, broken about G (A1 + A2 = 1.5 < A3 = 1.9)
    assert moments_o[0] + moments_o[1] >= moments_o[2]
    assert moments_g[0] + moments_g[1] < moments_g[2]
    text = edit(BASE, ("principal_moments = [2.0, 2.0, 1.0]", "principal_moments = [1.0, 1.0, 1.9]"),
                ("com = [0.1, 0.0, 0.0]", "com = [0.0, 0.0, 0.5]"))
    err = rejects(write(tmp_path, text), "body.principal_moments",
                  "inertia about the centre of mass (Huygens–Steiner with body.mass and body.com) must satisfy "
                  "the triangle inequality")
    assert "about O" not in err.rule


def test_quaternion_not_unit(tmp_path):
    text = edit(BASE, ("{ euler_zxz = [0.2, 1.0, 0.4] }", "{ quaternion = [1.001, 0.0, 0.0, 0.0] }"))
    err = rejects(write(tmp_path, text), "initial.attitude.quaternion", "quaternion must have unit length (|q| = 1.001")


def test_two_attitude_charts(tmp_path):
    text = edit(BASE, ("{ euler_zxz = [0.2, 1.0, 0.4] }", "{ euler_zxz = [0.2, 1.0, 0.4], gibbs = [0.0, 0.0, 0.0] }"))
    rejects(write(tmp_path, text), "initial.attitude", "exactly one of quaternion, euler_zxz or gibbs")


def test_direction_not_unit(tmp_path):
    rejects(write(tmp_path, edit(BASE, ("direction = [0.0, 0.0, -1.0]", "direction = [0.0, 0.0, -9.81]"))),
            "gravity.direction", "direction must have unit length")
    rejects(write(tmp_path, edit(BASE, ("axis = [0.0, 0.0, 1.0]", "axis = [0.0, 1.0, 1.0]"))),
            "body_torque.axis", "axis must have unit length")


def test_wrong_length_vector(tmp_path):
    rejects(write(tmp_path, edit(BASE, ("com = [0.1, 0.0, 0.0]", "com = [0.1, 0.0]"))), "body.com",
            "must be a list of 3 numbers")


@pytest.mark.parametrize("dt, key, rule", [
    ("0.0", "run.dt", "must be > 0"),
    ("[1e-2, -1e-3]", "run.dt[1]", "must be > 0"),
    ("[1e-2, 0.0]", "run.dt[1]", "must be > 0"),
    ("[1e-2, 25.0]", "run.dt[1]", "dt must be <= t_end (25 > 20)"),
    ("[]", "run.dt", "must not be empty"),
])
def test_bad_dt(tmp_path, dt, key, rule):
    rejects(write(tmp_path, edit(BASE, ("dt = [1e-2, 3e-3, 1e-3]", f"dt = {dt}"))), key, rule)


def test_bad_t_end(tmp_path):
    rejects(write(tmp_path, edit(BASE, ("t_end = 20.0", "t_end = -1.0"))), "run.t_end", "must be > 0")


@pytest.mark.parametrize("samples, rule", [("1", "must be >= 2"), ("1000.0", "must be an integer"),
                                           ("true", "must be an integer")])
def test_bad_samples(tmp_path, samples, rule):
    rejects(write(tmp_path, edit(BASE, ("samples = 500", f"samples = {samples}"))), "run.samples", rule)


@pytest.mark.parametrize("old, new, key", [
    ("mass = 1.0", "mass = inf", "body.mass"),
    ("com = [0.1, 0.0, 0.0]", "com = [0.1, nan, 0.0]", "body.com[1]"),
    ("a = 0.6", "a = -inf", "body_torque.a"),
    ("omega = [0.5, -0.3, 1.5]", "omega = [0.5, -0.3, 1e400]", "initial.omega[2]"),
])
def test_non_finite_number(tmp_path, old, new, key):
    rejects(write(tmp_path, edit(BASE, (old, new))), key, "must be finite")


@pytest.mark.parametrize("old, new, key", [
    ("mass = 1.0", 'mass = "1.0"', "body.mass"),
    ("g = 9.81", "g = true", "gravity.g"),
    ("dt = [1e-2, 3e-3, 1e-3]", 'dt = [1e-2, "3e-3"]', "run.dt[1]"),
    ("principal_moments = [2.0, 2.0, 1.0]", 'principal_moments = [2.0, "2.0", 1.0]', "body.principal_moments[1]"),
])
def test_not_a_number(tmp_path, old, new, key):
    rejects(write(tmp_path, edit(BASE, (old, new))), key, "must be a number")


def test_unknown_oracle(tmp_path):
    rejects(write(tmp_path, edit(BASE, ("horizon = 10.0", 'oracle = "euler_poisson"\nhorizon = 10.0'))),
            "expect.oracle", "unknown oracle 'euler_poisson'")


def test_horizon_beyond_t_end(tmp_path):
    rejects(write(tmp_path, edit(BASE, ("horizon = 10.0", "horizon = 30.0"))), "expect.horizon", "must be <= run.t_end")


def test_negative_gravity(tmp_path):
    rejects(write(tmp_path, edit(BASE, ("g = 9.81", "g = -9.81"))), "gravity.g", "must be >= 0")


def test_central_field_needs_com_at_o(tmp_path):
    text = edit(CENTRAL, ("com = [0.0, 0.0, 0.0]", "com = [0.0, 0.0, 0.1]"))
    rejects(write(tmp_path, text), "body.com", "O is the centre of mass")


def test_central_field_radius_positive(tmp_path):
    rejects(write(tmp_path, edit(CENTRAL, ("radius = 10.0", "radius = 0.0"))), "central_field.radius", "must be > 0")


def test_tags_must_be_strings(tmp_path):
    rejects(write(tmp_path, edit(BASE, ('tags = ["heavy-top"]', 'tags = ["heavy-top", 3]'))), "tags[1]",
            "must be a string")


def test_a_case_name_shows_as_itself_in_markdown(tmp_path):
    """Issue 46's eleventh attack, F3: a case named ev|il`x`<b>h&amp; (its file's stem) opened a code span and bold
    for the rest of report.md, whose headings and cells escaped only bars: a name holds no Markdown markup. A plain
    name with spaces, dots, dashes, underscores and parentheses loads. Break-checked: without the rule it loads."""
    rejects(write(tmp_path, edit(BASE, ('name = "base"', 'name = "ev|il`x`<b>h&amp;"'))), "name",
            "must hold none of")
    rejects(write(tmp_path, edit(BASE, ('name = "base"\n', '')), "a*b.toml"), "name", "it holds *")
    # an underscore at a word's start or end is emphasis ("_x_" showed as an italic x: the twelfth attack)
    rejects(write(tmp_path, edit(BASE, ('name = "base"\n', '')), "_x_.toml"), "name", "it holds _")
    assert load_case(write(tmp_path, edit(BASE, ('name = "base"', 'name = "my top_2 (v1.5) +x -y"')))).name \
        == "my top_2 (v1.5) +x -y"


# ----------------------------------------------------------------------------------------- suite-level helpers

def test_duplicate_names_name_both_files(tmp_path):
    first = write(tmp_path, BASE, "a.toml")
    second = write(tmp_path, BASE, "b.toml")
    with pytest.raises(CaseError) as info:
        load_suite(tmp_path)
    assert info.value.path == str(second) and info.value.key == "name"
    assert "'base'" in info.value.rule and str(first) in info.value.rule


def test_find_case_by_path_and_unknown_name(tmp_path):
    path = write(tmp_path, BASE, "mine.toml")
    assert find_case(str(path)).name == "base"
    with pytest.raises(CaseError) as info:
        find_case("kovalevsky", load_suite())
    assert info.value.key == "kovalevsky"
    assert f"available: {', '.join(SUITE)}" in info.value.rule
    with pytest.raises(CaseError, match="file not found"):
        find_case(str(tmp_path / "missing.toml"))


def test_with_overrides():
    case = find_case("heavy-asymmetric")
    short = with_overrides(case, t_end=5.0, dt=[1e-2, 1e-3])
    assert (short.t_end, short.dt, short.horizon) == (5.0, (1e-2, 1e-3), 5.0)   # horizon clipped to t_end
    assert (case.t_end, case.horizon) == (20.0, 10.0)                            # the original is untouched
    assert with_overrides(case, dt=0.005).dt == (0.005,)
    assert with_overrides(case, t_end=15.0).horizon == 10.0
    with pytest.raises(CaseError) as info:
        with_overrides(case, t_end=0.01)   # the case's own dt = 0.02 no longer fits
    assert (info.value.key, info.value.path) == ("run.dt[0]", str(case.path))
    with pytest.raises(CaseError, match=r"run\.dt\[1\]: must be > 0"):
        with_overrides(case, dt=[1e-2, 0.0])
    with pytest.raises(CaseError, match=r"run\.t_end: must be finite"):
        with_overrides(case, t_end=math.inf)


def test_attitudes_agree_with_reference_rotations(tmp_path):
    from stereodyn.reference import rotations  # the loader does not depend on it: an independent check
    for case in load_suite():
        if case.kind != "rigid_body":
            continue
        np.testing.assert_allclose(rotations.quat_to_matrix(case.quat0), quat_matrix(case.quat0), rtol=0, atol=1e-15)
    np.testing.assert_allclose(find_case("kovalevskaya").quat0 @ rotations.matrix_to_quat(
        rotations.zxz_to_matrix(0.2, 1.0, 0.4)), 1.0, rtol=0, atol=1e-15)
    case = load_case(write(tmp_path, edit(BASE, ("{ euler_zxz = [0.2, 1.0, 0.4] }", "{ gibbs = [0.3, -0.4, 0.5] }"))))
    np.testing.assert_allclose(case.quat0, rotations.gibbs_to_quat(np.array([0.3, -0.4, 0.5])), rtol=0, atol=1e-16)
