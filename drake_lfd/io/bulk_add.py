"""Many joint logs added to a library at once: found, read, checked, written in batches,
with a typed report of what was added and what was refused and why.

:func:`add_logs` is what :meth:`Library.add_many <drake_lfd.io.library.Library.add_many>`,
:meth:`Library.create_many <drake_lfd.io.library.Library.create_many>` and ``drake-lfd
library add LIB DIR_OR_GLOB...`` run. Each log is named after its file's stem, read
(:func:`~drake_lfd.io.log_import.read_demonstration_log`) and prepared
(:mod:`~drake_lfd.io.demo_preparation`) before the library is touched; the prepared
ones are written :data:`BULK_BATCH` at a time, one turn of the library's lock each
(other writers wait at most one batch, and a killed bulk add keeps the batches before).
A new library is created with its first batch in the same turn of the lock
(``Library.create(path, X_tool0_E, first=...)``), so a killed create leaves no library.
Every valid log is added; each other one is refused with a kind (:data:`REFUSAL_KINDS`)
and a reason, never half-added.

Not for: reading a log's formats (:mod:`drake_lfd.io.log_import`), the library's files
(:mod:`drake_lfd.io.library`), printing (the command line prints the report).
"""

from __future__ import annotations

import dataclasses
import glob
import os
from collections.abc import Callable, Sequence
from pathlib import Path

from drake_lfd.core.errors import InputError
from drake_lfd.io.demo_preparation import DemonstrationPreparer, PreparedDemo
from drake_lfd.io.library_manifest import MANIFEST_NAME, DemoEntry, check_demo_name
from drake_lfd.io.log_import import check_time_window, read_demonstration_log
from drake_lfd.io.rosbag_logs import bag_location, is_bag

__all__ = [
    "BULK_BATCH",
    "LOG_SUFFIXES",
    "NOT_FOUND",
    "BAD_NAME",
    "REPEATED_NAME",
    "NAME_TAKEN",
    "BAD_LOG",
    "REFUSAL_KINDS",
    "LogReadOptions",
    "AddedLog",
    "RefusedLog",
    "AddManyReport",
    "find_logs",
    "add_logs",
]

# Prepared demonstrations per turn of the library's lock (each turn one manifest write):
# other writers wait at most one batch, and a killed bulk add keeps the batches before.
BULK_BATCH = 500
# Suffixes of the log files a folder is searched for (ROS 2 bags are directories).
LOG_SUFFIXES = (".csv", ".bag")

# Why a log of a bulk add was refused (the kinds a summary counts).
NOT_FOUND = "not found"
BAD_NAME = "file name not a demonstration name"
REPEATED_NAME = "name repeated in this add"
NAME_TAKEN = "name already in the library"
BAD_LOG = "log refused"
REFUSAL_KINDS = (NOT_FOUND, BAD_NAME, REPEATED_NAME, NAME_TAKEN, BAD_LOG)


@dataclasses.dataclass(frozen=True)
class LogReadOptions:
    """How each log is read (:func:`~drake_lfd.io.log_import.read_demonstration_log`):
    ``keep_all_rows`` skips the ``runtime_state`` filter; a bag's ``rate_hz`` and
    ``topic``; the time window ``start_s``/``end_s``; an RTDE log's ``tcp_offset``
    check."""

    keep_all_rows: bool = False
    rate_hz: float | None = None
    topic: str | None = None
    start_s: float | None = None
    end_s: float | None = None
    tcp_offset: object = None


@dataclasses.dataclass(frozen=True)
class AddedLog:
    """A log that was added: where it was read, its entry, and what reading it said
    (warnings about the log, and the import's reports, in order)."""

    path: Path
    entry: DemoEntry
    warnings: tuple[str, ...] = ()
    reports: tuple[str, ...] = ()


@dataclasses.dataclass(frozen=True)
class RefusedLog:
    """A log (or an argument that named nothing) that was not added: its ``kind`` (one of
    :data:`REFUSAL_KINDS`) and the ``reason``, one line."""

    path: Path | str
    kind: str
    reason: str


@dataclasses.dataclass(frozen=True)
class AddManyReport:
    """What a bulk add did.

    Attributes
    ----------
    library : Library or None
        The library added to; None when it was to be created and no log was accepted
        (then nothing was created).
    added : tuple of AddedLog
        In the order the logs were found.
    refused : tuple of RefusedLog
        The arguments that named nothing first, then the logs in the order they were
        refused.
    logs : int
        How many logs were named (found ones and arguments that named nothing).
    """

    library: object
    added: tuple[AddedLog, ...]
    refused: tuple[RefusedLog, ...]
    logs: int

    def refusal_counts(self) -> dict[str, int]:
        """Kind -> number of refused logs, in the order the kinds first occurred."""
        counts: dict[str, int] = {}
        for refusal in self.refused:
            counts[refusal.kind] = counts.get(refusal.kind, 0) + 1
        return counts


def _logs_in_folder(folder):
    """The logs directly in ``folder``, sorted: its ``*.csv`` and ``*.bag`` files and ROS 2
    bag directories."""
    found = []
    for child in sorted(folder.iterdir()):
        if child.is_dir() and is_bag(child):
            found.append(child)
        elif child.is_file() and child.suffix.lower() in LOG_SUFFIXES and not child.name.startswith("."):
            found.append(child)
    return found


def find_logs(arguments):
    """The logs the DEMO arguments of a bulk add name, in order, each once.

    Parameters
    ----------
    arguments : sequence of str
        Log files (a ROS 2 bag directory counts as one), folders (their ``*.csv`` and
        ``*.bag`` files and ROS 2 bag directories, not their subfolders) and glob patterns (``*``,
        ``?``, ``[``; ``**`` reaches into subfolders), whose matches are taken the same way.

    Returns
    -------
    logs : list of Path
    missing : list of str
        Arguments that name nothing.
    """
    logs, missing, seen = [], [], set()

    def take(path):
        if path.is_dir() and not is_bag(path):
            for log in _logs_in_folder(path):
                take(log)
            return
        key = os.path.realpath(path)
        if key not in seen:
            seen.add(key)
            logs.append(path)

    for argument in arguments:
        argument = str(argument)
        path = Path(argument)
        if path.exists():
            take(path)
        elif glob.has_magic(argument):
            matches = sorted(glob.glob(argument, recursive=True))
            for match in matches:
                take(Path(match))
            if not matches:
                missing.append(argument)
        else:
            missing.append(argument)
    return logs, missing


def _log_name(path):
    """A bulk-added log's demonstration name: its file's stem (a ROS 2 bag: its directory's
    name)."""
    location = bag_location(path)
    if location is not None and location.is_dir():
        return location.name
    return path.stem


def _reason(error, path):
    """An error's text without the log's own name in front (the refusal names it), on one
    line (a parser's message may span several, as the single add flattens too)."""
    text = str(error)
    prefix = f"{path}: "
    text = text[len(prefix):] if text.startswith(prefix) else text
    return " ".join(text.splitlines())


class _BulkAdd:
    """The state of one bulk add: the library (None until the first log is accepted, when
    a new one is created at ``new_path``), what was added and refused, and what waits."""

    def __init__(self, library, new_path, X_tool0_E_new, description, options):
        self.library = library
        self.new_path = new_path
        self.X_tool0_E_new = X_tool0_E_new
        self.description = description
        self.options = options
        X_tool0_E = X_tool0_E_new if library is None else library.X_tool0_E
        label = Path(new_path).absolute() if library is None else library.label
        if library is None:
            self.preparer = DemonstrationPreparer(X_tool0_E, label)
        else:
            self.preparer = DemonstrationPreparer(X_tool0_E, label, library.num_samples, library.rotation_length_m)
        self.added: list[AddedLog] = []
        self.refused: list[RefusedLog] = []
        self.pending: list[tuple[Path, PreparedDemo, tuple, tuple]] = []  # (path, prepared, warnings, reports)

    def refuse(self, path, kind, reason):
        self.refused.append(RefusedLog(path, kind, reason))

    def commit(self):
        """Adds the pending demonstrations in one turn of the library's lock."""
        from drake_lfd.io.library import Library

        if not self.pending:
            return
        added = refused = None
        pending = [item for _, item, _, _ in self.pending]
        if self.library is None and len({item.entry.name.lower() for item in pending}) == len(pending):
            try:  # the library and its first batch in one step: killed, it leaves no library
                self.library = Library.create(self.new_path, self.X_tool0_E_new, first=pending)
                added, refused = [item.entry for item in pending], []
            except InputError:
                if not (Path(self.new_path) / MANIFEST_NAME).is_file():
                    raise  # (made a library meanwhile by another process: added to below)
        if self.library is None:
            self.library = Library.open_or_create(self.new_path, self.X_tool0_E_new)
        if added is None:
            added, refused = self.library.add_prepared(pending)
        taken = {position for position, _ in refused}
        for position, error in refused:
            self.refuse(self.pending[position][0], NAME_TAKEN, _reason(error, self.library.label))
        entries = iter(added)
        for position, (path, _, warnings, reports) in enumerate(self.pending):
            if position not in taken:
                self.added.append(AddedLog(path, next(entries), tuple(warnings), tuple(reports)))
        self.pending = []

    def read(self, path, names, existing):
        """Reads and checks one log; a valid one joins ``pending``."""
        name = _log_name(path)
        try:
            check_demo_name(name)
        except InputError as error:
            self.refuse(path, BAD_NAME, f"{error.problem}; rename the file, or add it alone with --name NAME")
            return
        if name.lower() in names:
            self.refuse(path, REPEATED_NAME, f"its name {name!r} is also the name of {names[name.lower()]}; "
                                             "rename one of the files, or add it alone with --name NAME")
            return
        if name.lower() in existing:
            self.refuse(path, NAME_TAKEN, f"the library has a demonstration named {name!r} already; remove it "
                                          "first, or rename the file")
            return
        options = self.options
        try:
            demonstration, warnings, reports = read_demonstration_log(
                path, name=name, description=self.description, filter_runtime_state=not options.keep_all_rows,
                rate_hz=options.rate_hz, topic=options.topic, start_s=options.start_s, end_s=options.end_s,
                tcp_offset=options.tcp_offset,
            )
            prepared = self.preparer.prepare(demonstration, name, self.description, source=path)
        except InputError as error:
            self.refuse(path, BAD_LOG, _reason(error, path))
            return
        names[name.lower()] = path
        self.pending.append((path, prepared, warnings, reports))


def add_logs(
    target,
    paths: Sequence[str | os.PathLike],
    description: str = "",
    *,
    X_tool0_E=None,
    options: LogReadOptions = LogReadOptions(),
    progress: Callable[[int, int, int, int], None] | None = None,
    before_adding: Callable[[object], None] | None = None,
    batch: int = BULK_BATCH,
) -> AddManyReport:
    """Adds every log ``paths`` name to a library, each named after its file's stem.

    Parameters
    ----------
    target : Library, str or Path
        An opened library, what :meth:`Library.open` takes, or (with ``X_tool0_E``) the
        directory of a new library, created with the first batch of accepted logs.
    paths : sequence of str or Path
        Log files, folders and glob patterns (:func:`find_logs`).
    description : str
        Every added demonstration's description.
    X_tool0_E : RigidTransform, optional
        The end-effector frame of a new library (only then).
    options : LogReadOptions
    progress : callable, optional
        ``progress(done, total, accepted, refused)``: once before the first log (``done``
        0) and after each log, with the counts of logs accepted (added or waiting for
        their batch) and refused so far.
    before_adding : callable, optional
        Called with the opened library (an existing one) before any log is read: a front
        end's own checks, which raise to stop.
    batch : int
        Prepared logs per turn of the library's lock.

    Returns
    -------
    AddManyReport

    Raises
    ------
    InputError
        The time window is invalid, ``paths`` name no log at all, the library cannot be
        opened or is read-only (bundled): nothing is added then. Refusals of single logs
        are in the report instead.
    """
    from drake_lfd.io.library import Library

    check_time_window(options.start_s, options.end_s)
    logs, missing = find_logs(paths)
    if not logs:
        raise InputError(
            f"found no logs in {', '.join(str(path) for path in paths)} (a folder's *.csv and *.bag files and "
            "ROS 2 bag directories are added; give files, folders or glob patterns)",
            field="DEMO",
        )
    if X_tool0_E is not None:
        library = None
    else:
        library = target if isinstance(target, Library) else Library.open(target)
    bulk = _BulkAdd(library, target if library is None else None, X_tool0_E, description, options)
    existing = set()
    if library is not None:
        if library.read_only:
            library.check_writable()  # a bundled library: refused, with the hint to copy it
        if before_adding is not None:
            before_adding(library)
        existing = {name.lower() for name in library.names}
    for argument in missing:
        bulk.refuse(argument, NOT_FOUND, "no such file or directory, and no file matches it")
    names = {}
    if progress is not None:
        progress(0, len(logs), 0, len(bulk.refused))
    for done, path in enumerate(logs, start=1):
        bulk.read(path, names, existing)
        if len(bulk.pending) >= batch:
            bulk.commit()
        if progress is not None:
            progress(done, len(logs), len(bulk.added) + len(bulk.pending), len(bulk.refused))
    bulk.commit()
    return AddManyReport(bulk.library, tuple(bulk.added), tuple(bulk.refused), len(logs) + len(missing))
