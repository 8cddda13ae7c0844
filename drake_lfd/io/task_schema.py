"""The keys of a task file and the check of its structure, in plain Python.

The ``*Spec`` dataclasses say which keys a task file has and what kind of value each
takes (:mod:`drake_lfd.io.task_files` documents the format and loads it with Drake's
``yaml_load_typed``). :func:`check_task_file` reads a file and checks it against them
(YAML syntax, duplicated, unknown or missing keys, values of the wrong kind) without
importing Drake or numpy, so the command line refuses a typo'd key before it loads
anything heavy. :class:`TaskSpec` checks the ``simulation:``, ``people:`` and
``collaboration:`` blocks only as a mapping and lists of mappings; :class:`TypedTaskSpec`
types them as the loader does (``people_schema.py``, ``simulation_schema.py``). A value
the file does not give is None where its default belongs to the record it becomes.

Not for: the values' meaning (ranges, ordering, names: ``task_checks.py``).
"""

# No ``from __future__ import annotations`` here: yaml_load_typed reads the Spec fields'
# types at run time and needs them as types, not strings.

import dataclasses
from pathlib import Path
from typing import Any, Optional, Union

from drake_lfd.io.people_schema import CollaborationSpec, PersonSpec
from drake_lfd.io.simulation_schema import SimulationSpec
from drake_lfd.io.yaml_checks import PoseSpec, Scalar, check_yaml_file, read_text, required

__all__ = [
    "CriticalConfigurationSpec",
    "BoxSpec",
    "CylinderSpec",
    "ToolShapeSpec",
    "PathConstraintSpec",
    "DeviationSpec",
    "RefinementSpanSpec",
    "RefinementSpec",
    "TimingSpec",
    "TaskSpec",
    "TypedTaskSpec",
    "TASK_FILE_WORDS",
    "check_task_text",
    "check_task_file",
]

#: How errors name a task file and its keys ("the task file is empty", "expected a
#: mapping of task keys").
TASK_FILE_WORDS = {"document": "the task file", "keys": "task keys"}


# A None default: the file does not say; the record's own default applies (the Task's
# angle grid, TimingLimits' limits), stated there once.
_RECORD_DEFAULT: Any = None


# A coordinate or angle: a number-like token, or a [lower, upper] list of them.
Entry = Union[list[Scalar], float, int, str]


@dataclasses.dataclass
class CriticalConfigurationSpec:
    """``con_i``: each coordinate / angle a value, a [lower, upper] range or a variable."""

    p: list[Entry] = dataclasses.field(
        default_factory=list,
        metadata={"required": True, "expected": "a number, a [lower, upper] list or a variable name"},
    )
    euler_zyx: list[Entry] = dataclasses.field(
        default_factory=list,
        metadata={"required": True, "expected": "an angle or a [lower, upper] list of angles"},
    )
    # Whether the tool comes to rest here (absent: only at the first and the last).
    stop: Optional[bool] = dataclasses.field(default=None, metadata={"expected": "true or false"})


@dataclasses.dataclass
class BoxSpec:
    """A box in W: ``centre`` and full edge lengths ``size``, metres; ``euler_zyx`` turns
    its edges (axis-aligned if absent)."""

    name: str = required(str)
    centre: list[float] = required(list)
    size: list[float] = required(list)
    euler_zyx: list[Scalar] = dataclasses.field(default_factory=lambda: [0.0, 0.0, 0.0])


@dataclasses.dataclass
class CylinderSpec:
    """A cylinder of the tool: ``radius`` and full ``length`` along its z axis, metres."""

    radius: float = required(float)
    length: float = required(float)


@dataclasses.dataclass
class ToolShapeSpec:
    """One shape of the ``tool:`` block, fixed to ``tool0``: a ``box: [x, y, z]`` (full
    edges) or a ``cylinder: {radius, length}``, centred at ``p`` and turned by
    ``euler_zyx`` in ``tool0``."""

    name: str = required(str)
    box: list[float] = dataclasses.field(default_factory=list)
    cylinder: CylinderSpec = dataclasses.field(default_factory=CylinderSpec)
    p: list[float] = dataclasses.field(default_factory=lambda: [0.0, 0.0, 0.0])
    euler_zyx: list[Scalar] = dataclasses.field(default_factory=lambda: [0.0, 0.0, 0.0])


@dataclasses.dataclass
class DeviationSpec:
    """How far refinement may move E from the composed path: metres and degrees (each
    absent: as the wider bounds say)."""

    position_m: Optional[float] = dataclasses.field(
        default=None, metadata={"expected": "a number (metres), or absent"})
    rotation_deg: Optional[float] = dataclasses.field(
        default=None, metadata={"expected": "a number (degrees), or absent"})


@dataclasses.dataclass
class PathConstraintSpec:
    """A constraint judged on a run between two critical configurations (1-based)."""

    kind: str = "orientation"
    between: list[int] = required(list)
    euler_zyx: list[Scalar] = required(list)
    tolerance_deg: float = required(float)
    # Absent (or its rotation_deg): refinement keeps the rotation within tolerance_deg of the
    # composed path here.
    max_deviation: DeviationSpec = dataclasses.field(default_factory=DeviationSpec)


@dataclasses.dataclass
class RefinementSpanSpec(DeviationSpec):
    """An entry of ``refinement.spans``: the bound from con_j to con_k."""

    between: list[int] = required(list)


@dataclasses.dataclass
class RefinementSpec:
    """The ``refinement:`` block (:mod:`drake_lfd.io.task_files`)."""

    max_deviation: DeviationSpec = dataclasses.field(default_factory=DeviationSpec)
    spans: list[RefinementSpanSpec] = dataclasses.field(default_factory=list)


@dataclasses.dataclass
class TimingSpec:
    """The ``timing:`` block: the limits the plan's time-optimal timing keeps to
    (:class:`~drake_lfd.core.timing.TimingLimits`, whose defaults apply where the file is
    silent)."""

    joint_speed_rad_s: float = _RECORD_DEFAULT
    joint_acceleration_rad_s2: float = _RECORD_DEFAULT
    tool_speed_m_s: float = _RECORD_DEFAULT
    tool_acceleration_m_s2: Optional[float] = dataclasses.field(
        default=None, metadata={"expected": "a number (m/s^2), or absent for none"})
    limit_fraction: float = _RECORD_DEFAULT


@dataclasses.dataclass
class TaskSpec:
    """The whole task file (docs/task_files.rst): its keys, in the order error messages
    list them."""

    name: str = ""
    description: str = ""
    X_WB: PoseSpec = dataclasses.field(default_factory=PoseSpec)
    X_tool0_E: PoseSpec = dataclasses.field(default_factory=PoseSpec)
    angle_grid_deg: float = _RECORD_DEFAULT
    variables: dict[str, list[Scalar]] = dataclasses.field(default_factory=dict)
    critical_configurations: list[CriticalConfigurationSpec] = required(list)
    obstacles: list[BoxSpec] = dataclasses.field(default_factory=list)
    safety_shells: list[BoxSpec] = dataclasses.field(default_factory=list)
    path_constraints: list[PathConstraintSpec] = dataclasses.field(default_factory=list)
    # Drake's config structs are its schema: checked when the file is loaded
    # (io/task_files.py's TaskSpec types it as a PipelineConfig); here only as a mapping.
    simulation: dict[str, Any] = dataclasses.field(default_factory=dict)
    timing: TimingSpec = dataclasses.field(default_factory=TimingSpec)
    refinement: RefinementSpec = dataclasses.field(default_factory=RefinementSpec)
    # Absent (None): the default tool sized from X_tool0_E; [] for no tool geometry.
    tool: Optional[list[ToolShapeSpec]] = dataclasses.field(
        default=None, metadata={"expected": "a list of tool shapes ([] for none)"})
    # People in the cell and speed and separation monitoring: their schema is
    # io/people_files.py's (its records need Drake), checked when the file is loaded
    # (io/task_files.py's TaskSpec types them); here only as a list and a mapping.
    people: list[dict[str, Any]] = dataclasses.field(default_factory=list)
    collaboration: Optional[dict[str, Any]] = dataclasses.field(
        default=None, metadata={"expected": "a mapping of collaboration keys ({} for the defaults)"})


@dataclasses.dataclass
class TypedTaskSpec(TaskSpec):
    """The task file's keys as the loader types them: ``people:`` and ``collaboration:``
    as :mod:`~drake_lfd.io.people_schema`'s records, ``simulation:`` as
    :class:`~drake_lfd.io.simulation_schema.SimulationSpec` (the block's own keys; the
    loader's :class:`drake_lfd.io.task_files.TaskSpec` types it as Drake's structs too).
    The check before Drake loads (``task_checks.py``) reads a file with it."""

    simulation: SimulationSpec = dataclasses.field(default_factory=SimulationSpec)
    people: list[PersonSpec] = dataclasses.field(default_factory=list)
    collaboration: Optional[CollaborationSpec] = dataclasses.field(
        default=None, metadata={"expected": "a mapping of collaboration keys ({} for the defaults)"})


def check_task_text(text, *, file=None):
    """Checks task-file YAML text's structure against :class:`TaskSpec`; ``file`` is named
    in errors. Returns the raw mapping.

    Raises
    ------
    InputError
        Invalid YAML, a duplicated, unknown or missing key, or a value of the wrong kind,
        naming the file and the field.
    """
    return check_yaml_file(text, TaskSpec, file=file, **TASK_FILE_WORDS)


def check_task_file(path):
    """Reads the task file at ``path`` and checks its structure (:func:`check_task_text`):
    a missing or unreadable file, invalid YAML, a typo'd key, all before Drake loads."""
    path = Path(path)
    return check_task_text(read_text(path), file=path)
