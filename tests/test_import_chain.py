"""The longest chain of runtime imports inside the package: A imports B imports C ..., every `import` and `from ...
import` in the source, at module level and inside functions (test_import_cycles' graph; TYPE_CHECKING blocks left out,
since they never run; an import from outside a package counts its __init__). Issue 29 asks for at most 15 modules;
LIMIT is what the tree has reached (see its comment), so that the chain can shorten and never grow unnoticed."""
from test_import_cycles import graph, imports

# 15 modules, issue 29's bound, counting the package __init__ that an import from outside the package runs first
# (test_import_cycles). Two chains are 15 long: cli.run -> pipeline.phases -> analysis.summary -> analysis.answers ->
# analysis.workprecision -> analysis.ladders -> analysis.fitting -> engines -> engines.base -> integrators ->
# integrators.geometric -> integrators.vector -> integrators.base -> harness -> moved, and cli.matrix -> cli.history ->
# report.history -> analysis.history -> analysis.compare -> analysis.gate -> run.results -> scenes.metrics ->
# scenes.cases -> reference.exact -> reference.exact.heavy -> reference.body -> reference.torque_models ->
# reference.registry -> reference. From 17 (this count, before): the torque-free body's home is reference/torque_free.py
# and the exact solutions' helpers reference/closed_form.py (before: a private module of the exact package), both
# outside reference/exact/, so that geometric's splitting imports the free flow without the exact package's __init__
# (every exact solution, the body, the torque models); the free flow names RigidBody in annotations only, so it imports
# it for type checkers only (reference/exact/euler_poinsot.py re-exports its names, 0.2.0's path); the Butcher tableau
# in harness/integrators/tableau.py, so that the vector methods no longer import the group methods (lie.py re-exports
# it); the `timing` column's SINGLE beside `disturbed` in harness/tables.py, so that run.timing no longer imports
# run.results (whose columns need the scenes' metrics, the cases and the exact solutions; results re-exports it). The
# floor under engines is now 8 modules of real needs (the registry checks Engine; Engine's defaults look integrators up
# in the table the integrators package fills with its built-ins; geometric's implicit midpoint is a VectorRK, and every
# integrator's step loop checks the budget), so a chain through engines has at most 7 above it.
LIMIT = 15


def longest_chain(edges: dict[str, set[str]]) -> list[str]:
    """The longest import chain of an acyclic graph (module -> the modules it imports), as its modules from the
    importer down; among chains of one length, the first by module name."""
    memo: dict[str, list[str]] = {}

    def down(node: str) -> list[str]:
        if node not in memo:
            below = [down(target) for target in sorted(edges.get(node, ()))]
            memo[node] = [node, *max(below, key=len, default=[])]
        return memo[node]

    return max((down(node) for node in sorted(edges)), key=len, default=[])


def test_the_longest_import_chain_is_short():
    chain = longest_chain(graph())
    assert len(chain) <= LIMIT, f"the longest import chain has {len(chain)} modules (at most {LIMIT}):\n" + \
        "\n -> ".join(chain)


def test_the_chain_finder_finds_the_longest_path():
    edges = {"a": {"b", "x"}, "b": {"c"}, "c": {"d"}, "x": {"d"}, "d": set(), "e": {"a"}}
    assert longest_chain(edges) == ["e", "a", "b", "c", "d"]
    assert longest_chain({"a": set()}) == ["a"] and longest_chain({}) == []


def test_a_lazy_import_lengthens_the_chain_and_a_type_checking_one_does_not(tmp_path):
    (tmp_path / "one.py").write_text("def f():\n    from pkg import two\n")
    (tmp_path / "two.py").write_text("from typing import TYPE_CHECKING\nif TYPE_CHECKING:\n    from pkg import three\n")
    (tmp_path / "three.py").write_text("")
    known = {"pkg.one", "pkg.two", "pkg.three"}
    edges = {name: imports(name, tmp_path / f"{name[4:]}.py", known) for name in known}
    assert longest_chain(edges) == ["pkg.one", "pkg.two"]


def test_importing_a_submodule_from_outside_runs_its_package_and_from_inside_does_not(tmp_path):
    (tmp_path / "pkg").mkdir()
    (tmp_path / "pkg" / "__init__.py").write_text("")
    (tmp_path / "pkg" / "sub.py").write_text("x = 1\n")
    (tmp_path / "pkg" / "inner.py").write_text("from pkg.sub import x\n")
    (tmp_path / "outer.py").write_text("from pkg.sub import x\n")
    known = {"pkg", "pkg.sub", "pkg.inner", "outer"}
    assert imports("outer", tmp_path / "outer.py", known) == {"pkg", "pkg.sub"}
    assert imports("pkg.inner", tmp_path / "pkg" / "inner.py", known) == {"pkg.sub"}
