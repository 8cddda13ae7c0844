"""A package's exported names, each loaded from its module on first use (PEP 562).

``drake_lfd`` and each of its sub-packages keep one table, name -> the module that
defines it, and hand it to :func:`lazy_exports`; the package's ``__getattr__`` imports a
name's module the first time the name is looked up, so importing a package loads none
of its modules (and no Drake) until a name is used. A table may name only modules of
its own package, so a package's exports never import from a layer above it.
"""

from __future__ import annotations

import importlib
from collections.abc import Callable, Mapping
from typing import Any

__all__ = ["lazy_exports"]


def lazy_exports(
    namespace: dict[str, Any], exports: Mapping[str, str]
) -> tuple[Callable[[str], Any], Callable[[], list[str]]]:
    """The ``__getattr__`` and ``__dir__`` of a package whose names load on first use.

    Parameters
    ----------
    namespace : dict
        The package's ``globals()``; a loaded name is stored there, so it is looked up
        once.
    exports : mapping of str to str
        Exported name -> dotted name of the module that defines it, a module of the
        package itself (``"drake_lfd.core.tasks"`` in ``drake_lfd.core``).

    Returns
    -------
    (__getattr__, __dir__)
        To assign at the package's top level.

    Raises
    ------
    ValueError
        When a module in ``exports`` is not in the package.
    """
    package = str(namespace["__name__"])
    table = dict(exports)
    outside = sorted({module for module in table.values() if not module.startswith(package + ".")})
    if outside:
        raise ValueError(f"{package} may export only names of its own modules, not of {', '.join(outside)}")

    def __getattr__(name: str) -> Any:
        module = table.get(name)
        if module is None:
            raise AttributeError(f"module {package!r} has no attribute {name!r}")
        value = getattr(importlib.import_module(module), name)
        namespace[name] = value
        return value

    def __dir__() -> list[str]:
        return sorted(set(namespace) | set(table))

    return __getattr__, __dir__
