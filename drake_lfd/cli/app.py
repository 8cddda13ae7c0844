"""The ``drake-lfd`` command line: a thin argparse front end over the library.

Each command lives in its own module exposing ``add_parser(subparsers)``, which
registers a subparser whose ``func(args) -> int`` does the work. This module only wires
them together and turns errors into the exit codes of docs/cli.rst: 2 for bad input
(one line on stderr, no traceback), 3 for a demonstration request, 1 for anything else.
"""

from __future__ import annotations

import argparse
import importlib
import sys

from drake_lfd import __version__
from drake_lfd.core.errors import EXIT_BAD_INPUT, EXIT_FAILURE, InputError

__all__ = ['build_parser', 'main']

# Modules that each add one subcommand, in the order --help lists them. A module that
# is missing (a later issue not yet shipped) is simply skipped.
_COMMAND_MODULES = (
    "drake_lfd.cli.record",
    "drake_lfd.cli.library",
    "drake_lfd.cli.train",
    "drake_lfd.cli.plan",
    "drake_lfd.cli.simulate",
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
    subparsers = parser.add_subparsers(dest="command", metavar="COMMAND")
    for module_name in _COMMAND_MODULES:
        try:
            module = importlib.import_module(module_name)
        except ModuleNotFoundError as error:
            if error.name == module_name:
                continue
            raise
        module.add_parser(subparsers)
    for command_parser in _parsers_of(parser):  # every command's --help shows the defaults
        command_parser.formatter_class = HelpFormatter
    return parser


def main(argv: list[str] | None = None) -> int:
    parser = build_parser()
    args = parser.parse_args(argv)
    if not getattr(args, "func", None):
        parser.print_help()
        return EXIT_BAD_INPUT
    try:
        return int(args.func(args) or 0)
    except InputError as error:
        print(f"drake-lfd {args.command}: error: {error}", file=sys.stderr)
        return EXIT_BAD_INPUT
    except KeyboardInterrupt:
        print(f"drake-lfd {args.command}: interrupted", file=sys.stderr)
        return EXIT_FAILURE


if __name__ == "__main__":
    sys.exit(main())
