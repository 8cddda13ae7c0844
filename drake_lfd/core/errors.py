"""Errors users can act on, and the exit codes the command line maps them to.

Every problem with user input (a task file, a demonstration log, a library) is raised
as an :class:`InputError` that names the file, the field and what is wrong; the command
line prints it as one line and exits with status 2, never a traceback.
"""

from __future__ import annotations

EXIT_OK = 0
EXIT_FAILURE = 1
EXIT_BAD_INPUT = 2
EXIT_DEMONSTRATION_REQUESTED = 3


class InputError(Exception):
    """Bad user input. ``str(error)`` is one line: ``file: field: problem``."""

    def __init__(self, problem: str, *, file: str | None = None, field: str | None = None):
        self.file = None if file is None else str(file)
        self.field = field
        self.problem = problem
        parts = [p for p in (self.file, field, problem) if p]
        super().__init__(": ".join(parts))
