"""The ``drake-lfd`` command line: a thin argparse front end over the library.

Each command lives in its own module exposing ``add_parser(subparsers)``, which
registers a subparser whose ``func(args) -> int`` does the work. This module only wires
them together and turns every way a command can end into one line and the exit codes of
docs/cli.rst: 2 for bad input (an :class:`~drake_lfd.core.errors.InputError`, or a file
or folder named on the command line that cannot be read or written: missing, no
permission, read-only, a name too long), 3 for a demonstration request, 1 for anything
else: a fault of the machine (a full disk), an interrupt (Ctrl-C or SIGTERM, from the
first import on) or an internal error (one line; the traceback only with ``--debug``).
A reader that stops reading (``drake-lfd library show paper5 | head``) ends the command
quietly.
"""

from __future__ import annotations

import argparse
import errno
import importlib
import os
import re
import signal
import sys

from drake_lfd import __version__
from drake_lfd.core.errors import EXIT_BAD_INPUT, EXIT_FAILURE, InputError

__all__ = ['build_parser', 'main', 'describe_os_error', 'USER_PATH_ERRNOS']

#: OSError numbers that mean a path the user named cannot be used (exit 2); any other
#: OSError (a full disk, an I/O error) is a fault of the machine (exit 1).
USER_PATH_ERRNOS = frozenset({
    errno.ENOENT, errno.ENOTDIR, errno.EISDIR, errno.EEXIST, errno.EACCES, errno.EPERM, errno.EROFS,
    errno.ENAMETOOLONG, errno.ELOOP, errno.ENOTEMPTY,
})
# The temporary file of an atomic write (io/atomic_files.py): ".NAME.RANDOM.tmp".
_TEMPORARY_NAME = re.compile(r"^\.(?P<name>.+)\.[A-Za-z0-9_]+\.tmp$")

# Modules that each add one subcommand, in the order --help lists them. Each is plain
# Python at import (argparse, the standard library, drake_lfd's light modules), so
# --version, --help and a bad flag answer before Drake is imported; a command imports
# its heavy modules in its run function, once its input has been checked. A module that
# cannot be imported is an error of the installation, raised as it is.
_COMMAND_MODULES = (
    "drake_lfd.cli.record",
    "drake_lfd.cli.library",
    "drake_lfd.cli.train",
    "drake_lfd.cli.plan",
    "drake_lfd.cli.simulate",
    "drake_lfd.cli.sweep",
    "drake_lfd.cli.export",
    "drake_lfd.cli.paper",
    "drake_lfd.cli.show_model",
)


class HelpFormatter(argparse.HelpFormatter):
    """argparse's formatter, with each option's default after its help text
    (``(default: 20)``) unless the text already speaks of its default; options without
    a default (None, an empty text, or a flag's False) show none."""

    def _get_help_string(self, action):
        text = action.help or ""
        default = action.default
        if (not action.option_strings or default is None or default is False or default == ""
                or default is argparse.SUPPRESS or "default" in text):
            return text
        return f"{text} (default: %(default)s)"


def _parsers_of(parser: argparse.ArgumentParser):
    """``parser`` and every (sub)command parser below it."""
    yield parser
    for action in parser._actions:
        if isinstance(action, argparse._SubParsersAction):
            for subparser in action.choices.values():
                yield from _parsers_of(subparser)


def build_parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(
        prog="drake-lfd",
        description=(
            "Plan UR5e motions for new tasks by composing kinesthetic demonstrations "
            "(Yu & Chang), simulated closed loop in Drake."
        ),
    )
    parser.add_argument("--version", action="version", version=f"drake-lfd {__version__}")
    parser.add_argument("--debug", action="store_true",
                        help="show the Python traceback of an internal error")
    subparsers = parser.add_subparsers(dest="command", metavar="COMMAND")
    for module_name in _COMMAND_MODULES:
        importlib.import_module(module_name).add_parser(subparsers)
    for command_parser in _parsers_of(parser):  # every command's --help shows the defaults
        command_parser.formatter_class = HelpFormatter
        if command_parser is not parser and "--debug" not in command_parser._option_string_actions:
            command_parser.add_argument("--debug", action="store_true", default=argparse.SUPPRESS,
                                        help="show the Python traceback of an internal error")
    return parser


def describe_os_error(error: OSError) -> str:
    """``FILE: what went wrong`` for an OSError, naming the file the user asked for (not
    the temporary file of an atomic write)."""
    problem = error.strerror or str(error)
    filename = error.filename
    if filename is None:
        return problem
    path = os.fsdecode(filename)
    match = _TEMPORARY_NAME.match(os.path.basename(path))
    if match:
        path = os.path.join(os.path.dirname(path), match.group("name"))
    if len(path) > 160:
        path = path[:80] + "..." + path[-40:]
    return f"{path}: {problem}"


def _caused_by_interrupt(error: BaseException) -> bool:
    """Whether ``error`` was raised while handling, or because of, a KeyboardInterrupt."""
    seen = set()
    while error is not None and id(error) not in seen:
        if isinstance(error, KeyboardInterrupt):
            return True
        seen.add(id(error))
        error = error.__cause__ or error.__context__
    return False


_INTERRUPTED = False


def _interrupted(command: str, argv) -> int:
    """Says ``COMMAND: interrupted``; the exit status of an interrupt."""
    global _INTERRUPTED
    _INTERRUPTED = True
    if argv is None:  # the console command: a second Ctrl-C must not interrupt the exit
        _ignore_further_interrupts()
    _say(f"{command}: interrupted")
    return EXIT_FAILURE


def _raise_interrupt(signum, frame):
    raise KeyboardInterrupt


def _ignore_further_interrupts() -> None:
    for signum in (signal.SIGINT, signal.SIGTERM):
        try:
            signal.signal(signum, signal.SIG_IGN)
        except (ValueError, OSError):  # not the main thread
            pass


def _say(line: str) -> None:
    """Prints one line on stderr; a closed stderr is ignored."""
    try:
        print(line, file=sys.stderr, flush=True)
    except (OSError, ValueError):
        pass


def _silence_stdout() -> None:
    """After a broken pipe: point stdout at /dev/null so the interpreter's last flush
    does not fail again."""
    try:
        devnull = os.open(os.devnull, os.O_WRONLY)
        os.dup2(devnull, sys.stdout.fileno())
    except (OSError, ValueError, AttributeError):
        pass


def main(argv: list[str] | None = None) -> int:
    """Runs one ``drake-lfd`` command; returns its exit status (docs/cli.rst)."""
    global _INTERRUPTED
    _INTERRUPTED = False
    try:
        previous_sigterm = signal.signal(signal.SIGTERM, _raise_interrupt)  # SIGTERM behaves like Ctrl-C
    except (ValueError, OSError):  # not the main thread (main() called by a test or a tool)
        previous_sigterm = None
    try:
        status = _run(argv)
    finally:
        if previous_sigterm is not None:
            try:
                signal.signal(signal.SIGTERM, previous_sigterm)
            except (ValueError, OSError, TypeError):
                pass
    if argv is None and _INTERRUPTED:
        # The console command was interrupted. If the interrupt went through an embedded
        # interpreter call (pybind11 importing pydrake), Python would end the process by
        # SIGINT instead of this status; exit here, everything already closed and said.
        for stream in (sys.stdout, sys.stderr):
            try:
                stream.flush()
            except (OSError, ValueError):
                pass
        os._exit(status)
    return status


def _run(argv: list[str] | None) -> int:
    command = "drake-lfd"
    debug = "--debug" in (sys.argv[1:] if argv is None else argv)
    try:
        parser = build_parser()  # plain Python: each command loads Drake once its input is checked
        args = parser.parse_args(argv)
        debug = getattr(args, "debug", False)
        if not getattr(args, "func", None):
            parser.print_help()
            return EXIT_BAD_INPUT
        command = f"drake-lfd {args.command}"
        return int(args.func(args) or 0)
    except InputError as error:
        _say(f"{command}: error: {' '.join(str(error).splitlines())}")  # one line, whatever the message
        return EXIT_BAD_INPUT
    except KeyboardInterrupt:
        return _interrupted(command, argv)
    except BrokenPipeError:
        _silence_stdout()
        return EXIT_FAILURE
    except OSError as error:
        if debug:
            raise
        _say(f"{command}: error: {describe_os_error(error)}")
        return EXIT_BAD_INPUT if error.errno in USER_PATH_ERRNOS else EXIT_FAILURE
    except SystemExit:
        raise
    except Exception as error:  # an internal error: one line, the traceback with --debug
        if _caused_by_interrupt(error):  # pybind11 turns Ctrl-C inside an import into ImportError
            return _interrupted(command, argv)
        if debug:
            raise
        text = " ".join(str(error).split())
        if len(text) > 300:
            text = text[:297] + "..."
        _say(f"{command}: internal error: {type(error).__name__}: {text} (run with --debug for the traceback)")
        return EXIT_FAILURE


if __name__ == "__main__":
    sys.exit(main())
