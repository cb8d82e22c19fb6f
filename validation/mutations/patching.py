"""How a mutation changes the code: a patch replaces one named object while it is applied.

A :class:`Patch` names its target as ``"package.module:name"`` (a module attribute) or
``"package.module:Class.name"`` (a class attribute, e.g. a method) and says how to
build the replacement from the original: :func:`edited` for a change of its source, or
any callable, e.g. one that wraps the original and alters its output. A function or
class is replaced wherever it is looked up: in its own module and in every loaded module
that imported it by name (``from m import f`` binds ``f`` in the importer, which a patch
of ``m.f`` alone would not reach); not inside containers (a dict of functions keeps the
original). Plain values (numbers, strings) are replaced in the named module only.
Undoing restores every reference, including those that modules imported while the
patch was applied took from the patched module.
"""

import importlib
import inspect
import sys
import textwrap
from collections.abc import Callable, Iterator
from contextlib import contextmanager
from dataclasses import dataclass
from typing import Any

Make = Callable[[Any], Any]


@dataclass(frozen=True)
class Patch:
    """One object replaced while a mutation is applied.

    Attributes
    ----------
    target : str
        ``"package.module:name"`` or ``"package.module:Class.name"``.
    make : callable
        Builds the replacement from the original object.
    """

    target: str
    make: Make

    def owner_and_name(self) -> tuple[Any, str]:
        """The module or class that holds the target, and the target's attribute name."""
        module_name, _, path = self.target.partition(":")
        if not path:
            raise ValueError(f"patch target {self.target!r} is not 'module:name'")
        owner: Any = importlib.import_module(module_name)
        *parents, name = path.split(".")
        for parent in parents:
            owner = getattr(owner, parent)
        if name not in vars(owner):
            raise AttributeError(f"{self.target}: {owner!r} has no attribute {name!r}")
        return owner, name

    def original(self) -> Any:
        """The unpatched object."""
        owner, name = self.owner_and_name()
        return vars(owner)[name]


def _shared(obj: Any) -> bool:
    """Whether other modules may hold ``obj`` by identity (functions, classes, Numba
    dispatchers: callables), as opposed to plain values that identity cannot attribute."""
    return callable(obj)


def _references(obj: Any) -> list[tuple[Any, str]]:
    """Every (module, attribute) of the loaded modules that holds ``obj`` itself."""
    found = []
    for module in list(sys.modules.values()):
        namespace = getattr(module, "__dict__", None)
        if not isinstance(namespace, dict):
            continue
        found.extend((module, key) for key, held in list(namespace.items()) if held is obj)
    return found


@contextmanager
def applied(patches: tuple[Patch, ...]) -> Iterator[None]:
    """Apply ``patches`` for the duration of the block, then restore every reference."""
    undo: list[tuple[Any, str, Any, Any]] = []
    try:
        for patch in patches:
            owner, name = patch.owner_and_name()
            original = vars(owner)[name]
            replacement = patch.make(original)
            holders = [(owner, name)]
            if _shared(original) and inspect.ismodule(owner):
                holders += [h for h in _references(original) if h != (owner, name)]
            for holder, key in holders:
                setattr(holder, key, replacement)
                undo.append((holder, key, original, replacement))
        yield
    finally:
        for holder, key, original, replacement in reversed(undo):
            setattr(holder, key, original)
            if _shared(replacement):
                for late, late_key in _references(replacement):
                    setattr(late, late_key, original)


def _python_function(obj: Any) -> Any:
    """The plain Python function behind ``obj`` (a function, or a Numba dispatcher)."""
    return getattr(obj, "py_func", obj)


def edited(old: str, new: str) -> Make:
    """A replacement compiled from the original function's source with ``old`` → ``new``.

    The original may be a function, a Numba dispatcher or a property (its getter is
    edited). ``old`` must occur exactly once in the function's source (decorators included, so a
    Numba kernel is recompiled; its on-disk cache is switched off). The new function is
    compiled in the original module's namespace, so every name it uses is looked up there
    at call time, as the original's are.
    """

    def make(original: Any) -> Any:
        if isinstance(original, property):  # the getter's source carries @property
            return make(original.fget)
        function = _python_function(original)
        source = textwrap.dedent(inspect.getsource(function))
        count = source.count(old)
        if count != 1:
            raise ValueError(
                f"{function.__module__}.{function.__qualname__}: {old!r} occurs {count} times "
                "in its source, not once"
            )
        source = source.replace(old, new).replace("cache=True", "cache=False")
        code = compile(source, f"<mutated {function.__module__}.{function.__qualname__}>", "exec")
        namespace: dict[str, Any] = {}
        exec(code, function.__globals__, namespace)
        return namespace[function.__name__]

    return make
