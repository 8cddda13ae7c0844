"""The public API: what each sub-package exports, where each name is defined, and the
API reference that documents it.

Each sub-package of ``drake_lfd`` (one per layer) exports what users need: its
``__all__``, the names of its table ``_EXPORTS`` (name -> the module that defines it),
each loaded from that module on first use (``drake_lfd.core._lazy``). ``drake_lfd``
itself exports the main entry points the same way (``_ENTRY_POINTS``). Modules are
split and added while the API stays, so these checks hold the tables, the modules on
disk and docs/api.rst together, and each failure says what to change where:

* every exported name resolves, from the module its table names, where it is defined
  (not merely imported);
* docs/api.rst documents exactly the exported names: a section per sub-package
  (``drake_lfd.core`` ...) and the package's entry points;
* every module under drake_lfd/ is classified in docs/api.rst, "Internal modules": as a
  module that defines exported names or as one of the other modules (a module whose
  name starts with ``_`` is private by its name);
* importing a package loads none of its modules and no Drake, except
  ``drake_lfd.systems``, which loads ``typed_ports`` (and with it Drake) to install its
  connection check, as it always has.
"""

from __future__ import annotations

import ast
import importlib
import json
import re
import subprocess
import sys
from functools import cache
from pathlib import Path

import pytest

from drake_lfd.core._lazy import lazy_exports

REPOSITORY = Path(__file__).resolve().parent.parent
PACKAGE = REPOSITORY / "drake_lfd"
API_RST = REPOSITORY / "docs" / "api.rst"
LAYERS = ("core", "robot", "planning", "io", "systems", "diagrams", "experiments", "cli")

# The sub-packages whose import loads Drake: drake_lfd.systems installs
# typed_ports.install_connect_check when it is imported.
LOADS_DRAKE = {"drake_lfd.systems": ("drake_lfd.systems.typed_ports",)}

DEFINING_SECTION = "Modules that define exported names"
OTHER_SECTION = "Other modules"


def exports(layer: str) -> dict[str, str]:
    """The table of ``drake_lfd.<layer>``: exported name -> defining module."""
    return dict(importlib.import_module(f"drake_lfd.{layer}")._EXPORTS)


def disk_modules() -> dict[str, Path]:
    """Every module of the layers, from the files on disk: dotted name -> file."""
    return {f"drake_lfd.{layer}.{path.stem}": path
            for layer in LAYERS for path in sorted((PACKAGE / layer).glob("*.py")) if path.stem != "__init__"}


@cache
def defined_names(path: Path) -> frozenset[str]:
    """The names a module's source defines at its top level (def, class, assignment)."""
    names = set()
    for node in ast.parse(path.read_text(encoding="utf-8")).body:
        if isinstance(node, (ast.FunctionDef, ast.AsyncFunctionDef, ast.ClassDef)):
            names.add(node.name)
        elif isinstance(node, (ast.Assign, ast.AnnAssign)):
            targets = node.targets if isinstance(node, ast.Assign) else [node.target]
            for target in targets:
                names.update(n.id for n in ast.walk(target) if isinstance(n, ast.Name))
    return frozenset(names)


def definers(name: str, layer: str) -> list[str]:
    """The modules of ``drake_lfd.<layer>`` whose source defines ``name``."""
    return [module for module, path in disk_modules().items()
            if module.startswith(f"drake_lfd.{layer}.") and name in defined_names(path)]


def init_file(package: str) -> str:
    return "drake_lfd/__init__.py" if package == "drake_lfd" else f"drake_lfd/{package.split('.')[1]}/__init__.py"


# -- docs/api.rst, read as its directives say --------------------------------------------

_UNDERLINE = re.compile(r"^([=\-~^])\1+$")
_CONTEXT = re.compile(r"^\.\. (?:current)?module:: (\S+)$")


def api_sections(text: str) -> dict[str, list[str]]:
    """Section title -> the full names its ``autosummary`` blocks list, in order.

    An entry is resolved against the ``.. module::`` or ``.. currentmodule::`` in force
    (``core.tasks`` under ``drake_lfd`` is ``drake_lfd.core.tasks``); a leading ``~``
    only shortens what is shown.
    """
    lines = text.splitlines()
    sections: dict[str, list[str]] = {}
    title, context = "", ""
    index = 0
    while index < len(lines):
        line = lines[index]
        following = lines[index + 1] if index + 1 < len(lines) else ""
        if line.strip() and _UNDERLINE.match(following) and len(following) >= len(line.rstrip()):
            title = line.strip()
            sections.setdefault(title, [])
            index += 2
            continue
        match = _CONTEXT.match(line.strip())
        if match:
            context = match.group(1)
        elif line.strip() == ".. autosummary::":
            index += 1
            while index < len(lines) and (not lines[index].strip() or lines[index].startswith(" ")):
                entry = lines[index].strip()
                if entry and not entry.startswith(":"):
                    entry = entry.lstrip("~")
                    sections[title].append(entry if entry.startswith("drake_lfd.") else f"{context}.{entry}")
                index += 1
            continue
        index += 1
    return sections


@pytest.fixture(scope="module")
def sections():
    return api_sections(API_RST.read_text(encoding="utf-8"))


def entry_line(full: str, context: str) -> str:
    """How ``full`` is written in an autosummary whose context is ``context``."""
    return f"   {full[len(context) + 1:]}"


# -- the tables ---------------------------------------------------------------------------

@pytest.mark.parametrize("layer", LAYERS)
def test_all_is_the_table(layer):
    package = importlib.import_module(f"drake_lfd.{layer}")
    assert package.__all__ == list(package._EXPORTS), (
        f"{init_file(package.__name__)}: __all__ must be list(_EXPORTS), the one table of its exports")
    assert set(package.__all__) <= set(dir(package))


@pytest.mark.parametrize("layer", LAYERS)
def test_every_exported_name_is_defined_where_its_table_says(layer):
    package = importlib.import_module(f"drake_lfd.{layer}")
    here = f"{init_file(package.__name__)}, _EXPORTS"
    modules = disk_modules()
    problems = []
    for name, module in exports(layer).items():
        if module not in modules:
            found = definers(name, layer)
            problems.append(f"{here}[{name!r}] = {module!r}: there is no such module; "
                            + (f"{name} is defined in {found[0]}: write {found[0]!r}" if len(found) == 1
                               else f"{name} is defined in {found or 'no module of drake_lfd.' + layer}"))
            continue
        if name not in defined_names(modules[module]):
            found = definers(name, layer)
            problems.append(f"{here}[{name!r}] = {module!r}, but {module} does not define {name} "
                            + (f"(it is defined in {found[0]}): write {found[0]!r}" if len(found) == 1
                               else f"(defined in: {', '.join(found) or 'no module of drake_lfd.' + layer})"))
            continue
        value = getattr(package, name)
        assert value is getattr(importlib.import_module(module), name), (layer, name)
        home = getattr(value, "__module__", None) if isinstance(value, type) or callable(value) else None
        if home is not None and home != module:
            problems.append(f"{here}[{name!r}] = {module!r}, but {name}.__module__ is {home!r}")
    assert not problems, "\n".join(problems)


@pytest.mark.parametrize("layer", LAYERS)
def test_no_exported_name_is_a_module_name(layer):
    """``import drake_lfd.io.x`` sets the package's attribute ``x`` to the module, so an
    exported name ``x`` would change meaning once the module is imported."""
    clashes = sorted(set(exports(layer)) & {module.rpartition(".")[2] for module in disk_modules()
                                            if module.startswith(f"drake_lfd.{layer}.")})
    assert not clashes, (f"drake_lfd/{layer}/__init__.py exports {clashes}, also module names of "
                         f"drake_lfd.{layer}: leave them out of _EXPORTS (import them from their module)")


def test_the_entry_points_are_exported_by_their_sub_packages():
    import drake_lfd

    problems = []
    for name, module in drake_lfd._ENTRY_POINTS.items():
        layer = module.split(".")[1]
        table = exports(layer) if layer in LAYERS else {}
        if table.get(name) != module:
            problems.append(
                f"drake_lfd/__init__.py, _ENTRY_POINTS[{name!r}] = {module!r}, but drake_lfd/{layer}/__init__.py "
                + (f"exports {name} from {table[name]!r}: write {table[name]!r} in both" if name in table
                   else f"does not export {name}: add {name!r}: {module!r} to its _EXPORTS"))
        elif getattr(drake_lfd, name) is not getattr(importlib.import_module(f"drake_lfd.{layer}"), name):
            problems.append(f"drake_lfd.{name} is not drake_lfd.{layer}.{name}")
    assert not problems, "\n".join(problems)


def test_the_lazy_exports_refuse_modules_of_other_packages():
    with pytest.raises(ValueError, match="drake_lfd.robot.kinematics"):
        lazy_exports({"__name__": "drake_lfd.core"}, {"UR5eKinematics": "drake_lfd.robot.kinematics"})


def test_a_lazy_name_is_loaded_once_and_an_unknown_one_is_refused():
    namespace = {"__name__": "drake_lfd.core"}
    getattr_, dir_ = lazy_exports(namespace, {"Feature": "drake_lfd.core.features"})
    from drake_lfd.core.features import Feature

    assert "Feature" in dir_() and "Feature" not in namespace
    assert getattr_("Feature") is Feature and namespace["Feature"] is Feature
    with pytest.raises(AttributeError, match="module 'drake_lfd.core' has no attribute 'Nothing'"):
        getattr_("Nothing")


# -- docs/api.rst -------------------------------------------------------------------------

@pytest.mark.parametrize("layer", LAYERS)
def test_the_reference_documents_exactly_the_exports(sections, layer):
    package = f"drake_lfd.{layer}"
    title = f"``{package}``"
    assert title in sections, (
        f"docs/api.rst has no section {title}: add it (title, underline of -, '.. module:: {package}', "
        "a line on what it holds, and an '.. autosummary::' with ':toctree: _autosummary' listing its exports)")
    listed = sections[title]
    exported = [f"{package}.{name}" for name in exports(layer)]
    missing = [full for full in exported if full not in listed]
    extra = [full for full in listed if full not in exported]
    twice = sorted({full for full in listed if listed.count(full) > 1})
    problems = [f"docs/api.rst, section {title}: add '{entry_line(full, package)}' to its autosummary "
                f"({package} exports it)" for full in missing]
    problems += [f"docs/api.rst, section {title}: remove '{entry_line(full, package)}' from its autosummary "
                 f"({package}.__all__ does not list it)" for full in extra]
    problems += [f"docs/api.rst, section {title}: {full} is listed more than once" for full in twice]
    assert not problems, "\n".join(problems)


def test_the_reference_lists_the_entry_points(sections):
    import drake_lfd

    title = "``drake_lfd``"
    assert title in sections, "docs/api.rst has no section ``drake_lfd`` (the package's entry points)"
    expected = [f"drake_lfd.{module.split('.')[1]}.{name}" for name, module in drake_lfd._ENTRY_POINTS.items()]
    listed = sections[title]
    problems = [f"docs/api.rst, section {title}: add '{entry_line(full, 'drake_lfd')}' to its autosummary "
                f"(drake_lfd exports {full.rpartition('.')[2]})" for full in expected if full not in listed]
    problems += [f"docs/api.rst, section {title}: remove '{entry_line(full, 'drake_lfd')}' "
                 "(not an entry point of drake_lfd, _ENTRY_POINTS)" for full in listed if full not in expected]
    assert not problems, "\n".join(problems)


def test_every_module_is_classified_in_the_reference(sections):
    """A module that defines an exported name is listed under one heading of "Internal
    modules", every other module under the other; a new or split module must be put in
    one of them."""
    for title in (DEFINING_SECTION, OTHER_SECTION):
        assert title in sections, f"docs/api.rst has no section {title!r} (under 'Internal modules')"
    defining = {module for layer in LAYERS for module in exports(layer).values()}
    public = [module for module in disk_modules() if not module.rpartition(".")[2].startswith("_")]
    expected = {DEFINING_SECTION: [m for m in public if m in defining],
                OTHER_SECTION: [m for m in public if m not in defining]}
    problems = []
    for title, modules in expected.items():
        listed = sections[title]
        why = ("it defines names its sub-package exports" if title == DEFINING_SECTION
               else "it defines no exported name")
        problems += [f"docs/api.rst, Internal modules, {title!r}: add '{entry_line(m, 'drake_lfd')}' ({why})"
                     for m in modules if m not in listed]
        problems += [f"docs/api.rst, Internal modules, {title!r}: remove '{entry_line(m, 'drake_lfd')}' "
                     + ("(no such module)" if m not in disk_modules() else "(it belongs under the other heading)")
                     for m in listed if m not in modules]
    assert not problems, "\n".join(problems)


def test_the_reader_of_the_reference_follows_its_directives():
    text = """Title
=====

``drake_lfd.core``
------------------

.. module:: drake_lfd.core

.. autosummary::
   :toctree: _autosummary

   Task
   ~draw_trial

Internal modules
----------------

.. currentmodule:: drake_lfd

Other modules
~~~~~~~~~~~~~

.. autosummary::

   core.tool
   drake_lfd.core.errors
"""
    assert api_sections(text) == {
        "Title": [], "``drake_lfd.core``": ["drake_lfd.core.Task", "drake_lfd.core.draw_trial"],
        "Internal modules": [], "Other modules": ["drake_lfd.core.tool", "drake_lfd.core.errors"]}


# -- importing a package ------------------------------------------------------------------

_PROBE = """
import importlib, json, sys
importlib.import_module(sys.argv[1])
print(json.dumps({"pydrake": "pydrake" in sys.modules,
                  "loaded": sorted(m for m in sys.modules if m.split(".")[0] == "drake_lfd")}))
"""


@pytest.mark.parametrize("package", ["drake_lfd", *(f"drake_lfd.{layer}" for layer in LAYERS)])
def test_importing_a_package_loads_none_of_its_modules(package):
    done = subprocess.run([sys.executable, "-c", _PROBE, package], capture_output=True, text=True,
                          timeout=300, cwd=REPOSITORY)
    assert done.returncode == 0, done.stderr
    result = json.loads(done.stdout.strip().splitlines()[-1])
    allowed = {"drake_lfd", "drake_lfd.core", "drake_lfd.core._lazy", package, *LOADS_DRAKE.get(package, ())}
    extra = sorted(set(result["loaded"]) - allowed)
    assert not extra, (
        f"importing {package} loaded {', '.join(extra)}: {init_file(package)} must load its modules on "
        "first use only; name each export's module in _EXPORTS instead of importing it")
    assert result["pydrake"] == (package in LOADS_DRAKE), (
        f"importing {package} {'loaded' if result['pydrake'] else 'did not load'} pydrake")
