"""Checks of command-line values shared by the ``drake-lfd`` commands.

Each raises an :class:`~drake_lfd.core.errors.InputError` naming the option, so the command
exits with status 2 and one line. :func:`prepare_output` is the one place that decides how
an output path is made ready (missing folders created, writability checked), for every
command, before the command does any work.
"""

from __future__ import annotations

import os
import tempfile
from pathlib import Path

from drake_lfd.core.errors import InputError

__all__ = [
    'require_at_least', 'require_seed', 'prepare_output', 'require_folder_of', 'require_writable_folder',
    'library_help', 'require_meshcat',
]


def library_help(what: str = "library directory") -> str:
    """Help text of a ``--library LIB`` option, naming the bundled libraries."""
    from drake_lfd.core.resources import bundled_library_names

    names = ", ".join(bundled_library_names()) or "none installed"
    return f"{what}, or the name of a bundled library ({names})"


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


def _make_folder(folder: Path, path: Path, option: str) -> None:
    """``mkdir -p folder``, or one-line refusal naming what is in the way."""
    try:
        folder.mkdir(parents=True, exist_ok=True)
    except OSError as error:
        blocking = next((p for p in (folder, *folder.parents) if p.exists() and not p.is_dir()), None)
        reason = f"{blocking} is a file" if blocking is not None else (error.strerror or str(error))
        raise InputError(f"cannot create the folder {folder}: {reason}", file=str(path), field=option) from None


def require_writable_folder(folder: Path, path: Path, option: str) -> None:
    """Refuses (one line) a folder in which a file cannot be created: creates and removes
    a small temporary file there, the way every write of drake-lfd starts (an atomic
    write creates its temporary file beside the target), so read-only file systems,
    permissions and special folders are all caught, also for root."""
    try:
        fd, probe = tempfile.mkstemp(prefix=".drake-lfd-write-check.", suffix=".tmp", dir=folder)
    except OSError as error:
        reason = error.strerror or str(error)
        raise InputError(f"cannot write into the folder {folder}: {reason}", file=str(path), field=option) from None
    os.close(fd)
    try:
        os.unlink(probe)
    except OSError:
        pass


def require_meshcat(what: str, *, optional: bool = True) -> None:
    """Refuses ``what`` (an option such as ``--html``, or a command) with one line, exit
    2, when ``DRAKE_ALLOW_NETWORK`` disables Drake's Meshcat, which a recording needs
    (:mod:`drake_lfd.core.network_policy`); before any work is done."""
    from drake_lfd.core.network_policy import meshcat_refusal

    refusal = meshcat_refusal(what, optional=optional)
    if refusal is not None:
        raise InputError(refusal, field=what if optional else None)


def prepare_output(path: str | Path | None, option: str, *, folder: bool = False) -> Path | None:
    """Makes an output path of a command ready to be written, before any work is done.

    The one rule every ``drake-lfd`` command follows for what it writes (docs/cli.rst):
    missing folders are created (``mkdir -p``): for a file (``--json OUT``, ``--html``,
    ``train --out POLICY``, ...) the folders it goes into, for a folder (``simulate
    --figures DIR``, ``paper --out DIR``) the folder itself. It refuses, with an
    :class:`InputError` (one line, exit 2), only when that cannot be done: a file is
    asked for where a folder exists, a folder where a file exists, creating a folder
    fails (a file in the way, no permission), or a file cannot be created in the folder
    (:func:`require_writable_folder`: read-only, no permission, a special folder such as
    ``/proc``), or the file's name is too long for the file system. An existing path that
    is neither a file nor a folder (a device such as ``/dev/stdout``, a named pipe) is
    only checked for write permission: it is written into, not replaced.

    Parameters
    ----------
    path : str or Path or None
        The option's value; None (option not given) and ``-`` (stdout) are left alone.
    option : str
        The option, for the error message (``--json``).
    folder : bool
        ``path`` names a folder to write into rather than a file.

    Returns
    -------
    Path or None
        ``path`` as a Path (None when it was None or ``-``).
    """
    if path is None or str(path) in ("", "-"):
        return None
    path = Path(path)
    if folder:
        if path.exists() and not path.is_dir():
            raise InputError("exists and is not a folder", file=str(path), field=option)
        _make_folder(path, path, option)
        require_writable_folder(path, path, option)
        return path
    if path.is_dir():
        raise InputError("is a folder; give the path of the file to write", file=str(path), field=option)
    if path.exists() and not path.is_file():  # a device or a pipe (/dev/stdout): written into directly
        if not os.access(path, os.W_OK):
            raise InputError("cannot be written (no permission)", file=str(path), field=option)
        return path
    _make_folder(path.parent, path, option)
    require_writable_folder(path.parent, path, option)
    _require_name_fits(path, option)
    return path


def _require_name_fits(path: Path, option: str) -> None:
    """The file's name, and its atomic write's temporary name, fit the file system."""
    try:
        limit = os.pathconf(path.parent, "PC_NAME_MAX")
    except (OSError, ValueError):
        limit = 255
    # atomic writes use ".NAME.XXXXXXXX.tmp" (io/atomic_files.py)
    if len(os.fsencode(path.name)) + 14 > limit:
        raise InputError(f"the file name is too long ({len(path.name)} characters; at most {limit - 14} here)",
                         file=str(path)[:80] + "...", field=option)


def require_folder_of(path: str | Path | None, option: str) -> None:
    """The folder a file will be written into exists afterwards: :func:`prepare_output`
    for a file (kept for older callers)."""
    prepare_output(path, option)
