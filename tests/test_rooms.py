"""The code's rooms: no import circle between synptv's modules, floors inside ``ptv`` and
``validation`` whose imports point down, and no module too long to live in (outside
modules of compiled numba kernels)."""

import ast
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
PACKAGES = ("ptv", "simulator", "validation", "benchmarks")
#: Longest module, lines, unless most of its functions are compiled kernels.
MAX_LINES = 700
_COMPILERS = {"njit", "jit", "vectorize", "guvectorize", "stencil"}
#: The floors of a package, lowest first (docs/README.md, "Floors"). A room is
#: a subpackage or a module right under the package; a room imports only rooms of lower
#: floors, never one of its own floor or above (the package's ``__init__``, its public
#: front door, may import any).
FLOORS = {
    "ptv": (
        ("_assign", "_checks", "_threads", "bins", "box", "camera_model", "errors", "names",
         "rays"),
        ("io", "tracking", "triangulate"),
        ("settings",),
        ("detect", "matching", "stats"),
        ("calibration", "reconstruct"),
        ("pipeline",),
    ),
    "validation": (
        ("reference_particles", "truth", "workflow"),
        ("dataset", "score"),
        ("report",),
        ("run",),
        ("export", "studies"),
        ("claims", "convert"),
        ("mutations",),
        ("audit",),
        ("commands",),
        ("cli",),
    ),
}


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


def _graph() -> dict[str, set[str]]:
    """Every module's imports of the packages' modules."""
    modules = _modules()
    return {
        name: _imported(ast.parse(path.read_text(encoding="utf-8")), name,
                        path.name == "__init__.py", modules)
        for name, path in modules.items()
    }  # fmt: skip


def _upward(graph: dict[str, set[str]], package: str, floors: tuple) -> list[str]:
    """The imports of ``package``'s modules that do not point to a lower floor, as
    "module -> module"; a room on no floor is reported as "room: on no floor"."""
    floor = {room: level for level, rooms in enumerate(floors) for room in rooms}
    found = []
    for name, targets in sorted(graph.items()):
        parts = name.split(".")
        if parts[0] != package or len(parts) == 1:
            continue
        if parts[1] not in floor:
            found.append(f"{parts[1]}: on no floor")
            continue
        for target in sorted(targets):
            room = target.split(".")[1:2]
            if target.split(".")[0] != package or not room or room[0] == parts[1]:
                continue
            if floor.get(room[0], len(floors)) >= floor[parts[1]]:
                found.append(f"{name} -> {target}")
    return sorted(set(found))


def test_the_floor_check_finds_an_upward_import():
    floors = (("low",), ("mid_a", "mid_b"), ("high",))
    graph = {
        "p": {"p.high"},
        "p.low": set(),
        "p.mid_a.x": {"p.low", "p.mid_a.y"},
        "p.mid_a.y": {"p.mid_b"},
        "p.mid_b": {"p.high.z"},
        "p.high.z": {"p.mid_a.x", "p.low"},
        "p.other": set(),
    }
    assert _upward(graph, "p", floors) == [
        "other: on no floor",
        "p.mid_a.y -> p.mid_b",
        "p.mid_b -> p.high.z",
    ]


@pytest.mark.parametrize("package", sorted(FLOORS))
def test_every_import_between_rooms_points_down(package):
    assert _upward(_graph(), package, FLOORS[package]) == []


def test_the_cycle_finder_finds_a_circle():
    assert _cycles({"a": {"b"}, "b": {"c"}, "c": {"a"}, "d": {"a"}}) == [["a", "b", "c"]]
    assert _cycles({"a": {"b"}, "b": set()}) == []


def test_no_import_circle():
    graph = _graph()
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
