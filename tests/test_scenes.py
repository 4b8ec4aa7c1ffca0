"""Scenes behind a seam (issue 20): the plan, the one run -> row path, the sweep and the engines never branch on a
scene kind; a scene's differences are done by its Scene object (harness.scenes) and each engine's model of it
(Engine.models())."""
import ast
from pathlib import Path

import pytest

from stereodyn.harness import scenes
from stereodyn.harness.engines import get_engine
from stereodyn.harness.engines.base import Engine, SceneModel
from stereodyn.harness.scenes import cases

ROOT = Path(__file__).resolve().parents[1]
HARNESS = ROOT / "harness"
# Where a kind may be compared and a case type tested: the scenes themselves.
SCENE_MODULES = HARNESS / "scenes"
CASE_TYPES = {"Case", "LadderCase"}
PARAMETER_KINDS = {"POSITIONAL_ONLY", "POSITIONAL_OR_KEYWORD", "VAR_POSITIONAL", "KEYWORD_ONLY", "VAR_KEYWORD"}


def kind_branches(source: str) -> list[str]:
    """Every comparison with a `.kind` attribute or a scene kind (a registered kind's literal, RIGID_BODY,
    SLIDING_LADDER), and every isinstance test on a case type, in a module's source: 'line: text'."""
    tree = ast.parse(source)
    kind_names = {"RIGID_BODY", "SLIDING_LADDER"}
    found = []

    def is_kind(node: ast.AST) -> bool:
        return (isinstance(node, ast.Attribute) and node.attr == "kind") or \
            (isinstance(node, ast.Name) and node.id in kind_names) or \
            (isinstance(node, ast.Constant) and node.value in scenes.kinds())

    def is_parameter_kind(node: ast.AST) -> bool:  # inspect.Parameter.kind, compared with its constants
        if isinstance(node, ast.Tuple):
            return any(is_parameter_kind(n) for n in node.elts)
        return isinstance(node, ast.Attribute) and node.attr in PARAMETER_KINDS

    for node in ast.walk(tree):
        operands = [node.left, *node.comparators] if isinstance(node, ast.Compare) else []
        if any(is_kind(n) for n in operands) and not any(is_parameter_kind(n) for n in operands):
            found.append(f"{node.lineno}: {ast.unparse(node)}")
        if isinstance(node, ast.Call) and isinstance(node.func, ast.Name) and node.func.id == "isinstance" \
                and len(node.args) == 2:
            types = node.args[1].elts if isinstance(node.args[1], ast.Tuple) else [node.args[1]]
            if any(isinstance(t, (ast.Name, ast.Attribute)) and (getattr(t, "id", None) or t.attr) in CASE_TYPES
                   for t in types):
                found.append(f"{node.lineno}: {ast.unparse(node)}")
    return found


def test_no_branch_on_a_scene_kind_outside_the_scene_modules():
    offenders = {}
    for path in sorted(HARNESS.rglob("*.py")):
        if SCENE_MODULES in path.parents:
            continue
        found = kind_branches(path.read_text())
        if found:
            offenders[str(path.relative_to(ROOT))] = found
    assert offenders == {}


def test_the_grep_finds_each_form_of_branch():
    # break-check of the test above: each form it must catch, and what it must let through
    assert kind_branches("if case.kind == SLIDING_LADDER:\n    pass\n")
    assert kind_branches("x = spec.case.kind != 'rigid_body'\n")
    assert kind_branches("x = RIGID_BODY == k\n")
    assert kind_branches("x = 'sliding_ladder' in kinds\n")
    assert kind_branches("x = isinstance(c, Case)\n")
    assert kind_branches("x = isinstance(c, (str, cases.LadderCase))\n")
    assert not kind_branches("x = scene_of(c).work_precision\nm = models.get(scene.kind)\n")
    assert not kind_branches("x = self.variant == 'bilateral'\ny = isinstance(p, Path)\n")
    assert not kind_branches("x = p.kind is p.VAR_POSITIONAL\ny = p.kind in (p.POSITIONAL_ONLY, p.KEYWORD_ONLY)\n")


def test_the_built_in_scenes_are_registered():
    assert scenes.kinds()[:2] == ("rigid_body", "sliding_ladder")
    assert scenes.scene_of(cases.find_case("sliding-ladder")).title == "the sliding ladder"
    assert scenes.scene_of(cases.find_case("free-asymmetric")).work_precision


def test_an_unknown_kind_names_the_known_ones(tmp_path):
    path = tmp_path / "x.toml"
    path.write_text('kind = "pendulum"\n')
    with pytest.raises(cases.CaseError, match="unknown scene kind 'pendulum' \\(known: rigid_body, sliding_ladder"):
        cases.load_case(path)


def test_engines_declare_their_scenes():
    assert set(get_engine("mujoco").models()) == {"rigid_body", "sliding_ladder"}
    assert set(get_engine("reference").models()) == {"rigid_body", "sliding_ladder"}

    class Plain(Engine):  # the three required methods only: the rigid body through RigidBodyModel's defaults
        name = "plain"

        def integrators(self):
            return ("rk4",)

        def unsupported(self, case):
            return None

        def prepare(self, case, integrator, dt, **formulation):
            return ("prepared", integrator, dt, formulation)

    model = Plain().models()["rigid_body"]
    assert set(Plain().models()) == {"rigid_body"}
    assert model.prepare(None, "", "rk4", 0.1) == ("prepared", "rk4", 0.1, {})
    assert model.prepare(None, "q", "rk4", None, 1e-6) == ("prepared", "rk4", None, {"formulation": "q",
                                                                                     "tolerance": 1e-6})
    assert Plain().unmodelled(scenes.scene("sliding_ladder")) == "plain adapter does not model the sliding ladder"


def test_a_0_2_0_plugin_with_the_ladder_hooks_is_refused_naming_the_new_spelling():
    with pytest.raises(TypeError, match=r"defines 'sliding_ladder_models', a name of stereodyn 0\.2\.0's engine "
                                        r"protocol: since 0\.3\.0 declare models\(\) returning"):
        class Old(Engine):
            name = "old"

            def sliding_ladder_models(self):
                return ("m",)

            def prepare_sliding_ladder(self, case, model, integrator, dt):
                return ("ladder", model, integrator, dt)


def test_export_asks_the_engines_model_of_the_scene():
    from stereodyn.harness.export import ExportError, export

    ladder = cases.find_case("sliding-ladder")
    with pytest.raises(ExportError, match="sliding-ladder: the sliding ladder has two MuJoCo models"):
        export(ladder, "mjcf")
    with pytest.raises(ExportError, match="sliding-ladder: no urdf export of this scene's model"):
        export(ladder, "urdf")
    assert export(cases.find_case("free-asymmetric"), "mjcf").startswith('<mujoco model="free-asymmetric">')
