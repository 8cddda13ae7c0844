"""Type checks at ``DiagramBuilder.Connect`` for abstract ports that carry Python objects.

Drake checks an abstract connection by the C++ type of the two ports' model values: a
``RigidTransform`` output cannot feed a ``QueryObject`` input. Every Python object,
though, travels as the one C++ type ``Value[object]``, so Drake lets a
:class:`~drake_lfd.systems.feature_library.LibraryFeatures` output feed a
:class:`~drake_lfd.core.tasks.ConcreteTask` input; the mistake only shows (if at all)
when the receiving system finds the wrong object in its input during a simulation.

The project's systems declare every abstract port with a model value of its real type
(an instance of the class the port carries; a port that has nothing to say yet carries a
typed "nothing yet" value of that class, such as
:data:`~drake_lfd.systems.demo_recorder.NO_DEMONSTRATION`). :func:`install_connect_check`
(called when ``drake_lfd.systems`` is imported) wraps ``DiagramBuilder.Connect`` so that
it also compares the Python classes of the two model values: the output's class must be
the input's class or a subclass of it, otherwise ``Connect`` raises as Drake does for C++
types. Ports whose model value is a plain ``object()`` (anything goes) and vector or
C++-typed ports are left to Drake.

Not for: declaring ports (the systems' modules).
"""

from __future__ import annotations

import functools

from pydrake.common.value import AbstractValue, Value
from pydrake.systems.framework import DiagramBuilder, InputPort, OutputPort, PortDataType

__all__ = ["python_value_type", "check_abstract_connection", "install_connect_check"]

_PY_OBJECT_VALUE = Value[object]


def python_value_type(model: AbstractValue) -> type | None:
    """The Python class a ``Value[object]`` model value holds, or None.

    None for a C++-typed value (Drake checks those itself) and for a plain ``object()``
    model value, which declares a port that takes anything.
    """
    if type(model) is not _PY_OBJECT_VALUE:
        return None
    value_type = type(model.get_value())
    return None if value_type is object else value_type


def check_abstract_connection(src: OutputPort, dest: InputPort) -> None:
    """Raises when ``src`` and ``dest`` are abstract ports of unrelated Python classes.

    Raises
    ------
    RuntimeError
        ``src`` puts out objects of a class that is not ``dest``'s class or a subclass.
    """
    if src.get_data_type() != PortDataType.kAbstractValued or dest.get_data_type() != PortDataType.kAbstractValued:
        return
    output_type = python_value_type(src.Allocate())
    input_type = python_value_type(dest.Allocate())
    if output_type is None or input_type is None or issubclass(output_type, input_type):
        return
    raise RuntimeError(
        f"DiagramBuilder::Connect: Mismatched value types while connecting output port {src.get_name()} of "
        f"System {src.get_system().get_name()} (type {_qualified_name(output_type)}) to input port "
        f"{dest.get_name()} of System {dest.get_system().get_name()} (type {_qualified_name(input_type)})"
    )


def _qualified_name(value_type: type) -> str:
    return f"{value_type.__module__}.{value_type.__qualname__}"


def install_connect_check() -> None:
    """Makes ``DiagramBuilder.Connect`` (of ``float`` diagrams) check Python-typed ports
    with :func:`check_abstract_connection` before connecting; installing twice is a no-op."""
    connect = DiagramBuilder.Connect
    if getattr(connect, "_drake_lfd_checked", False):
        return

    @functools.wraps(connect)
    def checked_connect(self, src, dest):
        if isinstance(src, OutputPort) and isinstance(dest, InputPort):
            check_abstract_connection(src, dest)
        return connect(self, src, dest)

    checked_connect._drake_lfd_checked = True
    DiagramBuilder.Connect = checked_connect
