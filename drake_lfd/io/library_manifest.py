"""A library's manifest, ``library.json``: its layout, its entries, read and written.

A library directory holds ``library.json`` (the manifest), ``demos/<name>.csv`` (one
joint log per demonstration), ``cache/features.sqlite`` (the derived feature cache) and
``library.lock`` (an empty file whose ``flock`` orders writers, ``file_lock.py``). The
manifest lists what the library holds and with which end-effector frame::

    {
      "schema_version": 1,
      "X_tool0_E": {"p": [0, 0, 0], "q_wxyz": [1, 0, 0, 0]},
      "demos": [
        {"name": "screw_cw", "file": "demos/screw_cw.csv", "samples": 501,
         "duration_s": 5.0, "description": "screw 90 deg clockwise",
         "added": "2025-01-31T12:00:00+00:00"}
      ]
    }

:func:`read_manifest` checks every field (unknown or missing keys, names, paths that
leave the directory, missing logs unless asked not to, repeated names ignoring case) and
reports the first problem as one :class:`~drake_lfd.core.errors.InputError` naming the file and the field;
:func:`write_manifest` replaces the file atomically. The format is documented for users
in docs/libraries.rst.

Not for: what the library does with its entries (adding, removing, features:
:mod:`drake_lfd.io.library`), the feature cache files (:mod:`drake_lfd.io.feature_cache`),
joint logs (:mod:`drake_lfd.io.demonstration_logs`).
"""

from __future__ import annotations

import contextlib
import dataclasses
import json
import math
import os
import re
from pathlib import Path
from typing import NamedTuple

from pydrake.math import RigidTransform

from drake_lfd.core.errors import HINT, Hint, InputError
from drake_lfd.core.resources import MANIFEST_NAME
from drake_lfd.io.atomic_files import atomic_write_bytes
from drake_lfd.io.pose_records import pose_json_from_rigid_transform, rigid_transform_from_pose_json

__all__ = [
    "SCHEMA_VERSION",
    "MANIFEST_NAME",
    "LOCK_NAME",
    "TEMPORARY_PATTERN",
    "DEMOS_DIRECTORY",
    "CACHE_DIRECTORY",
    "NAME_PATTERN",
    "MAX_NAME_LENGTH",
    "DemoEntry",
    "Manifest",
    "check_demo_name",
    "read_manifest_bytes",
    "read_manifest",
    "manifest_text",
    "write_manifest",
]

SCHEMA_VERSION = 1
# The library's lock file (empty; writers hold an exclusive flock on it).
LOCK_NAME = "library.lock"
# The temporary files of atomic writes (``atomic_files.atomic_write_bytes``), as a glob.
TEMPORARY_PATTERN = ".*.tmp"
DEMOS_DIRECTORY = "demos"
CACHE_DIRECTORY = "cache"
NAME_PATTERN = re.compile(r"[A-Za-z0-9_-]+\Z")  # \Z: a trailing newline is no match ($ allows one)
#: Longest demonstration name: its log ``demos/NAME.csv`` and the log's temporary
#: ``.NAME.csv.RANDOM.tmp`` must fit the 255 bytes of a file name.
MAX_NAME_LENGTH = 100

_MANIFEST_KEYS = ("schema_version", "X_tool0_E", "demos")
_ENTRY_KEYS = ("name", "file", "samples", "duration_s", "description", "added")


def check_demo_name(name):
    """Raises InputError unless ``name`` matches ``[A-Za-z0-9_-]+`` and has at most
    :data:`MAX_NAME_LENGTH` characters."""
    if not isinstance(name, str) or not NAME_PATTERN.match(name):
        shown = name if not isinstance(name, str) or len(name) <= 60 else name[:40] + "..."
        raise InputError(
            f"invalid demonstration name {shown!r}: use letters, digits, '_' and '-' only",
            field="name",
        )
    if len(name) > MAX_NAME_LENGTH:
        raise InputError(
            f"the demonstration name {name[:20]!r}... is too long ({len(name)} characters; at most {MAX_NAME_LENGTH}: "
            "it names the file demos/NAME.csv)",
            field="name",
        )


@dataclasses.dataclass(frozen=True)
class DemoEntry:
    """One demonstration as the manifest lists it.

    Attributes
    ----------
    name : str
    file : str
        Its joint log, relative to the library directory (``demos/<name>.csv``).
    samples : int
        Number of samples in the log.
    duration_s : float
        Time from first to last sample.
    description : str
    added : str
        When it was added, ISO 8601 UTC.
    """

    name: str
    file: str
    samples: int
    duration_s: float
    description: str
    added: str

    def to_json(self):
        return {key: getattr(self, key) for key in _ENTRY_KEYS}


class Manifest(NamedTuple):
    """What ``library.json`` says: the end-effector frame and the entries, in order.

    The frame is kept as the file writes it (``{"p": ..., "q_wxyz": ...}``) and written
    back unchanged: converting a pose to a ``RigidTransform`` and back can change its
    last digits, and the frame is part of every feature cache's key.
    """

    X_tool0_E_json: dict
    entries: tuple[DemoEntry, ...] = ()

    @classmethod
    def new(cls, X_tool0_E: RigidTransform) -> "Manifest":
        """The manifest of an empty library for this end-effector frame."""
        return cls(X_tool0_E_json=pose_json_from_rigid_transform(X_tool0_E))

    @property
    def X_tool0_E(self) -> RigidTransform:
        """The end-effector frame, as every reader of this manifest gets it."""
        return rigid_transform_from_pose_json(self.X_tool0_E_json, field="X_tool0_E")

    def with_entries(self, entries) -> "Manifest":
        return self._replace(entries=tuple(entries))


def _manifest_error(problem, manifest, field=None):
    return InputError(problem, file=manifest, field=field)


# A relative path already in normal form (no empty, "." or ".." part): the common case,
# checked without building a Path.
_PLAIN_RELATIVE = re.compile(r"^(?!\.\.?(?:/|$))[^/\0]+(?:/(?!\.\.?(?:/|$))[^/\0]+)*$")


def _folder(directory, parent, resolved):
    """What :func:`_inside` knows of one folder of the library, memoised in ``resolved``:
    ``None`` if the folder resolves outside ``directory``, else name -> (is a file, is a
    symbolic link) of its entries, from one ``scandir``."""
    if parent in resolved:
        return resolved[parent]
    root = resolved.get(None)
    if root is None:
        root = resolved[None] = directory.resolve()
    folder = None
    if (root / parent).resolve().is_relative_to(root):
        folder = {}
        with contextlib.suppress(OSError):
            with os.scandir(os.path.join(directory, parent)) as entries:
                for entry in entries:
                    with contextlib.suppress(OSError):
                        folder[entry.name] = (entry.is_file(), entry.is_symlink())
    resolved[parent] = folder
    return folder


def _inside(directory, file, resolved):
    """``(inside, is_file)``: whether ``directory / file`` (a relative path) resolves to a
    path inside ``directory``, and whether it is a file.

    ``resolved`` memoises the resolution and the listing of each folder (one per library
    in practice, :func:`_folder`), so a manifest of thousands of entries costs one
    ``resolve`` and one ``scandir`` per folder: only an entry that is itself a symbolic
    link is resolved on its own."""
    parent, _, base = file.rpartition("/")
    folder = _folder(directory, parent, resolved)
    if folder is None:
        return False, False
    is_file, is_link = folder.get(base, (False, False))
    if is_link:
        root = resolved[None]
        return (root / file).resolve().is_relative_to(resolved.get("links within", root)), is_file
    return True, is_file


def _parse_entry(value, index, directory, manifest, check_logs, resolved):
    field = f"demos[{index}]"
    if not isinstance(value, dict):
        raise _manifest_error("expected an object describing one demonstration", manifest, field)
    for key in value:
        if key not in _ENTRY_KEYS:
            raise _manifest_error(f"unknown key {key!r}", manifest, f"{field}.{key}")
    for key in _ENTRY_KEYS:
        if key not in value:
            raise _manifest_error("missing", manifest, f"{field}.{key}")
    name = value["name"]
    if not isinstance(name, str) or not NAME_PATTERN.match(name):
        raise _manifest_error(
            f"invalid demonstration name {name!r} (letters, digits, '_', '-')", manifest, f"{field}.name"
        )
    file = value["file"]
    if not isinstance(file, str) or not file:
        raise _manifest_error(f"expected a relative path, got {file!r}", manifest, f"{field}.file")
    if not _PLAIN_RELATIVE.match(file):
        relative = Path(file)
        if relative.is_absolute() or ".." in relative.parts or "\0" in file:
            raise _manifest_error(f"{file!r} is not a path inside the library directory", manifest, f"{field}.file")
        file = relative.as_posix()
    inside, is_file = _inside(directory, file, resolved)
    if not inside:
        raise _manifest_error(
            f"{value['file']!r} is not a path inside the library directory", manifest, f"{field}.file"
        )
    if check_logs and not is_file:
        raise InputError(
            f"the joint log {value['file']} is missing; restore it, or drop the entry with '{HINT}'",
            file=manifest,
            field=f"{field}.file",
            hints=(Hint("library remove", (str(directory), name)),),
        )
    samples = value["samples"]
    if isinstance(samples, bool) or not isinstance(samples, int) or samples < 2:
        raise _manifest_error(f"expected an integer >= 2, got {samples!r}", manifest, f"{field}.samples")
    duration = value["duration_s"]
    if isinstance(duration, bool) or not isinstance(duration, (int, float)) or not math.isfinite(duration) or duration < 0:
        raise _manifest_error(
            f"expected a finite number >= 0, got {duration!r}", manifest, f"{field}.duration_s"
        )
    for key in ("description", "added"):
        if not isinstance(value[key], str):
            raise _manifest_error(f"expected a string, got {value[key]!r}", manifest, f"{field}.{key}")
    return DemoEntry(
        name=name,
        file=file,
        samples=samples,
        duration_s=float(duration),
        description=value["description"],
        added=value["added"],
    )


def read_manifest_bytes(directory) -> bytes:
    """The bytes of ``directory/library.json``.

    Raises
    ------
    InputError
        It is missing (the directory is not a library) or cannot be read.
    """
    manifest = Path(directory) / MANIFEST_NAME
    if not manifest.is_file():
        raise InputError(f"not a drake-lfd library: {MANIFEST_NAME} is missing", file=directory)
    try:
        return manifest.read_bytes()
    except OSError as error:
        raise _manifest_error(f"cannot read: {error}", manifest) from None


def read_manifest(directory, *, check_logs=True, data=None, links_within=None) -> Manifest:
    """Reads and checks ``directory/library.json``.

    ``check_logs=False`` skips only the check that every entry's joint log exists (what
    ``library remove`` needs to drop an entry whose log was deleted by hand). ``data``:
    the file's bytes, when the caller has read them (:func:`read_manifest_bytes`).
    ``links_within``: a folder a log that is a symbolic link may resolve into (default:
    the library directory). A bundled library's logs are links into the scenarios'
    ``demos/``, so each bundled joint log is stored once (``sims/make_paper_libraries.py``).

    Raises
    ------
    InputError
        The manifest is missing (the directory is not a library), not valid JSON, or
        any field is wrong; naming the file and the field.
    """
    directory = Path(directory)
    manifest = directory / MANIFEST_NAME
    if data is None:
        data = read_manifest_bytes(directory)
    try:
        data = json.loads(data.decode("utf-8"))
    except json.JSONDecodeError as error:
        raise _manifest_error(
            f"not valid JSON ({error.msg})", manifest, f"line {error.lineno} column {error.colno}"
        ) from None
    except (UnicodeDecodeError, OSError) as error:
        raise _manifest_error(f"cannot read: {error}", manifest) from None
    if not isinstance(data, dict):
        raise _manifest_error("expected a JSON object", manifest)
    for key in data:
        if key not in _MANIFEST_KEYS:
            raise _manifest_error(f"unknown key {key!r}", manifest, str(key))
    for key in _MANIFEST_KEYS:
        if key not in data:
            raise _manifest_error("missing", manifest, key)
    version = data["schema_version"]
    if isinstance(version, bool) or version != SCHEMA_VERSION:
        raise _manifest_error(
            f"is {version!r}; this drake-lfd reads schema_version {SCHEMA_VERSION}",
            manifest,
            "schema_version",
        )
    rigid_transform_from_pose_json(data["X_tool0_E"], file=manifest, field="X_tool0_E")  # checks it
    if not isinstance(data["demos"], list):
        raise _manifest_error("expected a list", manifest, "demos")
    entries = []
    seen = {}
    resolved = {} if links_within is None else {"links within": Path(links_within).resolve()}
    for index, value in enumerate(data["demos"]):
        entry = _parse_entry(value, index, directory, manifest, check_logs, resolved)
        if entry.name.lower() in seen:
            raise _manifest_error(
                f"name {entry.name!r} repeats demos[{seen[entry.name.lower()]}]",
                manifest,
                f"demos[{index}].name",
            )
        seen[entry.name.lower()] = index
        entries.append(entry)
    return Manifest(X_tool0_E_json=data["X_tool0_E"], entries=tuple(entries))


# What ``json.dumps`` writes for a string (``ensure_ascii``), without its per-call overhead.
_json_string = json.encoder.encode_basestring_ascii


def _entry_text(entry):
    """An entry as ``json.dumps(entry.to_json(), indent=2)`` writes it, indented by 4 more
    spaces, built directly (the indenting encoder is pure Python: 10,000 entries took
    0.1 s)."""
    if not math.isfinite(entry.duration_s):
        raise ValueError(f"duration_s of {entry.name!r} is not finite: {entry.duration_s!r}")
    return (
        "    {\n"
        f'      "name": {_json_string(entry.name)},\n'
        f'      "file": {_json_string(entry.file)},\n'
        f'      "samples": {int(entry.samples)},\n'
        f'      "duration_s": {float(entry.duration_s)!r},\n'
        f'      "description": {_json_string(entry.description)},\n'
        f'      "added": {_json_string(entry.added)}\n'
        "    }"
    )


def manifest_text(manifest: Manifest) -> str:
    """The text of ``library.json`` (ends with a newline), strict JSON.

    Raises
    ------
    ValueError
        A number is not finite (a manifest never holds one: entries come from checked
        demonstrations, and :func:`read_manifest` would refuse it).
    """
    # json.dumps(indent=2) would put every number of the pose on its own line;
    # this layout keeps the pose on one line and each entry as an indented block.
    demos = ",\n".join(_entry_text(entry) for entry in manifest.entries)
    return (
        "{\n"
        f'  "schema_version": {SCHEMA_VERSION},\n'
        f'  "X_tool0_E": {json.dumps(manifest.X_tool0_E_json, allow_nan=False)},\n'
        + ('  "demos": [\n' + demos + "\n  ]\n" if manifest.entries else '  "demos": []\n')
        + "}\n"
    )


def write_manifest(directory, manifest: Manifest):
    """Replaces ``directory/library.json`` atomically (old or new, never half of one);
    returns the bytes written."""
    data = manifest_text(manifest).encode("utf-8")
    atomic_write_bytes(Path(directory) / MANIFEST_NAME, data)
    return data
