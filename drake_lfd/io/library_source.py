"""A library given in any form, as its features: :func:`resolve_features`.

Scripts name a library the way the command line does (a library folder or a bundled
library's name such as ``"paper5"``), or hand over an opened
:class:`~drake_lfd.io.library.Library` or the features themselves;
``drake_lfd.plan_task`` and ``drake_lfd.build_pipeline`` accept each.

Not for: reading or editing a library (``library.py``).
"""

from __future__ import annotations

from collections.abc import Mapping
from os import PathLike

from drake_lfd.core.features import Feature
from drake_lfd.core.tasks import ConcreteTask, Task
from drake_lfd.io.library import Library, check_end_effector_frame, library_features

__all__ = ["resolve_features"]


def resolve_features(library: Mapping[str, Feature] | Library | str | PathLike,
                     task: ConcreteTask | Task | None = None) -> Mapping[str, Feature]:
    """The features (name -> Feature) of ``library``: a mapping as it is, or those of a
    :class:`~drake_lfd.io.library.Library`, opened first when given as a folder or a
    bundled name. A library's end-effector frame is checked against ``task``'s
    (:func:`~drake_lfd.io.library.check_end_effector_frame`); a bare mapping carries no
    frame to check.

    Raises
    ------
    TypeError
        ``library`` is none of these.
    drake_lfd.core.errors.InputError
        No such library, or its end-effector frame differs from the task's.
    """
    if isinstance(library, Mapping):
        return library
    if isinstance(library, (str, PathLike)):
        library = Library.open(library)
    if not isinstance(library, Library):
        raise TypeError("library must be a Mapping[str, Feature], a Library, a library folder or a bundled "
                        f"library name, got {type(library).__name__}")
    if task is not None:
        check_end_effector_frame(library, task.X_tool0_E, file=task.file)
    return library_features(library)
