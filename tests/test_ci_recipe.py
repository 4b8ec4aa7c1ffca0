"""docs/CI.md's recipe, end to end: docs/ci/stereodyn-gate.sh on a toy plug-in integrator whose pull request changes
one coefficient of its tableau (Heun's b = (1/2, 1/2) to (0.6, 0.4): order 2 to 1). The gate fails, JUnit counts the
failures, and the pull-request summary names the plug-in's new source hash, signs the changed metrics and lists the
fallen orders, in at most 60 lines and no image. Each sweep: one case, two steps, one engine."""
import json
import os
import re
import subprocess
import sys
from pathlib import Path
from xml.etree import ElementTree

import pytest

import plugin_packages


REPO = Path(__file__).resolve().parents[1]
SCRIPT = REPO / "docs" / "ci" / "stereodyn-gate.sh"
PACKAGE = "stereodyn_gate_toy"

MODULE = '''
"""Heun's method, as a plug-in: on the group and on a formulation's coordinates."""
from stereodyn.harness.integrators import ButcherTableau, ExplicitRK, VectorRK

HEUN = ButcherTableau(a=((0.0, 0.0), (1.0, 0.0)), b=B, c=(0.0, 1.0))

class HeunGate(ExplicitRK):
    name, order, tableau, description = "heun_gate", 2, HEUN, "Heun's method, the CI recipe's toy plug-in"

class HeunGateVector(VectorRK):
    name, order, tableau, description = "heun_gate", 2, HEUN, "Heun's method, the CI recipe's toy plug-in"

INTEGRATORS = (HeunGate, HeunGateVector)
'''
# Pinocchio runs the plug-in on the group, in one model: two rows a run (~9 s of CPU each, most of it imports and the
# report's figures; the reference engine's formulations would be 8 rows)
SWEEP = ("lagrange-top --t-end 1 --dt 1e-2,5e-3 --engines pinocchio --integrators heun_gate --jobs 1 --no-ladder "
         "--no-certify")


def _source(root: Path, b: str) -> Path:
    """The plug-in's source tree with Heun's weights b (a Python tuple's text)."""
    files = {"pyproject.toml": plugin_packages.pyproject(PACKAGE, {"stereodyn.integrators":
                                                                   {"heun_gate": f"{PACKAGE}:INTEGRATORS"}}),
             f"{PACKAGE}/__init__.py": f"B = {b}\n" + MODULE, "zip_backend.py": plugin_packages.ZIP_BACKEND}
    for path, text in files.items():
        (root / path).parent.mkdir(parents=True, exist_ok=True)
        (root / path).write_text(text)
    return root


@pytest.mark.slow  # since 2026-12-02, ~50 s: the whole shell recipe; by default test_ci_output.py and test_ci_truth.py check check's outputs (the default suite's 8 minutes)
def test_the_shell_recipe_gates_a_plugin_integrator_and_writes_the_pull_request_summary(tmp_path):
    base, head = _source(tmp_path / "base", "(0.5, 0.5)"), _source(tmp_path / "head", "(0.6, 0.4)")
    site, out, summary = tmp_path / "site", tmp_path / "gate", tmp_path / "step-summary.md"
    env = {**plugin_packages.env_with(site), "STEREODYN_GATE_SWEEP": SWEEP, "GITHUB_STEP_SUMMARY": str(summary),
           "PATH": os.pathsep.join([str(Path(sys.executable).parent), os.environ["PATH"]]),
           # pip into a folder on PYTHONPATH (the venv is not touched), replacing the base's copy by the head's
           "STEREODYN_GATE_INSTALL": f"{sys.executable} -m pip install --quiet --no-build-isolation --no-deps "
                                     f"--upgrade --target {site}"}
    result = subprocess.run(["bash", str(SCRIPT), str(base), str(head), str(out)], capture_output=True, text=True,
                            env=env, cwd=tmp_path, timeout=600)
    assert result.returncode == 1, result.stdout[-3000:] + result.stderr[-3000:]  # check's status: worse
    printed = result.stdout
    assert "gate: same-machine mode (the baseline's)" in printed
    failed = int(re.search(r"check failed: (\d+) of (\d+) baseline rows got worse", printed).group(1))
    fell = int(re.search(r"(\d+) of \d+ fitted orders fell", printed).group(1))
    suite = ElementTree.parse(out / "junit.xml").getroot().find("testsuite")
    assert failed >= 2 and fell >= 1 and int(suite.get("failures")) == failed + fell
    pr = (out / "pr.md").read_text()
    lines = pr.splitlines()
    assert len(lines) <= 60 and "![" not in pr and "](" not in pr, pr
    # the plug-in's source hash as runs.json records it (code.integrators), cut to 12 digits, A then B
    recorded = [json.loads((out / run / "runs.json").read_text())["code"]["integrators"]["heun_gate"][0]["source"]
                for run in ("base", "head")]
    env_row = next(line for line in lines if line.startswith("| plug-in integrator heun_gate |"))
    shown = [cell.split("source ")[1].rstrip("…") for cell in env_row.strip("| ").split(" | ")[1:3]]
    assert recorded[0] != recorded[1] and shown == [h[:12] for h in recorded], env_row
    assert "**" in lines[0] and " for the worse**" in lines[0]
    signed = [line for line in lines if line.startswith("| attitude_err |")]
    assert signed and " worse | " in signed[0], pr  # the error grew: signed worse, not just "changed"
    assert any(line.startswith("| lagrange-top pinocchio") and "heun_gate" in line and line.endswith("| worse |")
               for line in lines if line.count("|") == 6), pr  # the fallen order: family, declared, A, B, worse
    step = summary.read_text()
    assert step.startswith("### stereodyn check failed") and lines[0] in step  # check's summary, then pr.md

