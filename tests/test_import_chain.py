"""The longest chain of runtime imports inside the package: A imports B imports C ..., every `import` and `from ...
import` in the source, at module level and inside functions (test_import_cycles' graph; TYPE_CHECKING blocks left out,
since they never run). Issue 29 asks for at most 15 modules; LIMIT is what the tree has reached (see its comment), so
that the chain can shorten and never grow unnoticed."""
from test_import_cycles import graph, imports

# Issue 29's bound, reached: 15 modules (cli.run -> pipeline.phases -> pipeline.work_precision -> pipeline.advice ->
# pipeline.tolerance_ladders -> pipeline.dt_ladders -> analysis.ladders -> analysis.fitting -> scenes.checks ->
# scenes.cases -> reference.exact -> reference.exact.euler_poinsot -> reference.body ->
# reference.torque_models.body_torque -> reference.torque_models.base), from 20: engines.base reads the integrator
# table (integrators.registry), not the package whose geometric methods import the exact solutions; the truth's names
# in engines.truth, not the engine registry (run.spec, scenes.checks); with_precision and disturbed in harness/tables.py
# (analysis.fitting, analysis.pareto: not run.results, whose columns need the integrals); the body and the exact
# solutions read the torque models' own modules, not their registry package. Several chains are 15 long: the pipeline's
# dt_ladders line (6 modules) over analysis.ladders -> fitting, and over run.timing -> run.results -> scenes.metrics.
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
