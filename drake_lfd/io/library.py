"""The demonstration library ``LB = {HD_1, ..., HD_k}`` (Eq. 14), kept as a directory.

A library is a folder a user can read and back up with ordinary tools::

    LIB/
      library.json          the manifest (below); the list of what the library holds
      demos/<name>.csv      one joint log per demonstration, the project's RTDE-style CSV
      cache/<name>.npz      resampled poses and feature per demonstration (derived data)

``library.json``::

    {
      "schema_version": 1,
      "X_tool0_E": {"p": [0, 0, 0], "q_wxyz": [1, 0, 0, 0]},
      "demos": [
        {"name": "screw_cw", "file": "demos/screw_cw.csv", "samples": 501,
         "duration_s": 5.0, "description": "screw 90 deg clockwise",
         "added": "2025-01-31T12:00:00+00:00"}
      ]
    }

The joint logs are the source of truth. Features depend on the end-effector frame, so
the library stores the one its demonstrations were recorded with (``X_tool0_E``) and
planning a task with another frame is refused (:func:`check_end_effector_frame`).
Features are computed by forward kinematics (with ``X_WB`` = identity: features do not
depend on where the robot stands) and cached in ``cache/``; a cache file carries a hash
of the log's bytes, ``X_tool0_E``, the feature parameters and the source of the code that
computes features, and is recomputed and rewritten whenever that hash differs or the file
is missing or unreadable.

Durability: every file is written atomically (``atomic_files.atomic_write_bytes``: a
temporary file in the same directory, flushed and fsynced, ``os.replace``, then the
directory fsynced). ``add`` writes the log before the manifest that references it,
``remove`` rewrites the manifest before deleting the log. A crash therefore leaves at worst an unreferenced log (ignored, overwritten by
a later ``add`` of that name), never a manifest pointing at a missing or partial log.
Concurrent writers are not coordinated: do not run two ``add``/``remove`` at once on one
library.

Names: ``Library.open`` takes a path to an existing directory, else the name of a
library bundled with drake-lfd (``drake_lfd/sims/libraries/<name>/`` when installed,
``sims/libraries/<name>/`` in a checkout). Bundled libraries opened by name are
read-only. Demonstration names match ``[A-Za-z0-9_-]+`` and are unique ignoring case (so
their log files do not collide on case-insensitive file systems).

Not for: reading foreign log formats (``demonstrations.py``), comparing features
(``similarity.py``), the command line (``cli_library.py``).
"""

from __future__ import annotations

import dataclasses
import datetime
import functools
import hashlib
import io
import json
import math
import re
from pathlib import Path

import numpy as np
from pydrake.math import RigidTransform

from drake_lfd.core import dual_quaternion as _dual_quaternion_module
from drake_lfd.core import features as _features_module
from drake_lfd.robot import kinematics as _kinematics_module
from drake_lfd.io.atomic_files import atomic_write_bytes, fsync_directory
from drake_lfd.io.demonstration_logs import (
    Demonstration,
    check_demonstration,
    dual_quaternions_from_demonstration,
    read_rtde_csv,
    rtde_csv_text,
)
from drake_lfd.core.errors import InputError
from drake_lfd.core.features import (
    DEFAULT_NUM_SAMPLES,
    DEFAULT_ROTATION_LENGTH_M,
    Feature,
    arc_lengths_from_poses,
)
from drake_lfd.core.resources import bundled_library_directories, models_directory
from drake_lfd.robot.kinematics import shared_kinematics
from drake_lfd.io.pose_records import pose_json_from_rigid_transform, rigid_transform_from_pose_json

SCHEMA_VERSION = 1
MANIFEST_NAME = "library.json"
DEMOS_DIRECTORY = "demos"
CACHE_DIRECTORY = "cache"
NAME_PATTERN = re.compile(r"^[A-Za-z0-9_-]+$")
# Two end-effector frames closer than this (max abs difference of the 4x4 matrices)
# are the same frame written twice; anything more changes the features.
END_EFFECTOR_FRAME_TOLERANCE = 1e-9
# A demonstration whose tool path is shorter than this (arc length in metres, rotation
# counted as in features.py) does not move and has no feature worth matching.
MIN_MOTION_LENGTH = 1e-6
# Bump when the cache file's layout changes.
_CACHE_FORMAT = "drake-lfd-feature-cache-1"

_MANIFEST_KEYS = ("schema_version", "X_tool0_E", "demos")
_ENTRY_KEYS = ("name", "file", "samples", "duration_s", "description", "added")


def _make_directory(path):
    if not path.is_dir():
        path.mkdir(parents=True, exist_ok=True)
        fsync_directory(path.parent)


# ---------------------------------------------------------------------- bundled names


def bundled_library_names():
    """Names of the libraries bundled with drake-lfd (sorted; may be empty)."""
    names = set()
    for directory in bundled_library_directories():
        if directory.is_dir():
            names.update(p.name for p in directory.iterdir() if (p / MANIFEST_NAME).is_file())
    return sorted(names)


# ------------------------------------------------------------------------------ names


def check_demo_name(name):
    """Raises InputError unless ``name`` matches ``[A-Za-z0-9_-]+``."""
    if not isinstance(name, str) or not NAME_PATTERN.match(name):
        raise InputError(
            f"invalid demonstration name {name!r}: use letters, digits, '_' and '-' only",
            field="name",
        )


# ----------------------------------------------------------------------------- cache


@functools.lru_cache(maxsize=1)
def _code_fingerprint():
    """Hash of everything besides the log that decides a feature's numbers."""
    digest = hashlib.sha256()
    for path in (
        Path(_features_module.__file__),
        Path(_dual_quaternion_module.__file__),
        Path(_kinematics_module.__file__),
        models_directory() / "ur5e" / "ur5e.urdf",
    ):
        digest.update(path.read_bytes())
    return digest.hexdigest()


def _cache_key(log_bytes, X_tool0_E, num_samples, rotation_length_m):
    digest = hashlib.sha256()
    digest.update(_CACHE_FORMAT.encode())
    digest.update(hashlib.sha256(log_bytes).digest())
    digest.update(np.ascontiguousarray(X_tool0_E.GetAsMatrix4(), dtype=float).tobytes())
    digest.update(repr((int(num_samples), float(rotation_length_m))).encode())
    digest.update(_code_fingerprint().encode())
    return digest.hexdigest()


_FEATURE_FIELDS = tuple(field.name for field in dataclasses.fields(Feature))


def _feature_npz_bytes(key, feature):
    arrays = {"key": np.array(key)}
    for name in _FEATURE_FIELDS:
        value = getattr(feature, name)
        if value is not None:
            arrays[name] = np.asarray(value)
    buffer = io.BytesIO()
    np.savez(buffer, **arrays)
    return buffer.getvalue()


def _feature_from_npz(path, key):
    """The cached feature if ``path`` holds one for ``key``, else None."""
    try:
        with np.load(path, allow_pickle=False) as data:
            if str(data["key"]) != key:
                return None
            values = {}
            for name in _FEATURE_FIELDS:
                values[name] = np.array(data[name]) if name in data.files else None
    except (OSError, ValueError, KeyError, EOFError):
        return None
    for value in values.values():
        if value is not None:
            value.flags.writeable = False
    try:
        return Feature(**values)
    except (TypeError, ValueError):
        return None


# --------------------------------------------------------------------------- library


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


def _manifest_error(problem, manifest, field=None):
    return InputError(problem, file=manifest, field=field)


def _parse_entry(value, index, directory, manifest):
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
    relative = Path(file)
    root = directory.resolve()
    if relative.is_absolute() or ".." in relative.parts or not (root / relative).resolve().is_relative_to(root):
        raise _manifest_error(
            f"{file!r} is not a path inside the library directory", manifest, f"{field}.file"
        )
    if not (directory / relative).is_file():
        raise _manifest_error(f"the joint log {file} is missing", manifest, f"{field}.file")
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
        file=relative.as_posix(),
        samples=samples,
        duration_s=float(duration),
        description=value["description"],
        added=value["added"],
    )


class Library:
    """A demonstration library directory (Eq. 14). Use :meth:`open` or :meth:`create`.

    Attributes
    ----------
    path : Path
        The library directory (absolute).
    label : str
        How to name it to a user: the bundled name, or the absolute path.
    read_only : bool
        True for a bundled library opened by name.
    X_tool0_E : RigidTransform
        The end-effector frame the demonstrations' features are computed for.
    num_samples, rotation_length_m
        Feature parameters (``features.Feature.from_poses``).
    """

    def __init__(
        self,
        *,
        path,
        X_tool0_E,
        entries,
        label,
        read_only,
        num_samples=DEFAULT_NUM_SAMPLES,
        rotation_length_m=DEFAULT_ROTATION_LENGTH_M,
    ):
        self.path = Path(path).resolve()
        self.X_tool0_E = RigidTransform(X_tool0_E)
        self._entries = list(entries)
        self.label = label
        self.read_only = read_only
        self.num_samples = int(num_samples)
        self.rotation_length_m = float(rotation_length_m)
        self._features = {}

    # -- opening ---------------------------------------------------------------------
    @classmethod
    def open(cls, path_or_name, **feature_parameters):
        """Opens a library directory, or a bundled library by name (read-only).

        Parameters
        ----------
        path_or_name : str or Path
            A path to an existing library directory; otherwise a bundled library name.
        **feature_parameters
            ``num_samples``, ``rotation_length_m`` (defaults from ``features.py``).

        Raises
        ------
        InputError
            Neither exists (the message lists what was tried), or the manifest is
            corrupt (naming the field).
        """
        candidate = Path(path_or_name)
        if candidate.is_dir():
            return cls._load(candidate, label=str(candidate.resolve()), read_only=False, **feature_parameters)
        if candidate.exists():
            raise InputError("is a file, not a library directory", file=path_or_name)
        name = str(path_or_name)
        looked_in = []
        if NAME_PATTERN.match(name):
            for directory in bundled_library_directories():
                if (directory / name / MANIFEST_NAME).is_file():
                    return cls._load(directory / name, label=name, read_only=True, **feature_parameters)
                looked_in.append(str(directory))
        bundled = ", ".join(bundled_library_names()) or "none"
        tried = f"no directory {candidate.resolve()}"
        if looked_in:
            tried += f", and no bundled library of that name in {' or '.join(looked_in)}"
        raise InputError(f"no such library: {tried} (bundled libraries: {bundled})", file=name)

    @classmethod
    def _load(cls, directory, *, label, read_only, **feature_parameters):
        directory = Path(directory)
        manifest = directory / MANIFEST_NAME
        if not manifest.is_file():
            raise InputError(f"not a drake-lfd library: {MANIFEST_NAME} is missing", file=directory)
        try:
            data = json.loads(manifest.read_text(encoding="utf-8"))
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
        X_tool0_E = rigid_transform_from_pose_json(data["X_tool0_E"], file=manifest, field="X_tool0_E")
        if not isinstance(data["demos"], list):
            raise _manifest_error("expected a list", manifest, "demos")
        entries = []
        seen = {}
        for index, value in enumerate(data["demos"]):
            entry = _parse_entry(value, index, directory, manifest)
            if entry.name.lower() in seen:
                raise _manifest_error(
                    f"name {entry.name!r} repeats demos[{seen[entry.name.lower()]}]",
                    manifest,
                    f"demos[{index}].name",
                )
            seen[entry.name.lower()] = index
            entries.append(entry)
        return cls(
            path=directory,
            X_tool0_E=X_tool0_E,
            entries=entries,
            label=label,
            read_only=read_only,
            **feature_parameters,
        )

    @classmethod
    def create(cls, path, X_tool0_E=None, **feature_parameters):
        """Creates an empty library directory (the directory may exist if empty).

        Parameters
        ----------
        path : str or Path
        X_tool0_E : RigidTransform, optional
            The end-effector frame of the demonstrations to come; identity by default.

        Raises
        ------
        InputError
            ``path`` is a file, a library already, or a non-empty directory.
        """
        directory = Path(path)
        if directory.exists():
            if not directory.is_dir():
                raise InputError("exists and is not a directory", file=path)
            if (directory / MANIFEST_NAME).exists():
                raise InputError("is a library already", file=path)
            if any(directory.iterdir()):
                raise InputError("exists and is not empty; choose a new directory for a library", file=path)
        _make_directory(directory)
        _make_directory(directory / DEMOS_DIRECTORY)
        _make_directory(directory / CACHE_DIRECTORY)
        library = cls(
            path=directory,
            X_tool0_E=RigidTransform() if X_tool0_E is None else X_tool0_E,
            entries=[],
            label=str(directory.resolve()),
            read_only=False,
            **feature_parameters,
        )
        library._write_manifest(library._entries)
        return library

    # -- reading ---------------------------------------------------------------------
    @property
    def manifest_path(self) -> Path:
        return self.path / MANIFEST_NAME

    @property
    def names(self):
        """Demonstration names in the order they were added, tuple of str."""
        return tuple(entry.name for entry in self._entries)

    @property
    def entries(self):
        """The manifest's entries, tuple of :class:`DemoEntry`."""
        return tuple(self._entries)

    def __len__(self):
        return len(self._entries)

    def __contains__(self, name):
        return any(entry.name == name for entry in self._entries)

    def entry(self, name):
        """The :class:`DemoEntry` of ``name``; InputError listing the names if absent."""
        for entry in self._entries:
            if entry.name == name:
                return entry
        known = ", ".join(self.names) or "none"
        raise InputError(f"no demonstration {name!r} (it has: {known})", file=self.label, field="name")

    def log_path(self, name):
        """Absolute path of the joint log of ``name``."""
        return self.path / self.entry(name).file

    def demonstration(self, name):
        """The demonstration ``name`` read from its joint log.

        Raises
        ------
        InputError
            The log is damaged or disagrees with the manifest's sample count.
        """
        entry = self.entry(name)
        log = self.path / entry.file
        demonstration, warnings = read_rtde_csv(
            log, name=name, description=entry.description, filter_runtime_state=False
        )
        if warnings:
            raise InputError(f"damaged joint log: {warnings[0].removeprefix(f'{log}: ')}", file=log)
        if demonstration.num_samples != entry.samples:
            raise InputError(
                f"has {demonstration.num_samples} samples but {MANIFEST_NAME} says {entry.samples}",
                file=log,
            )
        return demonstration

    def feature(self, name):
        """The feature ``HD`` of ``name`` (arc-length resampled, Eq. 12), from the cache
        when it is fresh, else recomputed from the joint log and the cache rewritten."""
        entry = self.entry(name)
        log = self.path / entry.file
        try:
            log_bytes = log.read_bytes()
        except OSError as error:
            raise InputError(f"cannot read the joint log: {error.strerror}", file=log) from None
        key = _cache_key(log_bytes, self.X_tool0_E, self.num_samples, self.rotation_length_m)
        memo = self._features.get(name)
        if memo is not None and memo[0] == key:
            return memo[1]
        cache_file = self.cache_path(name)
        feature = _feature_from_npz(cache_file, key) if cache_file.is_file() else None
        if feature is None:
            feature = self._compute_feature(self.demonstration(name))
            self._write_cache(name, key, feature)
        self._features[name] = (key, feature)
        return feature

    def resampled_poses(self, name):
        """The arc-length resampled end-effector poses of ``name`` as dual quaternions,
        shape (num_samples, 8), in the robot base frame: what the feature and the
        mapping (Eq. 22-25) index into."""
        return self.feature(name).poses

    def cache_path(self, name):
        """Where the feature cache of ``name`` lives (it may not exist)."""
        return self.path / CACHE_DIRECTORY / f"{name}.npz"

    def _dual_quaternions(self, demonstration):
        """Raw poses of E in the base frame, shape (m, 8)."""
        return dual_quaternions_from_demonstration(demonstration, shared_kinematics(X_tool0_E=self.X_tool0_E))

    def _compute_feature(self, demonstration):
        return Feature.from_poses(
            self._dual_quaternions(demonstration),
            num_samples=self.num_samples,
            rotation_length_m=self.rotation_length_m,
        )

    def _write_cache(self, name, key, feature):
        if self.read_only:
            return
        try:
            _make_directory(self.path / CACHE_DIRECTORY)
            atomic_write_bytes(self.cache_path(name), _feature_npz_bytes(key, feature))
        except OSError:
            pass  # the cache is an optimisation; an unwritable one is recomputed next time

    # -- writing ---------------------------------------------------------------------
    def _check_writable(self):
        if self.read_only:
            raise InputError(
                "is a bundled library and read-only; create your own with "
                "'drake-lfd library add DIRECTORY ...' (or copy this one to a directory)",
                file=self.label,
            )

    def _write_manifest(self, entries):
        # json.dumps(indent=2) would put every number of the pose on its own line;
        # this layout keeps the pose on one line and each entry as an indented block.
        demos = ",\n".join(
            "    " + json.dumps(entry.to_json(), indent=2).replace("\n", "\n    ") for entry in entries
        )
        text = (
            "{\n"
            f'  "schema_version": {SCHEMA_VERSION},\n'
            f'  "X_tool0_E": {json.dumps(pose_json_from_rigid_transform(self.X_tool0_E))},\n'
            + ('  "demos": [\n' + demos + "\n  ]\n" if entries else '  "demos": []\n')
            + "}\n"
        )
        atomic_write_bytes(self.manifest_path, text.encode("utf-8"))

    def add(self, demonstration, name, description=""):
        """Adds a demonstration: its joint log, then the manifest entry, then the cache.

        Parameters
        ----------
        demonstration : Demonstration
        name : str
            ``[A-Za-z0-9_-]+``, unique in the library (ignoring case).
        description : str

        Returns
        -------
        entry : DemoEntry

        Raises
        ------
        InputError
            Read-only library, bad or taken name, an invalid demonstration, or one that
            does not move. The library is unchanged then.
        """
        self._check_writable()
        check_demo_name(name)
        for entry in self._entries:
            if entry.name.lower() == name.lower():
                raise InputError(
                    f"the library has a demonstration named {entry.name!r} already; "
                    "remove it first or choose another name",
                    file=self.label,
                    field="name",
                )
        if not isinstance(description, str):
            raise InputError(f"expected a string, got {description!r}", field="description")
        check_demonstration(demonstration)
        stored = Demonstration(
            name=name,
            timestamps=demonstration.timestamps,
            joint_positions=demonstration.joint_positions,
            description=description,
        )
        D = self._dual_quaternions(stored)
        if not arc_lengths_from_poses(D, self.rotation_length_m)[-1] > MIN_MOTION_LENGTH:
            raise InputError(
                "the demonstration does not move the tool; it has no feature to learn", field="samples"
            )
        feature = Feature.from_poses(D, num_samples=self.num_samples, rotation_length_m=self.rotation_length_m)
        log_bytes = rtde_csv_text(stored).encode("utf-8")
        relative = f"{DEMOS_DIRECTORY}/{name}.csv"
        log = self.path / relative
        entry = DemoEntry(
            name=name,
            file=relative,
            samples=stored.num_samples,
            duration_s=stored.duration_s,
            description=description,
            added=datetime.datetime.now(datetime.timezone.utc).isoformat(timespec="seconds"),
        )
        _make_directory(self.path / DEMOS_DIRECTORY)
        atomic_write_bytes(log, log_bytes)
        entries = self._entries + [entry]
        try:
            self._write_manifest(entries)
        except BaseException:
            # Nothing references the new log yet: take it away again.
            try:
                log.unlink()
            except OSError:
                pass
            raise
        self._entries = entries
        key = _cache_key(log_bytes, self.X_tool0_E, self.num_samples, self.rotation_length_m)
        self._write_cache(name, key, feature)
        self._features[name] = (key, feature)
        return entry

    def remove(self, name):
        """Removes a demonstration: the manifest entry first, then its log and cache.

        Raises
        ------
        InputError
            Read-only library or no such demonstration.
        """
        self._check_writable()
        entry = self.entry(name)
        entries = [e for e in self._entries if e.name != name]
        self._write_manifest(entries)
        self._entries = entries
        self._features.pop(name, None)
        for path in (self.path / entry.file, self.cache_path(name)):
            try:
                path.unlink()
            except FileNotFoundError:
                pass
        fsync_directory(self.path / DEMOS_DIRECTORY)


def check_end_effector_frame(library, X_tool0_E_task, file=None):
    """Refuses to plan a task whose end-effector frame differs from the library's.

    Features describe the motion of frame E; demonstrations recorded with one
    ``X_tool0_E`` say nothing exact about another, so a mismatch is an error rather
    than a silently wrong plan.

    Parameters
    ----------
    library : Library
    X_tool0_E_task : RigidTransform
        The task's end-effector frame.
    file : str or Path, optional
        The task file, named in the error.

    Raises
    ------
    InputError
        If any entry of the 4x4 matrices differs by more than
        :data:`END_EFFECTOR_FRAME_TOLERANCE`.
    """
    difference = np.max(np.abs(library.X_tool0_E.GetAsMatrix4() - X_tool0_E_task.GetAsMatrix4()))
    if difference > END_EFFECTOR_FRAME_TOLERANCE:
        task = pose_json_from_rigid_transform(X_tool0_E_task)
        ours = pose_json_from_rigid_transform(library.X_tool0_E)
        raise InputError(
            f"the task's end-effector frame (p={_short(task['p'])}, q_wxyz={_short(task['q_wxyz'])}) "
            f"differs from the one library {library.label} was recorded with "
            f"(p={_short(ours['p'])}, q_wxyz={_short(ours['q_wxyz'])}); use a library recorded "
            "with this tool frame or change the task's X_tool0_E",
            file=file,
            field="X_tool0_E",
        )


def _short(values):
    return "[" + ", ".join(f"{v:.6g}" for v in values) + "]"
