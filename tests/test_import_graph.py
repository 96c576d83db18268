"""The product's modules import one another without a circle, function-local imports included (a
circle hidden in a function is a circle a refactoring trips over), and nothing outside the
composition layer reaches the simulators.

The graph is read from the source (``ast``), not from what one run happened to import: every import
statement counts but those under ``if TYPE_CHECKING:``, which never run.
"""

from __future__ import annotations

import ast
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
PACKAGES = ("bench", "drivers", "sequences", "simulators")
#: The composition layer (docs/architecture.md): the only modules that may reach the simulators,
#: the simulated bench's composition among them. Everything else (analysis, models, store, report,
#: engine, the drivers and the vocabulary) works the same whatever is at the other end of a link.
COMPOSITION = ("bench.app.", "bench.cli.", "bench.tui.", "bench.demo", "bench.simulated_")


def _module_name(path: Path) -> str:
    parts = path.relative_to(ROOT).with_suffix("").parts
    return ".".join(parts[:-1] if parts[-1] == "__init__" else parts)


def _modules() -> dict[str, Path]:
    return {
        _module_name(path): path
        for package in PACKAGES
        for path in sorted((ROOT / package).rglob("*.py"))
        if "__pycache__" not in path.parts
    }


def _type_checking(node: ast.If) -> bool:
    test = node.test
    return (isinstance(test, ast.Name) and test.id == "TYPE_CHECKING") or (
        isinstance(test, ast.Attribute) and test.attr == "TYPE_CHECKING"
    )


def _imports(tree: ast.AST, package: str, modules: dict[str, Path]) -> set[str]:
    """The product modules a module's source imports (relative imports resolved against ``package``)."""
    found: set[str] = set()

    def visit(node: ast.AST) -> None:
        if isinstance(node, ast.If) and _type_checking(node):
            for child in node.orelse:
                visit(child)
            return
        if isinstance(node, ast.Import):
            found.update(alias.name for alias in node.names)
        elif isinstance(node, ast.ImportFrom):
            base = node.module or ""
            if node.level:
                anchor = package.split(".")[: len(package.split(".")) - node.level + 1]
                base = ".".join([*anchor, base] if base else anchor)
            for alias in node.names:
                found.add(f"{base}.{alias.name}" if f"{base}.{alias.name}" in modules else base)
        for child in ast.iter_child_nodes(node):
            visit(child)

    visit(tree)
    return {name for name in found if name in modules}


def import_graph() -> dict[str, set[str]]:
    modules = _modules()
    graph = {}
    for name, path in modules.items():
        package = name if path.name == "__init__.py" else name.rpartition(".")[0]
        graph[name] = _imports(ast.parse(path.read_text(), str(path)), package, modules) - {name}
    return graph


def circles(graph: dict[str, set[str]]) -> list[list[str]]:
    """The strongly connected components of more than one module (Tarjan's algorithm, iterative)."""
    index: dict[str, int] = {}
    low: dict[str, int] = {}
    stack: list[str] = []
    on_stack: set[str] = set()
    found: list[list[str]] = []
    for start in sorted(graph):
        if start in index:
            continue
        work = [(start, iter(sorted(graph[start])))]
        index[start] = low[start] = len(index)
        stack.append(start)
        on_stack.add(start)
        while work:
            node, children = work[-1]
            child = next(children, None)
            if child is not None:
                if child not in index:
                    index[child] = low[child] = len(index)
                    stack.append(child)
                    on_stack.add(child)
                    work.append((child, iter(sorted(graph[child]))))
                elif child in on_stack:
                    low[node] = min(low[node], index[child])
                continue
            work.pop()
            if work:
                low[work[-1][0]] = min(low[work[-1][0]], low[node])
            if low[node] == index[node]:
                component = []
                while True:
                    member = stack.pop()
                    on_stack.discard(member)
                    component.append(member)
                    if member == node:
                        break
                if len(component) > 1:
                    found.append(sorted(component))
    return found


def test_the_finder_finds_a_circle_through_a_function_local_import():
    """The check itself: a circle closed by an import inside a function is found."""
    modules = {"a": Path("a.py"), "b": Path("b.py"), "c": Path("c.py")}
    a = _imports(ast.parse("import b\n"), "", modules)
    b = _imports(ast.parse("def f():\n    from c import g\n"), "", modules)
    source = "from typing import TYPE_CHECKING\nif TYPE_CHECKING:\n    import b\nimport a\n"
    c = _imports(ast.parse(source), "", modules)
    assert circles({"a": a, "b": b, "c": c}) == [["a", "b", "c"]]
    assert circles({"a": a, "b": b, "c": set()}) == []


def test_no_module_of_the_product_imports_another_in_a_circle():
    found = circles(import_graph())
    assert not found, "import circles:\n" + "\n".join(" <-> ".join(c) for c in found)


def test_only_the_composition_reaches_the_simulators():
    """No module outside the composition imports the simulators, directly or through another
    (a renderer drawing a simulated result imported the simulation with it)."""
    graph = import_graph()
    reaches: dict[str, bool] = {}

    def reaches_simulators(name: str) -> bool:
        if name not in reaches:
            reaches[name] = False  # the graph has no circle (above); this only ends the walk
            reaches[name] = name.startswith("simulators") or any(map(reaches_simulators, graph[name]))
        return reaches[name]

    outside = sorted(
        name
        for name in graph
        if name.startswith(("bench", "drivers", "sequences"))
        and not name.startswith(COMPOSITION)
        and reaches_simulators(name)
    )
    assert not outside, outside
