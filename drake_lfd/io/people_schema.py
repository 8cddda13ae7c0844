"""The keys of a ``people:`` list and a ``collaboration:`` block, and of a people file, in plain Python.

The ``*Spec`` dataclasses say which keys a person, a waypoint, a reach, a body and the
``collaboration:`` block have and what kind of value each takes; a task file's
``people:`` and ``collaboration:`` keys and a people file (``drake-lfd simulate --people
FILE.yaml``) use them alike (docs/collaboration.rst). A value the file does not give is
None here where its default belongs to the record it becomes
(:class:`~drake_lfd.core.people.BodySize`, :class:`~drake_lfd.core.people.CollaborationParameters`):
those records say their defaults once, and nothing here imports Drake, so the command
line checks a people file before Drake loads (``people_checks.py``).

Not for: the values' ranges and meaning (``people_checks.py``), reading track CSVs or
making the records (``people_files.py``).
"""

# No ``from __future__ import annotations``: yaml_load_typed reads the Spec fields' types.
import dataclasses
from typing import Any, Optional

from drake_lfd.io.yaml_checks import required

__all__ = ["WaypointSpec", "ReachSpec", "BodySpec", "PersonSpec", "CollaborationSpec", "PeopleFileSpec",
           "PEOPLE_FILE_WORDS"]

#: How errors name a people file and its keys.
PEOPLE_FILE_WORDS = {"document": "the people file", "keys": "people-file keys (people, collaboration)"}

# A None default: the file does not say; the record's own default applies.
_RECORD_DEFAULT: Any = None


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

    torso_radius_m: float = _RECORD_DEFAULT
    shoulder_height_m: float = _RECORD_DEFAULT
    shoulder_half_width_m: float = _RECORD_DEFAULT
    head_radius_m: float = _RECORD_DEFAULT
    head_top_m: float = _RECORD_DEFAULT
    arm_radius_m: float = _RECORD_DEFAULT
    arm_length_m: float = _RECORD_DEFAULT


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

    policy: str = _RECORD_DEFAULT
    human_speed_m_s: float = _RECORD_DEFAULT
    reaction_time_s: float = _RECORD_DEFAULT
    stopping_time_s: Optional[float] = dataclasses.field(
        default=None, metadata={"expected": "a number (s), or absent for the UR5e's from its joint limits"})
    intrusion_distance_m: float = _RECORD_DEFAULT
    human_position_uncertainty_m: float = _RECORD_DEFAULT
    robot_position_uncertainty_m: float = _RECORD_DEFAULT
    stop_radius_m: Optional[float] = dataclasses.field(
        default=None, metadata={"expected": "a number (m), or absent for one as safe as speed and separation"})
    floor_z_m: Optional[float] = dataclasses.field(
        default=None, metadata={"expected": "a number (m), or absent for 0.75 m below the robot's base"})
    moving_toward_speed_m_s: float = _RECORD_DEFAULT
    max_speed_m_s: float = _RECORD_DEFAULT
    max_time_lost_s: float = _RECORD_DEFAULT


@dataclasses.dataclass
class PeopleFileSpec:
    """A people file: ``people:`` and ``collaboration:``, both optional."""

    people: list[PersonSpec] = dataclasses.field(default_factory=list)
    collaboration: Optional[CollaborationSpec] = dataclasses.field(
        default=None, metadata={"expected": "a mapping of collaboration keys ({} for the defaults)"})
