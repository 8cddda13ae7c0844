"""The package's layers: no module imports from a layer above its own.

The sub-packages of ``drake_lfd``, lowest first, are core < robot < planning < io <
systems < diagrams < experiments < cli. A module may import its own layer and the ones
below; ``drake_lfd/__init__.py`` and ``__main__.py`` are the top and may import anything.
Every ``import``, ``from ... import`` (relative ones resolved; inside functions and
``if TYPE_CHECKING:`` blocks too) and ``importlib.import_module("...")`` /
``__import__("...")`` call with a literal name counts. A dynamic ``import_module`` with
a computed name cannot be checked, so below the top layer it is refused; in the top
layer every string naming a ``drake_lfd`` module is taken as a possible import.

The one exception is the lazy-export helper (``drake_lfd.core._lazy``): a package hands
``lazy_exports`` a table, exported name -> defining module, and the helper imports those
modules by computed name. It refuses any module outside the package that hands it the
table, and in a module that calls ``lazy_exports`` every string naming a ``drake_lfd``
module counts as an import, so the tables are checked where they are written.
"""

from __future__ import annotations

import ast
import importlib.util
import pkgutil
import re
from pathlib import Path

import pytest

import drake_lfd

LAYERS = ("core", "robot", "planning", "io", "systems", "diagrams", "experiments", "cli")
TOP_MODULES = ("drake_lfd", "drake_lfd.__main__")
_MODULE_NAME = re.compile(r"^drake_lfd(\.[A-Za-z_][A-Za-z0-9_]*)+$")


# An installed drake-lfd carries the repository's models/ and sims/ folders as data
# packages (drake_lfd.models, drake_lfd.sims: the UR5e model, the scenarios, the bundled
# libraries and the scripts that rebuild them); they are data, not layers of the code.
DATA_PACKAGES = ("drake_lfd.models", "drake_lfd.sims")

# The lazy-export helper: its computed import takes the modules of a table that the
# calling package writes (and it refuses modules outside that package).
LAZY_EXPORTS_MODULE = "drake_lfd.core._lazy"
LAZY_EXPORTS_FUNCTION = "lazy_exports"


def package_modules() -> dict[str, Path]:
    """Every module of the package's code: dotted name -> source file."""
    modules = {"drake_lfd": Path(drake_lfd.__file__)}
    for info in pkgutil.walk_packages(drake_lfd.__path__, prefix="drake_lfd."):
        if any(info.name == data or info.name.startswith(data + ".") for data in DATA_PACKAGES):
            continue
        modules[info.name] = Path(importlib.util.find_spec(info.name).origin)
    return modules


def layer_of(module: str) -> str | None:
    """The layer of a dotted ``drake_lfd`` module name; None for the package itself."""
    parts = module.split(".")
    return parts[1] if len(parts) > 1 else None


def _called_name(node: ast.Call) -> str | None:
    function = node.func
    return function.attr if isinstance(function, ast.Attribute) else getattr(function, "id", None)


def _is_import_call(node: ast.Call) -> bool:
    return _called_name(node) in ("import_module", "__import__")


def imported_modules(source: str, module: str, *, is_package: bool = False) -> list[tuple[int, str]]:
    """``(line, dotted name)`` of every ``drake_lfd`` module that ``source`` imports.

    ``from A import b`` yields ``A.b`` (b may be a module or a name in A; its layer is
    A's either way). A computed ``import_module(...)`` yields ``(line, "?")``. After a
    computed import or a call of ``lazy_exports``, every string naming a ``drake_lfd``
    module counts too.
    """
    package = module if is_package else module.rpartition(".")[0]
    tree = ast.parse(source)
    found = []
    dynamic = False
    tables = False
    for node in ast.walk(tree):
        if isinstance(node, ast.Import):
            found.extend((node.lineno, alias.name) for alias in node.names)
        elif isinstance(node, ast.ImportFrom):
            if node.level:
                base = package.split(".")
                base = base[: len(base) - (node.level - 1)]
                target = ".".join(base + ([node.module] if node.module else []))
            else:
                target = node.module
            found.extend((node.lineno, f"{target}.{alias.name}") for alias in node.names)
        elif isinstance(node, ast.Call) and _is_import_call(node):
            argument = node.args[0] if node.args else None
            if isinstance(argument, ast.Constant) and isinstance(argument.value, str):
                found.append((node.lineno, argument.value))
            else:
                dynamic = True
                found.append((node.lineno, "?"))
        elif isinstance(node, ast.Call) and _called_name(node) == LAZY_EXPORTS_FUNCTION:
            tables = True
    if dynamic or tables:
        found.extend(
            (node.lineno, node.value)
            for node in ast.walk(tree)
            if isinstance(node, ast.Constant) and isinstance(node.value, str) and _MODULE_NAME.match(node.value)
        )
    return [(line, name) for line, name in found if name == "?" or name.split(".")[0] == "drake_lfd"]


def violations(module: str, source: str, *, is_package: bool = False) -> list[str]:
    """What is wrong with the imports of ``module``, one line each (empty: nothing)."""
    if module in TOP_MODULES:
        return []
    own = layer_of(module)
    if own not in LAYERS:
        return [f"{module}: not in a layer (modules live in drake_lfd/<layer>/, layers {', '.join(LAYERS)})"]
    problems = []
    for line, name in imported_modules(source, module, is_package=is_package):
        if name == "?":
            if own != LAYERS[-1] and module != LAZY_EXPORTS_MODULE:
                problems.append(f"{module}:{line}: import_module with a computed name cannot be checked")
            continue
        target = layer_of(name)
        if target is None or target.startswith("__"):
            continue  # the package root itself (its docstring and __version__)
        if target not in LAYERS:
            problems.append(f"{module}:{line}: imports {name}, which is in no layer")
        elif LAYERS.index(target) > LAYERS.index(own):
            problems.append(f"{module}:{line}: imports {name} ({own} may not import from {target})")
    return problems


def test_every_module_is_in_a_layer():
    """Besides ``__init__`` and ``__main__``, nothing lives directly under drake_lfd/."""
    modules = package_modules()
    assert {f"drake_lfd.{layer}" for layer in LAYERS} <= set(modules), "every layer is a sub-package"
    stray = [name for name in modules if name not in TOP_MODULES and layer_of(name) not in LAYERS]
    assert not stray, f"modules outside the layers: {stray}"


def test_no_module_imports_from_a_higher_layer():
    problems = []
    for name, path in sorted(package_modules().items()):
        problems.extend(violations(name, path.read_text(encoding="utf-8"), is_package=path.name == "__init__.py"))
    assert not problems, "upward imports:\n" + "\n".join(problems)


@pytest.mark.parametrize(
    "module, source, words",
    [
        ("drake_lfd.robot.scene", "from drake_lfd.systems.shell_monitor import min_signed_distances\n", "systems"),
        ("drake_lfd.core.tasks", "def f():\n    import drake_lfd.io.task_files\n", "io"),
        ("drake_lfd.io.library", "from ..diagrams import kinesthetic\n", "diagrams"),
        ("drake_lfd.planning.planner", "import importlib\nimportlib.import_module('drake_lfd.cli.app')\n", "cli"),
        ("drake_lfd.core.x", "from typing import TYPE_CHECKING\nif TYPE_CHECKING:\n    from drake_lfd.robot import kinematics\n", "robot"),
        ("drake_lfd.core.x", "import importlib\nname = 'drake_lfd.core.tasks'\nimportlib.import_module(name)\n", "computed"),
        ("drake_lfd.helpers", "import numpy\n", "not in a layer"),
        ("drake_lfd.robot", "from drake_lfd.core._lazy import lazy_exports\n"
         "__getattr__, __dir__ = lazy_exports(globals(), {'X': 'drake_lfd.systems.planner'})\n", "systems"),
        ("drake_lfd.robot.x", "import importlib\nimportlib.import_module(__name__ + '.y')\n", "computed"),
    ],
)
def test_the_check_catches_upward_imports(module, source, words):
    problems = violations(module, source)
    assert len(problems) == 1 and words in problems[0], problems


def test_the_check_allows_same_and_lower_layers():
    source = (
        "from drake_lfd.core.tasks import Box\n"
        "from . import library_manifest\n"
        "from drake_lfd import __version__\n"
        "def f():\n    import drake_lfd.robot.kinematics\n"
    )
    assert violations("drake_lfd.io.library", source) == []
    assert violations("drake_lfd", "import drake_lfd.cli\n") == []
    computed = "import importlib\nfor n in ('drake_lfd.cli.plan',):\n    importlib.import_module(n)\n"
    assert violations("drake_lfd.cli.app", computed) == []
