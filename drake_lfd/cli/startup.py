"""A command's start: its heavy modules load once its input has been checked.

Every ``drake-lfd`` command module is plain Python at import, so ``--version``,
``--help``, a bad flag and a task file's structure are answered before Drake is
imported; the command then imports Drake and the rest of drake-lfd inside
:func:`interrupts_deferred`, so an interrupt during that import is one line, not
Drake's stack. Not for: anything else about a command.
"""

from __future__ import annotations

import contextlib
import signal

__all__ = ["interrupts_deferred"]


@contextlib.contextmanager
def interrupts_deferred():
    """Ctrl-C and SIGTERM wait until the block is done, then interrupt. For a command's
    heavy imports: an interrupt inside pydrake's native initialisation makes Drake log a
    40-line stack of its own before Python sees it.

    Example::

        with interrupts_deferred():
            from drake_lfd.io.task_files import load_task
    """
    received = []
    try:
        previous = {signum: signal.signal(signum, lambda number, frame: received.append(number))
                    for signum in (signal.SIGINT, signal.SIGTERM)}
    except (ValueError, OSError):  # not the main thread: nothing to defer
        yield
        return
    try:
        yield
    finally:
        for signum, handler in previous.items():
            signal.signal(signum, handler)
    if received:
        raise KeyboardInterrupt
