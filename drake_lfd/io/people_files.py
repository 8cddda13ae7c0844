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
and the field (``people[0].path[2].t``), as task files report them. The keys are
``people_schema.py``'s and the value checks ``people_checks.py``'s, plain Python, so the
command line checks a people file before Drake loads (:func:`people_from_specs` makes the
records from what they checked).

Not for: the people's geometry or motion (``core/people.py``), the simulation.
"""

import csv
import dataclasses
import io
from pathlib import Path

import numpy as np

from drake_lfd.core.errors import InputError
from drake_lfd.core.people import (
    TRACK_KEYPOINTS, BodySize, CollaborationParameters, Person, Reach, RecordedTrack, ScriptedPath, Waypoint,
)
# The keys are people_schema.py's and the value checks people_checks.py's (plain Python,
# so the command line checks a people file before Drake loads); the limits are theirs.
from drake_lfd.io.people_checks import (
    MAX_PEOPLE, MAX_WAYPOINTS, check_collaboration, check_people, time_s as _time,
)
from drake_lfd.io.people_schema import (
    PEOPLE_FILE_WORDS, BodySpec, CollaborationSpec, PeopleFileSpec, PersonSpec, ReachSpec, WaypointSpec,
)
from drake_lfd.io.yaml_checks import load_spec, read_text
from drake_lfd.io.yaml_values import coordinate

__all__ = ["WaypointSpec", "ReachSpec", "BodySpec", "PersonSpec", "CollaborationSpec", "PeopleFileSpec",
           "RecordJudge", "RECORD_JUDGE", "people_records", "people_from_specs", "collaboration_from_spec", "load_people_file", "task_with_people",
           "load_track_csv", "track_columns", "MAX_PEOPLE", "MAX_WAYPOINTS", "MAX_TRACK_BYTES"]

#: Largest track CSV read (about a minute of 30 Hz skeleton tracking takes 300 kB).
MAX_TRACK_BYTES = 64 * 2 ** 20


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


class RecordJudge:
    """The loader's :class:`~drake_lfd.io.people_checks.Judge`: a body's sizes make a
    :class:`~drake_lfd.core.people.BodySize`, a track's CSV is read (:func:`load_track_csv`)."""

    def body(self, sizes, *, file, field):
        try:
            return BodySize(**sizes)
        except ValueError as error:
            raise InputError(str(error), file=file, field=field) from None

    def track(self, path):
        return load_track_csv(path)


#: The judge of loading a file: it makes the records.
RECORD_JUDGE = RecordJudge()


def people_records(checked) -> tuple:
    """The :class:`~drake_lfd.core.people.Person` records of people checked with
    :data:`RECORD_JUDGE` (:func:`~drake_lfd.io.people_checks.check_people`)."""
    people = []
    for person in checked:
        if person.track is not None:
            people.append(Person(person.name, person.track, person.body))
            continue
        reach = None if person.reach is None else Reach(np.array(person.reach[0]), person.reach[1], person.reach[2])
        waypoints = tuple(Waypoint(t, np.array(xy)) for t, xy in person.path)
        people.append(Person(person.name, ScriptedPath(waypoints, reach), person.body))
    return tuple(people)


def people_from_specs(specs, *, file=None) -> tuple:
    """The checked :class:`~drake_lfd.core.people.Person` records of a ``people:`` list
    (track CSVs relative to ``file``'s folder)."""
    return people_records(check_people(specs, file=file, judge=RECORD_JUDGE))


def collaboration_from_spec(spec, *, file=None, field="collaboration") -> CollaborationParameters:
    """The checked :class:`~drake_lfd.core.people.CollaborationParameters` of a
    ``collaboration:`` block (None: the defaults)."""
    if spec is None:
        return CollaborationParameters()
    return CollaborationParameters(**check_collaboration(spec, file=file, field=field))


def load_people_file(path) -> tuple[tuple, CollaborationParameters | None]:
    """Reads and checks a people file: ``(people, collaboration)``, the collaboration
    None when the file has no ``collaboration:`` block.

    Raises
    ------
    InputError
        Naming the file and the field.
    """
    path = Path(path)
    spec = load_spec(read_text(path), PeopleFileSpec, file=path, **PEOPLE_FILE_WORDS)
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
