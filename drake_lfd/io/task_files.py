"""Task files: the YAML form of a task, read and checked into a :class:`~drake_lfd.core.tasks.Task`.

A task file is YAML, loaded with ``pydrake.common.yaml.yaml_load_typed`` into the
``*Spec`` dataclasses of :mod:`drake_lfd.io.task_schema` (unknown keys are errors; that
module checks a file's structure without Drake), then checked value by value (by
:mod:`drake_lfd.io.task_checks`, in plain Python) and made the
:class:`~drake_lfd.core.tasks.Task` of :mod:`drake_lfd.core.tasks` (Eq. 10), whose
:func:`~drake_lfd.core.tasks.draw_trial` makes each evaluation trial. The format is
documented for users in docs/task_files.rst.

Example, the paper's Table 8 (filling and pouring)::

    name: filling_pouring
    description: fill cup 1, carry the water upright, pour into cup 2
    X_WB: {p: [0, 0, 0], euler_zyx: [0, 0, 0]}         # robot base in W; identity if absent
    X_tool0_E: {p: [0, 0, 0], euler_zyx: [0, 0, 0]}    # E on tool0; identity if absent
    angle_grid_deg: 15                                  # grid for bounded angles; 15 if absent
    variables:            # position ranges drawn once per trial and shared by every use
      x: [-0.5, 0.7]
      y: [-0.2, 0.0]
    critical_configurations:
      - {p: [-0.4, -0.1, 0.0], euler_zyx: [0, -pi, 0]}
      - {p: [-0.5, 0.1, 0.1], euler_zyx: [0, -pi/2, [-pi, pi]]}
      - {p: [-0.7, -0.1, 0.1], euler_zyx: [0, -pi/2, [-pi, pi]]}
      - {p: [x, y, 0.1], euler_zyx: [0, -pi/2, [-pi, pi]]}
      - {p: [x, y, 0.0], euler_zyx: [pi/2, 0, -pi/2]}
    obstacles:            # axis-aligned boxes in W: centre and full edge lengths, metres
      - {name: cup_1, centre: [-0.4, -0.1, -0.05], size: [0.08, 0.08, 0.1]}
    safety_shells:        # keep-out boxes no robot geometry may enter
      - {name: cup_1_shell, centre: [-0.4, -0.1, -0.05], size: [0.12, 0.12, 0.12]}
    path_constraints:     # judged on a run: tool orientation within tolerance from con to con
      - {kind: orientation, between: [2, 4], euler_zyx: [0, -pi/2, 0], tolerance_deg: 10}
        # optional on a constraint: max_deviation: {position_m: 0.05, rotation_deg: 5}
    refinement:           # how far --refine may move E from the composed path
      max_deviation: {position_m: 0.15, rotation_deg: 30}   # the whole task; these are the defaults
      spans:              # from con_j to con_k instead (the tighter where two overlap)
        - {between: [4, 5], position_m: 0.02, rotation_deg: 3}
    tool:                 # shapes fixed to tool0; absent: a cylinder from the flange to E
      - {name: holder, cylinder: {radius: 0.03, length: 0.15}, p: [0, 0, 0.075]}
      - {name: cup, box: [0.08, 0.08, 0.1], p: [0, 0, 0.2]}
    timing:               # the limits of the time-optimal timing; these are the defaults
      joint_speed_rad_s: 3.14159        # UR5e datasheet: 180 deg/s, every joint
      joint_acceleration_rad_s2: 8.0
      tool_speed_m_s: 1.5               # UR's default safety limit
      # tool_acceleration_m_s2: 2.0     # optional (carrying water)
      limit_fraction: 0.9               # the share the plan uses; the rest is the controller's

A critical configuration may add ``stop: true`` (the tool comes to rest there) or
``stop: false``; by default it stops at the first and the last only (and wherever the
path has a corner).

Values:

- Positions ``p: [x, y, z]`` in metres. Each coordinate is a number, an inline range
  ``[lower, upper]`` (drawn uniformly per trial, independently of every other), or the
  name of an entry of ``variables`` (drawn once per trial; every coordinate naming it
  gets the same value: Table 7's ``z`` of con_2 and con_3, Table 8's ``(x, y)`` of
  con_4 and con_5). A position range is trial-to-trial variation, not a planner freedom.
- Orientations ``euler_zyx: [yaw, pitch, roll]`` in radians, ``R = Rz(yaw) Ry(pitch)
  Rx(roll)`` (Eq. 17; docs/method.rst, Conventions). Each angle is fixed, or bounded
  ``[lower, upper]``: a freedom the planner chooses among the grid
  :func:`~drake_lfd.core.tasks.angle_candidates` (every ``angle_grid_deg`` or finer,
  both bounds included). Angles may be written as numbers, as multiples of pi (``pi``,
  ``-pi/2``, ``3*pi/4``, ``0.5pi``) or in degrees (``-90deg``), so the paper's values
  stay readable. Each bounded angle is chosen per critical configuration; variables are
  for positions only.
- ``path_constraints[*].between: [j, k]`` are critical configuration numbers (1-based,
  ``j < k``); ``kind: orientation`` asks the tool orientation to stay within
  ``tolerance_deg`` of ``euler_zyx`` from con_j to con_k.
- ``refinement``: how far refinement (``--refine``) may move E from the composed path, at
  matching path fractions: ``position_m`` (metres, > 0) and ``rotation_deg`` (degrees, in
  (0, 180]), each optional. ``max_deviation`` holds for the whole task (absent: 0.15 m and
  30 deg); an entry of ``spans`` (``between: [j, k]`` as a path constraint's, and at least
  one of the two) replaces it from con_j to con_k, so a span may be held tighter or let
  wider. A path constraint bounds it besides, over its own spans: its ``max_deviation``
  (the same two keys), or without one the rotation within its ``tolerance_deg``. The whole
  task's position bound holds at matching path fractions; a span's own (from ``spans`` or a
  path constraint) holds E within that distance of the composed span's path, wherever
  along it (docs/task_files.rst, The refinement block).
- Root keys starting with ``_`` are ignored (YAML anchors for reuse, as in Drake).

Every problem is an :class:`~drake_lfd.core.errors.InputError` naming the file and the field
(``critical_configurations[3].p[2]``, list indices from 0; the message also names the
1-based ``con_4``).

Not for: the task types themselves, drawing trials or angle grids (all in
:mod:`drake_lfd.core.tasks`, which reads no files), planning, simulating the scene.
"""

import dataclasses
from pathlib import Path

import numpy as np

from drake_lfd.core.people import CollaborationParameters
from drake_lfd.core.tasks import (
    Box,
    CriticalConfiguration,
    DeviationBound,
    PathConstraint,
    RefinementBounds,
    Task,
    rigid_transform_from_euler_zyx,
)
from drake_lfd.core.timing import TimingLimits
from drake_lfd.core.tool import ToolShape

from drake_lfd.io import task_schema
from drake_lfd.io.people_files import RECORD_JUDGE, people_records
from drake_lfd.io.simulation_config import PipelineConfig
# The value checks are plain Python (task_checks.py), so the command line runs them before
# Drake loads; the limits are theirs.
from drake_lfd.io.task_checks import (
    MAX_BOXES,
    MAX_CRITICAL_CONFIGURATIONS,
    MAX_TOOL_SHAPES,
    MIN_ANGLE_GRID_DEG,
    check_task_values,
)
from drake_lfd.io.yaml_checks import load_spec, read_text

# The Spec dataclasses other than TaskSpec are io/task_schema.py's.
__all__ = [
    "TaskSpec",
    "load_task_spec",
    "task_spec_from_text",
    "task_from_spec",
    "load_task",
    "MAX_CRITICAL_CONFIGURATIONS",
    "MAX_BOXES",
    "MAX_TOOL_SHAPES",
    "MIN_ANGLE_GRID_DEG",
]

# No ``from __future__ import annotations`` here: yaml_load_typed reads the Spec fields'
# types at run time and needs them as types, not strings.

# ------------------------------------------------------------------ schema (the YAML)

# The keys and kinds of values are io/task_schema.py's (plain Python, so the command line
# checks a file's structure before Drake loads); the loader's TaskSpec types the
# simulation: block as the Drake structs it is.
@dataclasses.dataclass
class TaskSpec(task_schema.TypedTaskSpec):
    """The whole task file (see the module docstring): the keys of
    :class:`drake_lfd.io.task_schema.TypedTaskSpec` (``people:`` and ``collaboration:``
    :mod:`~drake_lfd.io.people_schema`'s records), its ``simulation:`` block a
    :class:`~drake_lfd.io.simulation_config.PipelineConfig`."""

    simulation: PipelineConfig = dataclasses.field(default_factory=PipelineConfig)


# ----------------------------------------------------------------------------- loading


def load_task_spec(path):
    """Reads a task file into a :class:`TaskSpec` (structure checked, values not yet).

    Raises
    ------
    InputError
        Unreadable file, invalid YAML, a duplicated or unknown key, a value of the
        wrong kind; naming the file and the field.
    """
    path = Path(path)
    return task_spec_from_text(read_text(path), file=path)


def task_spec_from_text(text, *, file=None):
    """Like :func:`load_task_spec` for YAML text; ``file`` is named in errors."""
    return load_spec(text, TaskSpec, file=file, **task_schema.TASK_FILE_WORDS)


def _pose(values):
    p, euler = values
    return rigid_transform_from_euler_zyx(np.array(p), np.array(euler))


def _box(values):
    name, centre, size, euler = values
    rotation = rigid_transform_from_euler_zyx(np.zeros(3), np.array(euler)).rotation()
    return Box(name=name, centre=np.array(centre), size=np.array(size), rotation=rotation)


def _tool_shape(values):
    if values[0] == "box":
        _, name, size, pose = values
        return ToolShape.box(name, np.array(size), _pose(pose))
    _, name, radius, length, pose = values
    return ToolShape.cylinder(name, radius, length, _pose(pose))


def _deviation(values):
    return None if values is None else DeviationBound(**values)


def task_from_spec(spec, *, file=None):
    """Checks the values of a :class:`TaskSpec` (:func:`~drake_lfd.io.task_checks.check_task_values`)
    and returns the :class:`Task`.

    Raises
    ------
    InputError
        Non-finite numbers, ``lower > upper``, fewer than 2 critical configurations,
        unknown variables, non-positive box sizes, constraint numbers out of range.
    """
    checked = check_task_values(spec, file=file, judge=RECORD_JUDGE)
    optional = {} if checked.angle_grid_deg is None else {"angle_grid_deg": checked.angle_grid_deg}
    refinement = None
    if checked.refinement is not None:
        whole, spans = checked.refinement
        refinement = RefinementBounds(max_deviation=DeviationBound(**whole),
                                      spans=tuple(DeviationBound(**span) for span in spans))
    return Task(
        name=checked.name,
        critical_configurations=tuple(CriticalConfiguration(**con) for con in checked.critical_configurations),
        X_WB=_pose(checked.X_WB),
        X_tool0_E=_pose(checked.X_tool0_E),
        variables=checked.variables,
        obstacles=tuple(_box(box) for box in checked.obstacles),
        safety_shells=tuple(_box(box) for box in checked.safety_shells),
        path_constraints=tuple(
            PathConstraint(**dict(constraint, euler_zyx=np.array(constraint["euler_zyx"]),
                                  max_deviation=_deviation(constraint["max_deviation"])))
            for constraint in checked.path_constraints),
        description=checked.description,
        file=None if file is None else str(file),
        simulation=checked.simulation,
        tool=None if checked.tool is None else tuple(_tool_shape(shape) for shape in checked.tool),
        timing=TimingLimits(**checked.timing),
        people=people_records(checked.people),
        collaboration=None if checked.collaboration is None else CollaborationParameters(**checked.collaboration),
        refinement=refinement,
        **optional,
    )


def load_task(path):
    """Reads and checks a task file.

    Parameters
    ----------
    path : str or Path

    Returns
    -------
    task : Task

    Raises
    ------
    InputError
        Naming the file and the field.
    """
    return task_from_spec(load_task_spec(path), file=Path(path))
