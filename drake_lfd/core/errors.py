"""Errors users can act on, and the exit codes the command line maps them to.

Every problem with user input (a task file, a demonstration log, a library) is raised
as an :class:`InputError` that names the file, the field and what is wrong; the command
line prints it as one line and exits with status 2, never a traceback.

An error whose fix is a command carries it as a :class:`Hint` (the command and its
arguments) in ``error.hints`` rather than as prose: a program can act on it, and the text
shows it as the command line spells it (``str(hint)``).

Not for: programming errors inside the package, such as a pose that is not a unit dual
quaternion handed to a core function; those raise ValueError.
"""

from __future__ import annotations

import dataclasses
import os

__all__ = [
    "EXIT_OK",
    "EXIT_FAILURE",
    "EXIT_BAD_INPUT",
    "EXIT_DEMONSTRATION_REQUESTED",
    "EXIT_NO_EXECUTABLE_PLAN",
    "HINT",
    "Hint",
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


@dataclasses.dataclass(frozen=True)
class Hint:
    """A command that fixes (or works around) the problem of an :class:`InputError`.

    Parameters
    ----------
    command : str
        The ``drake-lfd`` subcommand, words separated by spaces (``"library remove"``);
        empty for options alone (the ones to add to the command that was run).
    args : tuple of str
        Its arguments and options in order, as one would type them (placeholders such
        as ``DIR`` in capitals).
    """

    command: str
    args: tuple[str, ...] = ()

    def __str__(self) -> str:
        """The command as the command line spells it (``drake-lfd library remove LIB NAME``),
        or the options alone when there is no command."""
        words = (f"drake-lfd {self.command}",) if self.command else ()
        return " ".join((*words, *self.args))


#: Where a hint goes in a problem's text (``f"... with '{HINT}'"``), the first for the
#: first hint and so on: a control character no file name or field a user writes holds,
#: so text quoted from a user's file is never taken for one.
HINT = "\x1f"


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
    hints : sequence of Hint, optional
        Commands that fix the problem; ``problem`` says where each goes (:data:`HINT`,
        one per hint in order), and ``self.problem`` is the text with them written out.
    """

    def __init__(
        self, problem: str, *, file: str | os.PathLike[str] | None = None, field: str | None = None,
        hints: tuple[Hint, ...] | list[Hint] = (),
    ) -> None:
        self.file = None if file is None else str(file)
        self.field = field
        self.hints = tuple(hints)
        if self.hints:
            parts = problem.split(HINT)
            if len(parts) == len(self.hints) + 1:  # (a mismatch is a slip of the caller's: text kept)
                problem = parts[0] + "".join(str(hint) + part for hint, part in zip(self.hints, parts[1:]))
        self.problem = problem
        parts = [p for p in (self.file, field, problem) if p]
        super().__init__(": ".join(parts))
