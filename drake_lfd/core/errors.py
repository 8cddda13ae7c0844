"""Errors users can act on, and the exit codes the command line maps them to.

Every problem with user input (a task file, a demonstration log, a library) is raised
as an :class:`InputError` that names the file, the field and what is wrong; the command
line prints it as one line and exits with status 2, never a traceback.

Not for: programming errors inside the package, such as a pose that is not a unit dual
quaternion handed to a core function; those raise ValueError.
"""

from __future__ import annotations

import os

__all__ = [
    "EXIT_OK",
    "EXIT_FAILURE",
    "EXIT_BAD_INPUT",
    "EXIT_DEMONSTRATION_REQUESTED",
    "EXIT_NO_EXECUTABLE_PLAN",
    "InputError",
]

#: Command-line exit status: success.
EXIT_OK = 0
#: Command-line exit status: the command stopped without success (for example interrupted).
EXIT_FAILURE = 1
#: Command-line exit status: an :class:`InputError`.
EXIT_BAD_INPUT = 2
#: Command-line exit status: no composition covers the task; a demonstration is requested.
EXIT_DEMONSTRATION_REQUESTED = 3
#: Command-line exit status: demonstrations cover the task but no composition is
#: executable by the robot (reach, joint limits, singularity, collision).
EXIT_NO_EXECUTABLE_PLAN = 4


class InputError(Exception):
    """Bad user input. ``str(error)`` is one line: ``file: field: problem``.

    Parameters
    ----------
    problem : str
        What is wrong, as a sentence fragment.
    file : str or path-like, optional
        The file that holds the input.
    field : str, optional
        The field within it.
    """

    def __init__(
        self, problem: str, *, file: str | os.PathLike[str] | None = None, field: str | None = None
    ) -> None:
        self.file = None if file is None else str(file)
        self.field = field
        self.problem = problem
        parts = [p for p in (self.file, field, problem) if p]
        super().__init__(": ".join(parts))
