"""The layers of the package (DESIGN §1): reference <- harness (scenes, run, engines, integrators) <- analysis <-
report <- pipeline <- cli. A module imports only from its own layer or those below it, anywhere in its source (static,
as test_import_cycles reads it): analysis never renders (imports nothing from report) and runs nothing (nothing that
measures, pools, times or budgets runs), reference never imports harness."""
import ast

from test_import_cycles import ROOT, graph, imports, modules

LAYERS = ("reference", "harness", "analysis", "report", "pipeline", "cli")
# stereodyn.harness.testing stays where plug-ins import it from but measures and fits: the analysis layer.
ANALYSIS_ELSEWHERE = ("stereodyn.harness.testing",)


def layer(module: str) -> str | None:
    """The layer of a module of the package; None for the package's root (stereodyn, python -m stereodyn: above all)
    and for the case files' package."""
    if module.startswith("stereodyn.reference"):
        return "reference"
    for name in ("analysis", "report", "pipeline", "cli"):
        if module == f"stereodyn.harness.{name}" or module.startswith(f"stereodyn.harness.{name}."):
            return name
    if module in ANALYSIS_ELSEWHERE:
        return "analysis"
    if module.startswith("stereodyn.harness"):
        return "harness"
    return None


def upward(edges: dict[str, set[str]]) -> list[str]:
    """Every import that runs up a layer, as 'importer -> imported'."""
    found = []
    for importer, imported in edges.items():
        for target in sorted(imported):
            below, above = layer(importer), layer(target)
            if below is not None and above is not None and LAYERS.index(above) > LAYERS.index(below):
                found.append(f"{importer} ({below}) -> {target} ({above})")
    return found


def test_the_layers_cover_the_package():
    edges = graph()
    assert {layer(m) for m in edges} >= set(LAYERS)
    assert layer("stereodyn.harness.analysis.fitting") == "analysis" and layer("stereodyn.harness.cli") == "cli"
    assert layer("stereodyn.harness.engines.mujoco") == "harness" and layer("stereodyn.harness.report") == "report"


def test_no_import_runs_up_a_layer():
    bad = upward(graph())
    assert not bad, "imports up a layer:\n" + "\n".join(bad)


def test_analysis_imports_nothing_from_report():
    edges = graph()
    bad = [f"{m} -> {t}" for m, targets in edges.items() if layer(m) == "analysis" for t in targets
           if layer(t) == "report"]
    assert not bad, bad


# What runs simulations (issue 29): the one run -> row, the pool and its workers, timing, the processes' interrupt rule,
# the sweep, the truths, the Dask path, the budgets. analysis/ reads tables and returns tables: it imports none of them
# (the pipeline runs what analysis decides), not even inside a function.
RUNS_THINGS = tuple(f"stereodyn.harness.{m}" for m in (
    "run.measure", "run.pool", "run.workers", "run.timing", "run.processes", "run.sweep", "run.truth",
    "run.distributed", "budget"))


def running_imports(edges: dict[str, set[str]]) -> list[str]:
    """Every import by a module of analysis/ of a module that runs things (RUNS_THINGS), as 'importer -> imported'."""
    return [f"{m} -> {t}" for m, targets in sorted(edges.items())
            if m == "stereodyn.harness.analysis" or m.startswith("stereodyn.harness.analysis.")
            for t in sorted(targets) if t in RUNS_THINGS]


def test_analysis_imports_nothing_that_runs_simulations():
    bad = running_imports(graph())
    assert not bad, "analysis/ imports what runs simulations (move the running part to harness/pipeline/):\n" + \
        "\n".join(bad)


def test_a_lazy_running_import_in_analysis_is_found(tmp_path):
    """The rule reads imports inside functions too: a fitter that times its runs is caught."""
    path = tmp_path / "fitting.py"
    path.write_text("import math\n\ndef fit(points):\n    from ..run import timing\n    return timing\n")
    name = "stereodyn.harness.analysis.fitting"
    edges = {name: imports(name, path, set(RUNS_THINGS) | {"stereodyn.harness.run"})}
    assert running_imports(edges) == [f"{name} -> stereodyn.harness.run.timing"]
    assert running_imports({"stereodyn.harness.pipeline.advice": {"stereodyn.harness.run.measure"}}) == []


def test_an_upward_import_is_found():
    edges = {"stereodyn.harness.analysis.fitting": {"stereodyn.harness.report.markdown"},
             "stereodyn.harness.report.build": {"stereodyn.harness.analysis.verdicts"},
             "stereodyn.reference.truth": {"stereodyn.harness.engines"}}
    assert upward(edges) == ["stereodyn.harness.analysis.fitting (analysis) -> stereodyn.harness.report.markdown "
                             "(report)", "stereodyn.reference.truth (reference) -> stereodyn.harness.engines (harness)"]


# The package imports its own modules relatively (DESIGN §1: a plain checkout then reads correctly in an editor or a
# static tool)
def test_the_package_imports_its_own_modules_relatively():
    absolute = []
    for name, path in modules().items():
        if path.parent.name == "stereodyn":  # stereodyn/*.py: harness/ is not below it
            continue
        for node in ast.walk(ast.parse(path.read_text(encoding="utf-8"))):
            if isinstance(node, ast.ImportFrom) and node.level == 0 and (node.module or "").startswith("stereodyn."):
                absolute.append(f"{path.relative_to(ROOT)}:{node.lineno}: from {node.module} import ...")
            elif isinstance(node, ast.Import):
                absolute += [f"{path.relative_to(ROOT)}:{node.lineno}: import {a.name}" for a in node.names
                             if a.name.startswith("stereodyn.")]
    assert not absolute, "import these relatively (from .x / from ..x):\n" + "\n".join(absolute)


# Each engine SDK is imported by its adapter only (DESIGN §1, "Boundaries"); MuJoCo's back-ends import their own SDK
# (mujoco.mjx, mujoco_warp) and get MuJoCo's model from harness/engines/mujoco.py (scene_state).
SDK_ADAPTERS = {"mujoco": {"harness/engines/mujoco.py"}, "pinocchio": {"harness/engines/pinocchio.py"},
                "pydrake": {"harness/engines/drake.py"}}
SDK_SUBMODULES_ELSEWHERE = {"mujoco.mjx": {"harness/engines/mjx.py"}}


def sdk_imports(path) -> set[str]:
    """The absolute names a file imports (`import a.b`: a.b; `from a import b`: a.b)."""
    found = set()
    for node in ast.walk(ast.parse(path.read_text())):
        if isinstance(node, ast.Import):
            found |= {alias.name for alias in node.names}
        elif isinstance(node, ast.ImportFrom) and node.level == 0 and node.module:
            found |= {f"{node.module}.{alias.name}" for alias in node.names}
    return found


def test_each_engine_sdk_is_imported_by_its_adapter_only():
    wrong = []
    for path in sorted((ROOT / "harness").rglob("*.py")):
        relative = str(path.relative_to(ROOT))
        for name in sdk_imports(path):
            top = name.split(".")[0]
            if top in SDK_ADAPTERS and relative not in SDK_ADAPTERS[top] \
                    and relative not in SDK_SUBMODULES_ELSEWHERE.get(name, ()):
                wrong.append(f"{relative}: {name}")
    assert not wrong, "an engine SDK imported outside its adapter:\n" + "\n".join(wrong)
