"""The code's rooms: no import circle between synptv's modules, and no module too long
to live in (outside modules of compiled numba kernels)."""

import ast
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
PACKAGES = ("ptv", "simulator", "validation", "benchmarks")
#: Longest module, lines, unless most of its functions are compiled kernels.
MAX_LINES = 700
_COMPILERS = {"njit", "jit", "vectorize", "guvectorize", "stencil"}


def _modules() -> dict[str, Path]:
    """Every module of the packages, by dotted name (a package by its own name)."""
    found = {}
    for package in PACKAGES:
        for path in (ROOT / package).rglob("*.py"):
            parts = path.relative_to(ROOT).with_suffix("").parts
            name = ".".join(parts[:-1] if parts[-1] == "__init__" else parts)
            found[name] = path
    return found


def _imported(tree: ast.Module, name: str, is_package: bool, modules: dict) -> set[str]:
    """The project modules a module imports anywhere in its body (a function's deferred
    import and a type checker's included): the longest known prefix of each name."""

    def known(dotted: str) -> str | None:
        while dotted and dotted not in modules:
            dotted = dotted.rpartition(".")[0]
        return dotted or None

    package = name if is_package else name.rpartition(".")[0]
    targets = set()
    for node in ast.walk(tree):
        if isinstance(node, ast.Import):
            targets |= {known(alias.name) for alias in node.names}
        elif isinstance(node, ast.ImportFrom):
            base = node.module or ""
            if node.level:
                anchor = package.split(".")[: len(package.split(".")) - node.level + 1]
                base = ".".join([*anchor, base] if base else anchor)
            for alias in node.names:
                full = f"{base}.{alias.name}"
                targets.add(full if full in modules else known(base))
    targets.discard(None)
    targets.discard(name)
    return targets


def _cycles(graph: dict[str, set[str]]) -> list[list[str]]:
    """The strongly connected components of more than one module (Tarjan)."""
    index, low, stack, on_stack, found = {}, {}, [], set(), []

    def visit(v: str) -> None:
        index[v] = low[v] = len(index)
        stack.append(v)
        on_stack.add(v)
        for w in graph[v]:
            if w not in index:
                visit(w)
                low[v] = min(low[v], low[w])
            elif w in on_stack:
                low[v] = min(low[v], index[w])
        if low[v] == index[v]:
            component = []
            while True:
                w = stack.pop()
                on_stack.discard(w)
                component.append(w)
                if w == v:
                    break
            if len(component) > 1:
                found.append(sorted(component))

    for v in graph:
        if v not in index:
            visit(v)
    return found


def test_the_cycle_finder_finds_a_circle():
    assert _cycles({"a": {"b"}, "b": {"c"}, "c": {"a"}, "d": {"a"}}) == [["a", "b", "c"]]
    assert _cycles({"a": {"b"}, "b": set()}) == []


def test_no_import_circle():
    modules = _modules()
    graph = {
        name: _imported(ast.parse(path.read_text(encoding="utf-8")), name,
                        path.name == "__init__.py", modules)
        for name, path in modules.items()
    }  # fmt: skip
    assert len(graph) > 200
    assert _cycles(graph) == []


def _compiled_share(tree: ast.Module) -> float:
    """The fraction of a module's top-level functions that numba compiles."""

    def compiled(function: ast.FunctionDef) -> bool:
        for decorator in function.decorator_list:
            node = decorator.func if isinstance(decorator, ast.Call) else decorator
            name = node.attr if isinstance(node, ast.Attribute) else getattr(node, "id", "")
            if name in _COMPILERS:
                return True
        return False

    functions = [n for n in tree.body if isinstance(n, ast.FunctionDef)]
    return sum(map(compiled, functions)) / len(functions) if functions else 0.0


@pytest.mark.parametrize("package", [*PACKAGES, "tests"])
def test_no_module_over_the_limit_outside_numba_kernels(package):
    too_long = []
    for path in (ROOT / package).rglob("*.py"):
        text = path.read_text(encoding="utf-8")
        lines = text.count("\n")
        if lines > MAX_LINES and _compiled_share(ast.parse(text)) < 0.5:
            too_long.append(f"{path.relative_to(ROOT)} ({lines} lines)")
    assert too_long == []
