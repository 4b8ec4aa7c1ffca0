"""A thin disk is a body (issue 45 item 6): principal moments about its centre of mass mr^2/4, mr^2/4, mr^2/2, exactly
A + B = C. MuJoCo's compiler diagonalises the rotated inertia itself and checks A + B >= C without tolerance, so about
half of the disk's orientations round below the equality and are refused; the adapter then raises the principal
moments by the fewest ulps MuJoCo accepts (harness.engines.mujoco.compiled), says so in the row, and the run is judged
against the truth of the unchanged disk."""
from __future__ import annotations

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from stereodyn.harness.engines import get_engine
from stereodyn.harness.engines import mujoco as mujoco_engine
from stereodyn.harness.grid import time_grid
from stereodyn.harness.scenes.cases import find_case
from stereodyn.reference import truth as reference_truth
from stereodyn.reference.rotations import attitude_angle, quat_to_matrix

from helpers import case_file

MASS, RADIUS, COM = 1.0, 0.3, np.array([0.0, 0.0, 0.15])
# Orientations of the disk's principal axes (scipy's Rotation.random seeds): MuJoCo 4.0.0 refuses 7 of the first 12
# as they are (3, 5, 6, 7, 9, 10, 11) and accepts every one raised by 1 ulp; these two it refuses.
REFUSED_SEEDS = (3, 7)


def disk_case(folder, seed: int):
    axes = Rotation.random(random_state=seed).as_matrix()
    about_com = axes @ np.diag([MASS * RADIUS**2 / 4, MASS * RADIUS**2 / 4, MASS * RADIUS**2 / 2]) @ axes.T
    about_o = about_com + MASS * (COM @ COM * np.eye(3) - np.outer(COM, COM))  # Huygens-Steiner (FORMULARY T2)
    rows = ", ".join("[" + ", ".join(repr(float(x)) for x in row) + "]" for row in about_o)
    text = (f'description = "thin disk, principal axes turned (seed {seed})"\ntags = ["heavy-top"]\n'
            f"[body]\nmass = {MASS!r}\ncom = [{', '.join(repr(float(x)) for x in COM)}]\ninertia = [{rows}]\n"
            '[gravity]\ng = 9.81\ndirection = [0.0, 0.0, -1.0]\n'
            "[initial]\nattitude = { euler_zxz = [0.1, 0.7, 0.3] }\nomega = [1.0, -0.5, 4.0]\n"
            "[run]\nt_end = 2.0\ndt = [1e-2, 5e-3]\nsamples = 201\n")
    return find_case(case_file(folder, text, f"disk-{seed}.toml"))


@pytest.mark.parametrize("seed", REFUSED_SEEDS)
def test_mujoco_takes_a_thin_disk_with_the_smallest_change_it_accepts(tmp_path, seed):
    import mujoco

    case = disk_case(tmp_path, seed)
    with pytest.raises(ValueError, match="A \\+ B >= C"):  # the disk as it is: refused (what the row used to say)
        mujoco.MjModel.from_xml_string(mujoco_engine.scene(case, "rk4", 5e-3))
    _, model, note = mujoco_engine.compiled(case, "rk4", 5e-3)
    largest = float(np.linalg.eigvalsh(case.body.inertia_com)[-1])
    raised = float(np.sort(model.body_inertia[1])[-1]) - largest
    # a change of a few ulps (1 measured), far below any error a row reports
    assert 0.0 < raised <= mujoco_engine.LAMINA_MAX_ULPS * np.finfo(float).eps * largest * 4
    assert "raised by" in note and "lamina" in note and "ulp" in note

    grid = time_grid(2.0, 5e-3, 2)
    run = get_engine("mujoco").prepare(case, "rk4", 5e-3).run(grid)
    assert run.status.value == "ok" and run.message == note  # the row states the change
    # judged against the truth of the unchanged disk: as close as Pinocchio's RK4 on the disk itself (measured:
    # both 1.59e-7 at dt 5e-3, equal to 7 digits), and the two agree far below either's error
    truth = reference_truth.truth(case.body, case.quat0, case.omega0, np.array([0.0, 2.0])).quat[-1]
    pinocchio = get_engine("pinocchio").prepare(case, "rk4", 5e-3).run(grid)
    error = attitude_angle(quat_to_matrix(run.quat[-1:]), quat_to_matrix(truth[None]))[0]
    between = attitude_angle(quat_to_matrix(run.quat[-1:]), quat_to_matrix(pinocchio.quat[-1:]))[0]
    assert error < 1e-6 and between < 1e-3 * error, (error, between)


def test_a_body_mujoco_accepts_is_unchanged(tmp_path):
    case = disk_case(tmp_path, 0)  # accepted as it is (measured)
    xml, _, note = mujoco_engine.compiled(case, "rk4", 5e-3)
    assert note == "" and xml == mujoco_engine.scene(case, "rk4", 5e-3)


def test_a_refusal_the_raise_cannot_lift_is_named(tmp_path, monkeypatch):
    case = disk_case(tmp_path, REFUSED_SEEDS[0])
    monkeypatch.setattr(mujoco_engine, "LAMINA_MAX_ULPS", 0)  # no raise allowed: MuJoCo cannot represent it
    with pytest.raises(ValueError, match="MuJoCo cannot represent this lamina"):
        mujoco_engine.compiled(case, "rk4", 5e-3)
