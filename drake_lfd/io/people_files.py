"""People files and the ``people:`` / ``collaboration:`` keys of a task file, checked into
:mod:`drake_lfd.core.people` records.

A task file may hold ``people:`` and ``collaboration:`` (docs/task_files.rst); a people
file given to ``drake-lfd simulate --people FILE.yaml`` holds either or both and puts
them on any task (:func:`task_with_people`). The minimal form::

    people:
      - name: operator
        path: [{t: 0.0, xy: [-0.2, -2.0]}, {t: 1.5, xy: [-0.2, -0.75]},
               {t: 4.0, xy: [-0.2, -0.75]}, {t: 5.5, xy: [-0.2, -2.0]}]
    collaboration: {}      # optional: the documented defaults

A person has a ``path`` (timed floor waypoints) or a ``track`` (a CSV of time and
keypoints, relative to the YAML file's folder; format in docs/collaboration.rst and
:func:`load_track_csv`), an optional ``reach: {toward: [x, y, z], t: [from, to]}`` (a
path only) and an optional ``body:`` overriding :class:`~drake_lfd.core.people.BodySize`
fields. Every problem is one :class:`~drake_lfd.core.errors.InputError` naming the file
and the field (``people[0].path[2].t``), as task files report them.

Not for: the people's geometry or motion (``core/people.py``), the simulation.
"""

# No ``from __future__ import annotations``: yaml_load_typed reads the Spec fields' types.
import csv
import dataclasses
import io
from pathlib import Path
from typing import Optional

import numpy as np

from drake_lfd.core.errors import InputError
from drake_lfd.core.people import (
    POLICIES, TRACK_KEYPOINTS, BodySize, CollaborationParameters, Person, Reach, RecordedTrack, ScriptedPath,
    Waypoint,
)
from drake_lfd.io.yaml_checks import load_spec, read_text, required
from drake_lfd.io.yaml_values import (
    coordinate, finite, non_negative as _non_negative, positive as _positive, unique_name, vector,
)

__all__ = ["WaypointSpec", "ReachSpec", "BodySpec", "PersonSpec", "CollaborationSpec", "PeopleFileSpec",
           "people_from_specs", "collaboration_from_spec", "load_people_file", "task_with_people",
           "load_track_csv", "track_columns", "MAX_PEOPLE", "MAX_WAYPOINTS", "MAX_TRACK_BYTES"]

#: Most people a file may hold: each is four capsules queried against every robot
#: geometry at every control period.
MAX_PEOPLE = 20
#: Most waypoints of one path.
MAX_WAYPOINTS = 10_000
#: Largest track CSV read (about a minute of 30 Hz skeleton tracking takes 300 kB).
MAX_TRACK_BYTES = 64 * 2 ** 20


@dataclasses.dataclass
class WaypointSpec:
    """``{t, xy}``: the body's vertical axis at ``xy`` (W, m) on the floor at ``t`` s."""

    t: float = required(float)
    xy: list[float] = required(list)


@dataclasses.dataclass
class ReachSpec:
    """Both arms stretched toward ``toward`` (W, m) over ``t: [from, to]`` s."""

    toward: list[float] = required(list)
    t: list[float] = required(list)


@dataclasses.dataclass
class BodySpec:
    """Overrides of :class:`~drake_lfd.core.people.BodySize`'s capsule sizes, m."""

    torso_radius_m: float = BodySize.torso_radius_m
    shoulder_height_m: float = BodySize.shoulder_height_m
    shoulder_half_width_m: float = BodySize.shoulder_half_width_m
    head_radius_m: float = BodySize.head_radius_m
    head_top_m: float = BodySize.head_top_m
    arm_radius_m: float = BodySize.arm_radius_m
    arm_length_m: float = BodySize.arm_length_m


@dataclasses.dataclass
class PersonSpec:
    """One person: ``name`` and a ``path`` or a ``track``."""

    name: str = required(str)
    path: list[WaypointSpec] = dataclasses.field(default_factory=list)
    track: str = ""
    reach: Optional[ReachSpec] = dataclasses.field(
        default=None, metadata={"expected": "a mapping {toward: [x, y, z], t: [from, to]}"})
    body: BodySpec = dataclasses.field(default_factory=BodySpec)


@dataclasses.dataclass
class CollaborationSpec:
    """The ``collaboration:`` block (:class:`~drake_lfd.core.people.CollaborationParameters`)."""

    policy: str = CollaborationParameters.policy
    human_speed_m_s: float = CollaborationParameters.human_speed_m_s
    reaction_time_s: float = CollaborationParameters.reaction_time_s
    stopping_time_s: Optional[float] = dataclasses.field(
        default=None, metadata={"expected": "a number (s), or absent for the UR5e's from its joint limits"})
    intrusion_distance_m: float = CollaborationParameters.intrusion_distance_m
    human_position_uncertainty_m: float = CollaborationParameters.human_position_uncertainty_m
    robot_position_uncertainty_m: float = CollaborationParameters.robot_position_uncertainty_m
    stop_radius_m: Optional[float] = dataclasses.field(
        default=None, metadata={"expected": "a number (m), or absent for one as safe as speed and separation"})
    floor_z_m: Optional[float] = dataclasses.field(
        default=None, metadata={"expected": "a number (m), or absent for 0.75 m below the robot's base"})
    moving_toward_speed_m_s: float = CollaborationParameters.moving_toward_speed_m_s
    max_speed_m_s: float = CollaborationParameters.max_speed_m_s
    max_time_lost_s: float = CollaborationParameters.max_time_lost_s


@dataclasses.dataclass
class PeopleFileSpec:
    """A people file: ``people:`` and ``collaboration:``, both optional."""

    people: list[PersonSpec] = dataclasses.field(default_factory=list)
    collaboration: Optional[CollaborationSpec] = dataclasses.field(
        default=None, metadata={"expected": "a mapping of collaboration keys ({} for the defaults)"})


def _time(value, *, file, field):
    number = finite(value, file=file, field=field)
    if number < 0.0:
        raise InputError(f"times are seconds from the trial's start, >= 0; got {number:g}", file=file, field=field)
    return number


def _body(spec, *, file, field):
    values = {f.name: _positive(getattr(spec, f.name), file=file, field=f"{field}.{f.name}")
              for f in dataclasses.fields(BodySpec)}
    try:
        return BodySize(**values)
    except ValueError as error:
        raise InputError(str(error), file=file, field=field) from None


def _path(specs, *, file, field):
    if len(specs) > MAX_WAYPOINTS:
        raise InputError(f"a path has at most {MAX_WAYPOINTS:,} waypoints, got {len(specs):,}", file=file, field=field)
    waypoints = []
    for index, spec in enumerate(specs):
        base = f"{field}[{index}]"
        t = _time(spec.t, file=file, field=f"{base}.t")
        if waypoints and not t > waypoints[-1].t:
            raise InputError(f"waypoint times must increase: {t:g} s after {waypoints[-1].t:g} s",
                             file=file, field=f"{base}.t")
        xy = vector(spec.xy, 2, file=file, field=f"{base}.xy", convert=coordinate)
        waypoints.append(Waypoint(t, xy))
    return tuple(waypoints)


def track_columns() -> list[str]:
    """The header of a track CSV: ``t`` then ``<keypoint>_x, _y, _z`` per keypoint."""
    return ["t"] + [f"{name}_{axis}" for name in TRACK_KEYPOINTS for axis in "xyz"]


def load_track_csv(path) -> RecordedTrack:
    """Reads a recorded track: a CSV with the header :func:`track_columns` (``t`` in s
    from the trial's start, increasing; each keypoint's x, y, z in W, metres), one row
    per tracker frame.

    Raises
    ------
    InputError
        Naming the CSV file and the row and column of the problem.
    """
    path = Path(path)
    try:
        with path.open("rb") as handle:
            data = handle.read(MAX_TRACK_BYTES + 1)
        if len(data) > MAX_TRACK_BYTES:
            raise InputError(f"larger than {MAX_TRACK_BYTES // 2 ** 20} MiB", file=path)
        text = data.decode("utf-8")
    except FileNotFoundError:
        raise InputError("no such file", file=path) from None
    except (OSError, UnicodeDecodeError) as error:
        raise InputError(f"cannot read: {error}", file=path) from None
    rows = [row for row in csv.reader(io.StringIO(text)) if row and any(cell.strip() for cell in row)]
    expected = track_columns()
    if not rows:
        raise InputError("the track is empty (expected a header row: " + ",".join(expected[:4]) + ",...)", file=path)
    header = [cell.strip() for cell in rows[0]]
    if header != expected:
        missing = [name for name in expected if name not in header]
        extra = [name for name in header if name not in expected]
        detail = (f"missing {', '.join(missing[:3])}" if missing else f"unknown {', '.join(extra[:3])}") \
            if (missing or extra) else "columns out of order"
        raise InputError(f"expected the header {','.join(expected[:4])},... ({len(expected)} columns): {detail}",
                         file=path, field="header")
    if len(rows) < 2:
        raise InputError("the track has a header but no rows", file=path)
    values = np.empty((len(rows) - 1, len(expected)))
    for r, row in enumerate(rows[1:], start=2):
        if len(row) != len(expected):
            raise InputError(f"expected {len(expected)} values, got {len(row)}", file=path, field=f"row {r}")
        for c, cell in enumerate(row):
            convert = _time if c == 0 else coordinate
            values[r - 2, c] = convert(cell.strip(), file=path, field=f"row {r}, column {expected[c]}")
        if r > 2 and not values[r - 2, 0] > values[r - 3, 0]:
            raise InputError(f"times must increase: {values[r - 2, 0]:g} s after {values[r - 3, 0]:g} s",
                             file=path, field=f"row {r}, column t")
    return RecordedTrack(values[:, 0], values[:, 1:].reshape(len(values), len(TRACK_KEYPOINTS), 3), str(path))


def people_from_specs(specs, *, file=None) -> tuple:
    """The checked :class:`~drake_lfd.core.people.Person` records of a ``people:`` list
    (track CSVs relative to ``file``'s folder)."""
    if len(specs) > MAX_PEOPLE:
        raise InputError(f"at most {MAX_PEOPLE} people, got {len(specs):,}", file=file, field="people")
    people, names = [], {}
    for index, spec in enumerate(specs):
        field = f"people[{index}]"
        unique_name(spec.name, names, what="person", file=file, field=field)
        if bool(spec.path) == bool(spec.track):
            raise InputError("give exactly one of path: [{t, xy}, ...] or track: FILE.csv", file=file, field=field)
        body = _body(spec.body, file=file, field=f"{field}.body")
        if spec.track:
            if spec.reach is not None:
                raise InputError("a track records the arms already; reach is for a path",
                                 file=file, field=f"{field}.reach")
            track_path = Path(spec.track)
            if not track_path.is_absolute() and file is not None:
                track_path = Path(file).parent / track_path
            people.append(Person(spec.name, load_track_csv(track_path), body))
            continue
        reach = None
        if spec.reach is not None:
            point = vector(spec.reach.toward, 3, file=file, field=f"{field}.reach.toward", convert=coordinate)
            times = vector(spec.reach.t, 2, file=file, field=f"{field}.reach.t", convert=_time)
            if times[0] > times[1]:
                raise InputError(f"expected [from, to] with from <= to, got [{times[0]:g}, {times[1]:g}]",
                                 file=file, field=f"{field}.reach.t")
            reach = Reach(point, float(times[0]), float(times[1]))
        people.append(Person(spec.name, ScriptedPath(_path(spec.path, file=file, field=f"{field}.path"), reach), body))
    return tuple(people)


def collaboration_from_spec(spec, *, file=None, field="collaboration") -> CollaborationParameters:
    """The checked :class:`~drake_lfd.core.people.CollaborationParameters` of a
    ``collaboration:`` block (None: the defaults)."""
    if spec is None:
        return CollaborationParameters()
    if spec.policy not in POLICIES:
        raise InputError(f"unknown policy {spec.policy!r} (known: {', '.join(POLICIES)})",
                         file=file, field=f"{field}.policy")
    values = {"policy": spec.policy}
    for name in ("human_speed_m_s", "reaction_time_s", "max_speed_m_s", "max_time_lost_s"):
        values[name] = _positive(getattr(spec, name), file=file, field=f"{field}.{name}")
    for name in ("intrusion_distance_m", "human_position_uncertainty_m", "robot_position_uncertainty_m",
                 "moving_toward_speed_m_s"):
        values[name] = _non_negative(getattr(spec, name), file=file, field=f"{field}.{name}")
    for name in ("stopping_time_s", "stop_radius_m"):
        value = getattr(spec, name)
        values[name] = None if value is None else _positive(value, file=file, field=f"{field}.{name}")
    values["floor_z_m"] = None if spec.floor_z_m is None else coordinate(spec.floor_z_m, file=file,
                                                                         field=f"{field}.floor_z_m")
    return CollaborationParameters(**values)


def load_people_file(path) -> tuple[tuple, CollaborationParameters | None]:
    """Reads and checks a people file: ``(people, collaboration)``, the collaboration
    None when the file has no ``collaboration:`` block.

    Raises
    ------
    InputError
        Naming the file and the field.
    """
    path = Path(path)
    spec = load_spec(read_text(path), PeopleFileSpec, file=path, document="the people file",
                     keys="people-file keys (people, collaboration)")
    people = people_from_specs(spec.people, file=path)
    collaboration = None if spec.collaboration is None else collaboration_from_spec(spec.collaboration, file=path)
    return people, collaboration


def task_with_people(task, path):
    """``task`` with the people file ``path``'s people (replacing the task's own, when
    the file has any) and its ``collaboration:`` block (when it has one)."""
    people, collaboration = load_people_file(path)
    changes = {}
    if people:
        changes["people"] = people
    if collaboration is not None:
        changes["collaboration"] = collaboration
    return dataclasses.replace(task, **changes)
