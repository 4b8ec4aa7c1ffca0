"""One discovery mechanism (issue 29, reference/registry.py): each registry's built-ins are a table in code, its
plug-ins an entry-point group, and a member that does not load is one line naming it while everything else works."""
import ast
import shutil
import subprocess
import sys
from pathlib import Path

import plugin_packages
import pytest

from stereodyn.harness import cli, scenes
from stereodyn.harness.report import sections
from stereodyn.reference import registry, torque_models

ROOT = Path(__file__).resolve().parents[1]
BROKEN = "stereodyn_broken_members"
BROKEN_DIST = "stereodyn-broken-members 0.1.0"


def _registers_a_section(path: Path) -> bool:
    """Whether the module calls sections.register(...) (as a decorator or a call)."""
    return any(isinstance(node, ast.Call) and isinstance(node.func, ast.Attribute) and node.func.attr == "register"
               and isinstance(node.func.value, ast.Name) and node.func.value.id == "sections"
               for node in ast.walk(ast.parse(path.read_text())))


def test_every_module_that_registers_a_section_is_in_the_built_in_table():
    """A section module left out of the table would silently never render (its import line in build.py was the
    table before; forgetting it lost the section)."""
    registering = {f"stereodyn.harness.report.{path.stem}" for path in (ROOT / "harness" / "report").glob("*.py")
                   if _registers_a_section(path)}
    assert len(registering) >= 6  # markdown, build, verdicts, workprecision, agreement, method, history: 7 today
    assert registering == set(sections.BUILT_IN)
    names = [section.name for section in sections.registered()]
    assert {"cases", "history", "cross-engine-agreement", "verdicts"} <= set(names)


def test_the_built_in_scenes_and_torque_models_come_from_their_tables():
    assert scenes.SCENES.builtins == ("stereodyn.harness.scenes.rigid_body", "stereodyn.harness.scenes.sliding_ladder")
    assert scenes.kinds()[:2] == ("rigid_body", "sliding_ladder")
    modules = {path.stem for path in (ROOT / "reference" / "torque_models").glob("*.py")} - {"__init__"}
    assert {module.rsplit(".", 1)[1] for module in torque_models.BUILT_IN} == modules
    assert [model.key for model in torque_models.models()][:3] == ["body_torque", "central_field",
                                                                   "precession_torque"]


def test_a_registry_names_each_failure_and_loads_the_rest(monkeypatch, tmp_path):
    (tmp_path / "good_member.py").write_text("LOADED = True\n")
    (tmp_path / "bad_member.py").write_text("raise ValueError('broken on purpose')\n")
    monkeypatch.syspath_prepend(str(tmp_path))
    from importlib.metadata import EntryPoint
    entries = [EntryPoint("bad", "bad_member", "g"), EntryPoint("good", "good_member", "g")]
    monkeypatch.setattr(registry, "entry_points", lambda group: entries if group == "g" else [])
    accepted = []
    members = registry.Registry("toy plug-in", "g", accept=lambda name, obj: accepted.append((name, obj.LOADED)))
    try:
        assert members.load() == {"bad": "toy plug-in 'bad' (bad_member) does not load: ValueError: broken on "
                                         "purpose"}
        assert accepted == [("good", True)]
        assert members.load() is members.failed and accepted == [("good", True)]  # once per process
    finally:
        sys.modules.pop("good_member", None)
        sys.modules.pop("bad_member", None)


SCENE_PLUGIN = '''
from stereodyn.harness import scenes


class Scene:
    kind, title, needs_truth, keeps_states, work_precision, columns = "toy_plugin_scene", "a toy", False, False, False, ()

    def parse(self, parser, data):  # a scene defines its three hooks (scenes.register refuses one without them)
        return None

    def truth(self, case, grids, certify):
        return None

    def metrics(self, run, model, traj, grid, truth, full, rerun, keep_states=False):
        return {}


scenes.register(Scene())
'''


def test_a_scene_of_another_distribution_is_found_through_its_entry_point(monkeypatch, tmp_path, recwarn):
    """The scenes' group: a module that registers its scene on import is loaded when the kinds are read; one that
    raises is one warning line naming it, and the built-in scenes stay."""
    from importlib.metadata import EntryPoint

    from stereodyn.harness.scenes import base
    (tmp_path / "toy_scene_plugin.py").write_text(SCENE_PLUGIN)
    (tmp_path / "broken_scene_plugin.py").write_text("raise RuntimeError('scene broken on purpose')\n")
    monkeypatch.syspath_prepend(str(tmp_path))
    entries = [EntryPoint("toy", "toy_scene_plugin", base.ENTRY_POINT_GROUP),
               EntryPoint("broken", "broken_scene_plugin", base.ENTRY_POINT_GROUP)]
    monkeypatch.setattr(registry, "entry_points", lambda group: entries if group == base.ENTRY_POINT_GROUP else [])
    monkeypatch.setattr(base, "SCENES", registry.Registry(base.SCENES.what, base.ENTRY_POINT_GROUP,
                                                          base.SCENES.builtins))
    monkeypatch.setattr(base, "_SCENES", dict(base._SCENES))
    try:
        assert scenes.kinds() == ("rigid_body", "sliding_ladder", "toy_plugin_scene")
        assert scenes.scene("toy_plugin_scene").title == "a toy"
        lines = [str(w.message) for w in recwarn.list]
        assert lines == ["scene plug-in 'broken' (broken_scene_plugin) does not load: RuntimeError: scene broken on "
                         "purpose"]
    finally:
        sys.modules.pop("toy_scene_plugin", None)
        sys.modules.pop("broken_scene_plugin", None)


@pytest.fixture(scope="module")
def broken(tmp_path_factory) -> Path:
    """One distribution whose engine and report section raise at import."""
    return plugin_packages.install(tmp_path_factory.mktemp("broken_members"), {
        "pyproject.toml": plugin_packages.pyproject(BROKEN, {
            "stereodyn.engines": {"broken_engine": f"{BROKEN}.engine:Broken"},
            sections.ENTRY_POINT_GROUP: {"broken_section": f"{BROKEN}.section"}}),
        f"{BROKEN}/__init__.py": "",
        f"{BROKEN}/engine.py": "raise RuntimeError('engine broken on purpose')\n",
        f"{BROKEN}/section.py": "raise RuntimeError('section broken on purpose')\n"})


def _run(site: Path, *argv: str, cwd: Path) -> subprocess.CompletedProcess:
    return subprocess.run([sys.executable, "-m", "stereodyn", *argv], capture_output=True, text=True,
                          env=plugin_packages.env_with(site), cwd=cwd)


@pytest.mark.slow  # ~13 s of CPU (two subprocesses that import stereodyn, one renders a report); the default suite
# keeps the report half in test_report_sections.py and the engine half (a plug-in exiting at import) in
# test_engine_plugins.py
def test_plugins_that_raise_at_import_are_one_line_each_and_the_rest_works(broken, tmp_path):
    listing = _run(broken, "engines", cwd=tmp_path)
    assert listing.returncode == 0 and "Traceback" not in listing.stderr, listing.stderr[-3000:]
    assert "mujoco: built in; installed" in listing.stdout and "reference: built in; installed" in listing.stdout
    assert [line for line in listing.stdout.splitlines() if "broken_engine" in line] == [
        f"broken_engine: plug-in from {BROKEN_DIST}; not usable: engine plug-in 'broken_engine' "
        f"({BROKEN}.engine:Broken, distribution {BROKEN_DIST}) does not load: RuntimeError: engine broken on purpose"]
    out = tmp_path / "out"
    assert cli.main(["run", "free-asymmetric", "--engines", "reference", "--integrators", "rk4", "--t-end", "0.2",
                     "--dt", "1e-2", "--no-ladder", "--no-certify", "--jobs", "1", "--quiet", "--out", str(out)]) == 0
    copy = tmp_path / "copy"
    shutil.copytree(out, copy)
    report = _run(broken, "report", str(copy), cwd=tmp_path)
    assert report.returncode == 0, report.stderr[-3000:]
    assert report.stderr.splitlines() == [
        f"stereodyn: warning: report section plug-in 'broken_section' ({BROKEN}.section, distribution {BROKEN_DIST}) "
        "does not load: RuntimeError: section broken on purpose"]
    text = (copy / "report.md").read_text()
    assert "## Cases" in text and "### free-asymmetric" in text and "## Environment" in text
