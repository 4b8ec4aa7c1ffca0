"""The package's modules import each other without a cycle: every `import` and `from ... import` in the source, at
module level, inside functions and in TYPE_CHECKING blocks (static, by ast: a type-only import never runs, but a
cycle through it is still two modules that need each other to be read, issue 47), plus the enclosing packages that
such an import runs first (`from ..integrators.registry import get` runs integrators/__init__)."""
import ast
import functools
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
# import name prefix -> source folder (pyproject's package-dir)
FOLDERS = {"stereodyn.harness": ROOT / "harness", "stereodyn.reference": ROOT / "reference",
           "stereodyn.cases": ROOT / "cases", "stereodyn": ROOT / "stereodyn"}


def modules() -> dict[str, Path]:
    """Every module of the package: dotted name -> file."""
    found = {}
    for prefix, folder in FOLDERS.items():
        for path in folder.rglob("*.py"):
            parts = list(path.relative_to(folder).with_suffix("").parts)
            if parts[-1] == "__init__":
                parts = parts[:-1]
            found[".".join([prefix, *parts])] = path
    return found


def imports(name: str, path: Path, known: set[str]) -> set[str]:
    """The package's modules that the module imports anywhere in its source."""
    package = name if path.name == "__init__.py" else name.rpartition(".")[0]
    edges: set[str] = set()

    def visit(node: ast.AST) -> None:
        if isinstance(node, ast.Import):
            for alias in node.names:
                edges.add(alias.name)
        elif isinstance(node, ast.ImportFrom):
            base = node.module or ""
            if node.level:  # relative import
                anchor = package.split(".")
                anchor = anchor[:len(anchor) - (node.level - 1)]
                base = ".".join(anchor + ([base] if base else []))
            edges.add(base)
            for alias in node.names:  # `from package import module` imports the module
                edges.add(f"{base}.{alias.name}")
        for child in ast.iter_child_nodes(node):
            visit(child)

    visit(ast.parse(path.read_text(), filename=str(path)))
    # importing P.m from outside P runs P/__init__.py first: the importer depends on each enclosing package it is not in
    for edge in list(edges):
        parts = edge.split(".")
        for cut in range(1, len(parts)):
            parent = ".".join(parts[:cut])
            if name != parent and not name.startswith(parent + "."):
                edges.add(parent)
    return {edge for edge in edges if edge in known and edge != name}


@functools.cache  # parsed once per test process (every layer and chain test reads it; nothing mutates it)
def graph() -> dict[str, set[str]]:
    found = modules()
    return {name: imports(name, path, set(found)) for name, path in found.items()}


def find_cycle(edges: dict[str, set[str]]) -> list[str] | None:
    """One cycle of the graph as a list of modules (first == last), or None."""
    state: dict[str, int] = {}  # 1 on the stack, 2 done
    stack: list[str] = []

    def visit(node: str) -> list[str] | None:
        state[node] = 1
        stack.append(node)
        for target in sorted(edges.get(node, ())):
            if state.get(target) == 1:
                return stack[stack.index(target):] + [target]
            if target not in state:
                cycle = visit(target)
                if cycle:
                    return cycle
        stack.pop()
        state[node] = 2
        return None

    for node in sorted(edges):
        if node not in state:
            cycle = visit(node)
            if cycle:
                return cycle
    return None


def test_the_walk_sees_the_package():
    edges = graph()
    assert len(edges) > 40
    assert "stereodyn.harness.run.plan" in edges["stereodyn.harness.run.sweep"]
    # an import inside a function counts (harness.analysis.ladders.families imports the plan there, relatively)
    assert "stereodyn.harness.run.plan" in edges["stereodyn.harness.analysis.ladders"]


def test_no_import_cycle():
    cycle = find_cycle(graph())
    assert cycle is None, "import cycle: " + " -> ".join(cycle)


def test_the_cycle_finder_finds_one():
    assert find_cycle({"a": {"b"}, "b": {"c"}, "c": {"a"}, "d": set()}) == ["a", "b", "c", "a"]
    assert find_cycle({"a": {"b"}, "b": set()}) is None


def test_a_type_only_import_makes_a_cycle(tmp_path):
    """harness/engines/base.py -> harness/scenes/cases.py (Case) -> harness/scenes/base.py -> back (SceneModel) was one,
    every link but the first at runtime; such a cycle counts (issue 47)."""
    (tmp_path / "one.py").write_text("from typing import TYPE_CHECKING\nif TYPE_CHECKING:\n    from pkg import two\n")
    (tmp_path / "two.py").write_text("import pkg.one\n")
    known = {"pkg.one", "pkg.two"}
    edges = {name: imports(name, tmp_path / f"{name[4:]}.py", known) for name in known}
    assert find_cycle(edges) == ["pkg.one", "pkg.two", "pkg.one"]


def test_a_function_level_import_makes_a_cycle(tmp_path):
    (tmp_path / "one.py").write_text("import pkg.two\n")
    (tmp_path / "two.py").write_text("def f():\n    from pkg import one\n")
    known = {"pkg.one", "pkg.two"}
    edges = {"pkg.one": imports("pkg.one", tmp_path / "one.py", known),
             "pkg.two": imports("pkg.two", tmp_path / "two.py", known)}
    assert find_cycle(edges) == ["pkg.one", "pkg.two", "pkg.one"]
