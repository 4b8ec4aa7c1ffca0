"""The longest chain of imports inside the package: A imports B imports C ..., every `import` and `from ... import` in
the source, at module level, inside functions and in TYPE_CHECKING blocks (test_import_cycles' graph; an import from
outside a package counts its __init__). Issue 29 asks for at most 15 modules, issue 47 counting type-only imports too;
LIMIT is what the tree has reached (see its comment), so that the chain can shorten and never grow unnoticed."""
from test_import_cycles import graph, imports

# 15 modules, issue 29's bound, counting the package __init__ that an import from outside the package runs first
# (test_import_cycles) and, since issue 47, the imports for type checkers only. Ten chains are 15 long, from
# cli.run -> pipeline.phases or cli.matrix -> cli.history down to reference.body -> reference.torque_models ->
# reference.registry -> reference; e.g. cli.matrix -> cli.history -> report.history -> analysis.history ->
# analysis.compare -> analysis.gate -> run.results -> scenes.metrics -> scenes.cases -> reference.exact ->
# reference.exact.heavy -> reference.body -> reference.torque_models -> reference.registry -> reference.
# From 16 with the type-only imports (15 without them, the bound before): the engines' protocol names Case from
# harness/scenes/case.py (the dataclass alone, below the case files' readers and the exact solutions) instead of
# harness/scenes/cases.py, and the torque-free flow types its body as a protocol of what it reads
# (reference/torque_free.py: FreeBody) instead of importing reference.body. 17 before issue 29's shortening: the torque-free body's home is
# reference/torque_free.py and the exact solutions' helpers reference/closed_form.py, outside reference/exact/; the
# Butcher tableau in harness/integrators/tableau.py; the `timing` column's SINGLE in harness/tables.py. Shorter needs
# both tops cut (cli.run must import the pipeline, cli.matrix the history) or the torque registry below the body.
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


def test_a_lazy_import_and_a_type_checking_one_lengthen_the_chain(tmp_path):
    (tmp_path / "one.py").write_text("def f():\n    from pkg import two\n")
    (tmp_path / "two.py").write_text("from typing import TYPE_CHECKING\nif TYPE_CHECKING:\n    from pkg import three\n")
    (tmp_path / "three.py").write_text("")
    known = {"pkg.one", "pkg.two", "pkg.three"}
    edges = {name: imports(name, tmp_path / f"{name[4:]}.py", known) for name in known}
    assert longest_chain(edges) == ["pkg.one", "pkg.two", "pkg.three"]


def test_importing_a_submodule_from_outside_runs_its_package_and_from_inside_does_not(tmp_path):
    (tmp_path / "pkg").mkdir()
    (tmp_path / "pkg" / "__init__.py").write_text("")
    (tmp_path / "pkg" / "sub.py").write_text("x = 1\n")
    (tmp_path / "pkg" / "inner.py").write_text("from pkg.sub import x\n")
    (tmp_path / "outer.py").write_text("from pkg.sub import x\n")
    known = {"pkg", "pkg.sub", "pkg.inner", "outer"}
    assert imports("outer", tmp_path / "outer.py", known) == {"pkg", "pkg.sub"}
    assert imports("pkg.inner", tmp_path / "pkg" / "inner.py", known) == {"pkg.sub"}
