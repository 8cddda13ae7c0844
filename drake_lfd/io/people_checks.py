"""The values of a ``people:`` list and a ``collaboration:`` block checked, in plain Python.

A task file's ``people:`` and ``collaboration:`` keys and a people file hold the
``*Spec`` records of ``people_schema.py``. :func:`check_people` and
:func:`check_collaboration` check their values in the order a file is read (names,
path or track, body sizes, reach, waypoints; then the parameters) and return them
checked, as plain values; ``people_files.py`` makes the records of
:mod:`drake_lfd.core.people` from them. Two checks need what plain Python has not got:
a body's proportions (:class:`~drake_lfd.core.people.BodySize`) and a track's CSV; a
:class:`Judge` does those: the loader's makes the records, :data:`EARLY` (the command
line's check before Drake loads) raises :class:`~drake_lfd.io.yaml_checks.NeedsDrake`, so
the early check stops there and the loader finds the rest in the same order.

Every problem is one :class:`~drake_lfd.core.errors.InputError` naming the file and the
field (``people[0].path[2].t``).

Not for: the keys (``people_schema.py``), the records (``core/people.py``), reading a
track's CSV (``people_files.py``).
"""

from __future__ import annotations

import dataclasses
from pathlib import Path
from typing import Any, Protocol

from drake_lfd.core.errors import InputError
from drake_lfd.core.task_terms import POLICIES
from drake_lfd.io.people_schema import BodySpec
from drake_lfd.io.yaml_checks import NeedsDrake
from drake_lfd.io.yaml_values import coordinate, finite, non_negative, numbers, positive, unique_name

__all__ = ["MAX_PEOPLE", "MAX_WAYPOINTS", "Judge", "EARLY", "CheckedPerson", "check_people", "check_collaboration",
           "time_s"]

#: Most people a file may hold: each is four capsules queried against every robot
#: geometry at every control period.
MAX_PEOPLE = 20
#: Most waypoints of one path.
MAX_WAYPOINTS = 10_000


class Judge(Protocol):
    """What :func:`check_people` cannot judge in plain Python."""

    def body(self, sizes: dict[str, float], *, file, field) -> Any:
        """The body of checked ``sizes`` (the given ones, each > 0), or an InputError
        naming ``field`` if their proportions do not make one."""

    def track(self, path: Path) -> Any:
        """The recorded track in the CSV file ``path``, or an InputError naming it."""


class _Early:
    """The judge of the check before Drake loads: a body with given sizes and a track
    stop it (:class:`~drake_lfd.io.yaml_checks.NeedsDrake`)."""

    def body(self, sizes, *, file, field):
        if sizes:
            raise NeedsDrake(f"{field}: a body's proportions")
        return None

    def track(self, path):
        raise NeedsDrake(f"the track {path}")


#: The judge of the command line's check before Drake loads.
EARLY: Judge = _Early()


@dataclasses.dataclass(frozen=True)
class CheckedPerson:
    """A person's checked values: ``body`` and ``track`` as the judge made them;
    ``path`` the waypoints ``(t, (x, y))`` and ``reach`` ``((x, y, z), t_from, t_to)`` or
    None (a path); ``track`` None for a path."""

    name: str
    body: Any
    track: Any = None
    path: tuple = ()
    reach: tuple | None = None


def time_s(value, *, file, field):
    """Seconds from the trial's start: a finite number >= 0."""
    number = finite(value, file=file, field=field)
    if number < 0.0:
        raise InputError(f"times are seconds from the trial's start, >= 0; got {number:g}", file=file, field=field)
    return number


def _body(spec, *, file, field, judge):
    sizes = {}
    for f in dataclasses.fields(BodySpec):
        value = getattr(spec, f.name)
        if value is not None:  # None: BodySize's default
            sizes[f.name] = positive(value, file=file, field=f"{field}.{f.name}")
    return judge.body(sizes, file=file, field=field)


def _path(specs, *, file, field):
    if len(specs) > MAX_WAYPOINTS:
        raise InputError(f"a path has at most {MAX_WAYPOINTS:,} waypoints, got {len(specs):,}", file=file, field=field)
    waypoints = []
    for index, spec in enumerate(specs):
        base = f"{field}[{index}]"
        t = time_s(spec.t, file=file, field=f"{base}.t")
        if waypoints and not t > waypoints[-1][0]:
            raise InputError(f"waypoint times must increase: {t:g} s after {waypoints[-1][0]:g} s",
                             file=file, field=f"{base}.t")
        waypoints.append((t, numbers(spec.xy, 2, file=file, field=f"{base}.xy", convert=coordinate)))
    return tuple(waypoints)


def check_people(specs, *, file=None, judge: Judge) -> tuple[CheckedPerson, ...]:
    """The checked people of a ``people:`` list (track CSVs relative to ``file``'s folder)."""
    if len(specs) > MAX_PEOPLE:
        raise InputError(f"at most {MAX_PEOPLE} people, got {len(specs):,}", file=file, field="people")
    people, names = [], {}
    for index, spec in enumerate(specs):
        field = f"people[{index}]"
        unique_name(spec.name, names, what="person", file=file, field=field)
        if bool(spec.path) == bool(spec.track):
            raise InputError("give exactly one of path: [{t, xy}, ...] or track: FILE.csv", file=file, field=field)
        body = _body(spec.body, file=file, field=f"{field}.body", judge=judge)
        if spec.track:
            if spec.reach is not None:
                raise InputError("a track records the arms already; reach is for a path",
                                 file=file, field=f"{field}.reach")
            track_path = Path(spec.track)
            if not track_path.is_absolute() and file is not None:
                track_path = Path(file).parent / track_path
            people.append(CheckedPerson(spec.name, body, track=judge.track(track_path)))
            continue
        reach = None
        if spec.reach is not None:
            point = numbers(spec.reach.toward, 3, file=file, field=f"{field}.reach.toward", convert=coordinate)
            times = numbers(spec.reach.t, 2, file=file, field=f"{field}.reach.t", convert=time_s)
            if times[0] > times[1]:
                raise InputError(f"expected [from, to] with from <= to, got [{times[0]:g}, {times[1]:g}]",
                                 file=file, field=f"{field}.reach.t")
            reach = (point, times[0], times[1])
        people.append(CheckedPerson(spec.name, body, path=_path(spec.path, file=file, field=f"{field}.path"),
                                    reach=reach))
    return tuple(people)


def check_collaboration(spec, *, file=None, field="collaboration") -> dict[str, Any]:
    """The checked values a ``collaboration:`` block gives, by
    :class:`~drake_lfd.core.people.CollaborationParameters` field (the rest are its defaults)."""
    if spec.policy is not None and spec.policy not in POLICIES:
        raise InputError(f"unknown policy {spec.policy!r} (known: {', '.join(POLICIES)})",
                         file=file, field=f"{field}.policy")
    values: dict[str, Any] = {} if spec.policy is None else {"policy": spec.policy}
    for name in ("human_speed_m_s", "reaction_time_s", "max_speed_m_s", "max_time_lost_s"):
        if getattr(spec, name) is not None:
            values[name] = positive(getattr(spec, name), file=file, field=f"{field}.{name}")
    for name in ("intrusion_distance_m", "human_position_uncertainty_m", "robot_position_uncertainty_m",
                 "moving_toward_speed_m_s"):
        if getattr(spec, name) is not None:
            values[name] = non_negative(getattr(spec, name), file=file, field=f"{field}.{name}")
    for name in ("stopping_time_s", "stop_radius_m"):
        value = getattr(spec, name)
        values[name] = None if value is None else positive(value, file=file, field=f"{field}.{name}")
    values["floor_z_m"] = None if spec.floor_z_m is None else coordinate(spec.floor_z_m, file=file,
                                                                         field=f"{field}.floor_z_m")
    return values
