"""Checks of command-line values shared by the ``drake-lfd`` commands.

Each raises an :class:`~drake_lfd.core.errors.InputError` naming the option, so the command
exits with status 2 and one line.
"""

from __future__ import annotations

from pathlib import Path

from drake_lfd.core.errors import InputError

__all__ = ['require_at_least', 'require_seed', 'require_folder_of']


def require_at_least(value: int, least: int, option: str) -> int:
    """``value`` if it is at least ``least``."""
    if value < least:
        raise InputError(f"must be at least {least}, got {value}", field=option)
    return value


def require_seed(value: int, option: str = "--seed") -> int:
    """A non-negative seed."""
    if value < 0:
        raise InputError("must be a non-negative integer", field=option)
    return value


def require_folder_of(path: str | Path | None, option: str) -> None:
    """The folder a file will be written into must exist (nothing to check for None)."""
    if path and not Path(path).resolve().parent.is_dir():
        raise InputError("folder does not exist", file=str(Path(path).parent), field=option)
