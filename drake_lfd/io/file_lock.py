"""Advisory file locks (``fcntl.flock``): writers of one directory take turns.

A lock is a file (a library's ``library.lock``) that holds nothing: the lock is the
``flock`` on it. :func:`exclusive_lock` is for writers (a read-modify-write of a
manifest and the files it lists), :func:`shared_lock` for readers that must see a
writer's change whole or not at all. The kernel drops a lock when its holder exits,
``kill -9`` included, so a crashed writer never leaves a library locked; the lock file
itself stays (it is empty and harmless).

Locks are advisory: they order the processes that take them (every drake-lfd command),
not other programs. Within one process a lock already held is not taken again (a
nested request for the same file passes through), since a second ``flock`` on a new
file descriptor of the same file would wait for the process itself.

Not for: what is written under the lock (``library.py``), atomic replacement of a file
(``atomic_files.py``).
"""

from __future__ import annotations

import contextlib
import errno
import fcntl
import os
from pathlib import Path

__all__ = ["LockUnavailable", "exclusive_lock", "shared_lock"]

# Lock file path (absolute) -> (flock mode, nesting depth) of the locks this process holds.
_held: dict[str, list] = {}


class LockUnavailable(OSError):
    """The lock file cannot be created or opened (read-only directory, permissions)."""


@contextlib.contextmanager
def _locked(path, mode, *, create):
    key = os.path.abspath(path)
    held = _held.get(key)
    if held is not None:
        if mode == fcntl.LOCK_EX and held[0] != fcntl.LOCK_EX:
            raise RuntimeError(f"{path}: cannot upgrade a shared lock to an exclusive one")
        held[1] += 1
        try:
            yield True
        finally:
            held[1] -= 1
        return
    flags = (os.O_RDWR | os.O_CREAT) if create else os.O_RDONLY
    try:
        fd = os.open(key, flags | getattr(os, "O_CLOEXEC", 0), 0o644)
    except FileNotFoundError:
        if create:
            raise LockUnavailable(errno.ENOENT, "the directory does not exist", key) from None
        yield False  # nobody ever wrote here under a lock: nothing to wait for
        return
    except OSError as error:
        if not create:
            yield False
            return
        raise LockUnavailable(error.errno, error.strerror, key) from None
    try:
        fcntl.flock(fd, mode)  # waits for the holder; the kernel frees it if the holder dies
        _held[key] = [mode, 1]
        try:
            yield True
        finally:
            del _held[key]
            fcntl.flock(fd, fcntl.LOCK_UN)
    finally:
        os.close(fd)


def exclusive_lock(path):
    """Context manager: holds the exclusive lock on ``path`` (created if missing, mode
    0644), waiting for any other holder.

    Raises
    ------
    LockUnavailable
        The lock file cannot be created or opened for writing.
    """
    return _locked(Path(path), fcntl.LOCK_EX, create=True)


def shared_lock(path):
    """Context manager: holds a shared lock on ``path`` if that file exists and can be
    opened (yields True), else does nothing (yields False). Never creates a file, so a
    reader writes nothing, and a read-only (bundled) directory is read without a lock."""
    return _locked(Path(path), fcntl.LOCK_SH, create=False)
