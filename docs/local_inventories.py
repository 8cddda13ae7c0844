"""Offline intersphinx inventories for the documentation build.

The API reference links to pydrake, Python and NumPy, but the build must not need the
network. This script writes Sphinx inventories (the ``objects.inv`` format) that
intersphinx reads from local files:

- ``pydrake.inv`` from the installed pydrake itself: every public module loaded by
  ``import pydrake.all``, its classes, templates and functions, and the classes'
  methods and properties, each pointing where drake.mit.edu documents it
  (``https://drake.mit.edu/pydrake/pydrake.math.html#pydrake.math.RigidTransform``);
- ``python.inv`` and ``numpy.inv``: the few builtins, standard-library and NumPy names
  that drake-lfd's signatures and docstrings use, written out below.

``docs/conf.py`` calls :func:`write_inventories` on every build, so the pydrake
inventory always matches the installed Drake. Run alone it writes into a directory::

    python docs/local_inventories.py OUT_DIR
"""

from __future__ import annotations

import inspect
import os
import sys
import tempfile
import zlib
from pathlib import Path

# (name, role, page#anchor) relative to https://docs.python.org/3/.
PYTHON_OBJECTS = [
    ("bool", "class", "library/functions.html#bool"),
    ("bytes", "class", "library/stdtypes.html#bytes"),
    ("dict", "class", "library/stdtypes.html#dict"),
    ("float", "class", "library/functions.html#float"),
    ("int", "class", "library/functions.html#int"),
    ("list", "class", "library/stdtypes.html#list"),
    ("object", "class", "library/functions.html#object"),
    ("set", "class", "library/stdtypes.html#set"),
    ("str", "class", "library/stdtypes.html#str"),
    ("tuple", "class", "library/stdtypes.html#tuple"),
    ("None", "data", "library/constants.html#None"),
    ("Exception", "exception", "library/exceptions.html#Exception"),
    ("KeyboardInterrupt", "exception", "library/exceptions.html#KeyboardInterrupt"),
    ("OSError", "exception", "library/exceptions.html#OSError"),
    ("TypeError", "exception", "library/exceptions.html#TypeError"),
    ("ValueError", "exception", "library/exceptions.html#ValueError"),
    ("argparse.ArgumentParser", "class", "library/argparse.html#argparse.ArgumentParser"),
    ("argparse.Namespace", "class", "library/argparse.html#argparse.Namespace"),
    ("collections.abc.Callable", "class", "library/collections.abc.html#collections.abc.Callable"),
    ("collections.abc.Iterable", "class", "library/collections.abc.html#collections.abc.Iterable"),
    ("collections.abc.Mapping", "class", "library/collections.abc.html#collections.abc.Mapping"),
    ("collections.abc.Sequence", "class", "library/collections.abc.html#collections.abc.Sequence"),
    ("dataclasses.dataclass", "function", "library/dataclasses.html#dataclasses.dataclass"),
    ("pathlib.Path", "class", "library/pathlib.html#pathlib.Path"),
    ("typing.Callable", "data", "library/typing.html#typing.Callable"),
    ("typing.Mapping", "class", "library/typing.html#typing.Mapping"),
    ("typing.NamedTuple", "class", "library/typing.html#typing.NamedTuple"),
    ("typing.Sequence", "class", "library/typing.html#typing.Sequence"),
    ("typing.Union", "data", "library/typing.html#typing.Union"),
]

# (name, role, page#anchor) relative to https://numpy.org/doc/stable/.
NUMPY_OBJECTS = [
    ("numpy", "module", "reference/index.html#module-numpy"),
    ("numpy.ndarray", "class", "reference/generated/numpy.ndarray.html#numpy.ndarray"),
    ("numpy.typing.ArrayLike", "data", "reference/typing.html#numpy.typing.ArrayLike"),
    ("numpy.typing.NDArray", "data", "reference/typing.html#numpy.typing.NDArray"),
    ("numpy.integer", "class", "reference/arrays.scalars.html#numpy.integer"),
    ("numpy.float64", "class", "reference/arrays.scalars.html#numpy.float64"),
    ("numpy.random.Generator", "class", "reference/random/generator.html#numpy.random.Generator"),
    ("numpy.random.default_rng", "function", "reference/random/generator.html#numpy.random.default_rng"),
]


def _inventory_bytes(project, version, entries):
    """The objects.inv bytes for ``entries`` of (name, domain:role, priority, uri)."""
    header = (
        "# Sphinx inventory version 2\n"
        f"# Project: {project}\n"
        f"# Version: {version}\n"
        "# The remainder of this file is compressed using zlib.\n"
    )
    body = "".join(f"{name} {role} {priority} {uri} -\n" for name, role, priority, uri in sorted(set(entries)))
    return header.encode("utf-8") + zlib.compress(body.encode("utf-8"))


def _is_template(value):
    from pydrake.common.cpp_template import TemplateBase

    return isinstance(value, TemplateBase)


def pydrake_entries():
    """Inventory entries of the installed pydrake (imports ``pydrake.all``)."""
    import pydrake.all  # noqa: F401 (loads every public module)

    entries = []
    module_names = sorted(
        name for name in sys.modules
        if (name == "pydrake" or name.startswith("pydrake."))
        and not any(part.startswith("_") for part in name.split("."))
        and name.split(".")[-1] != "all"
    )
    for module_name in module_names:
        module = sys.modules[module_name]
        if module is None:
            continue
        page = f"{module_name}.html"
        entries.append((module_name, "py:module", "0", f"{page}#module-{module_name}"))
        for name, value in sorted(vars(module).items()):
            if name.startswith("_"):
                continue
            full = f"{module_name}.{name}"
            defined_here = getattr(value, "__module__", None) == module_name
            if _is_template(value) and defined_here:
                entries.append((full, "py:class", "1", f"{page}#$"))
            elif inspect.isclass(value) and defined_here:
                entries.append((full, "py:class", "1", f"{page}#$"))
                for member_name, member in sorted(vars(value).items()):
                    if member_name.startswith("_") and member_name != "__init__":
                        continue
                    member_full = f"{full}.{member_name}"
                    if isinstance(member, property):
                        entries.append((member_full, "py:property", "1", f"{page}#$"))
                        entries.append((member_full, "py:attribute", "1", f"{page}#$"))
                    elif callable(member) or isinstance(member, (staticmethod, classmethod)):
                        entries.append((member_full, "py:method", "1", f"{page}#$"))
            elif callable(value) and defined_here:
                entries.append((full, "py:function", "1", f"{page}#$"))
    return entries


def _drake_version():
    from importlib.metadata import PackageNotFoundError, version

    try:
        return version("drake")
    except PackageNotFoundError:
        return "unknown"


def _write_atomically(path, data):
    fd, temporary = tempfile.mkstemp(prefix=f".{path.name}.", dir=path.parent)
    with os.fdopen(fd, "wb") as file:
        file.write(data)
    os.replace(temporary, path)


def write_inventories(directory):
    """Writes ``pydrake.inv``, ``python.inv`` and ``numpy.inv`` into ``directory``.

    Returns
    -------
    paths : dict
        ``{"pydrake": Path, "python": Path, "numpy": Path}``.
    """
    directory = Path(directory)
    directory.mkdir(parents=True, exist_ok=True)
    documents = {
        "pydrake": _inventory_bytes("pydrake", _drake_version(), pydrake_entries()),
        "python": _inventory_bytes(
            "Python", "3", [(name, f"py:{role}", "1", uri) for name, role, uri in PYTHON_OBJECTS]),
        "numpy": _inventory_bytes(
            "NumPy", "stable", [(name, f"py:{role}", "1", uri) for name, role, uri in NUMPY_OBJECTS]),
    }
    paths = {}
    for project, data in documents.items():
        path = directory / f"{project}.inv"
        _write_atomically(path, data)
        paths[project] = path
    return paths


if __name__ == "__main__":
    if len(sys.argv) != 2:
        sys.exit("usage: python docs/local_inventories.py OUT_DIR")
    for project, path in write_inventories(sys.argv[1]).items():
        print(f"{project}: {path}")
