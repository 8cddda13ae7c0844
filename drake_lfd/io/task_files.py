"""Task files: the YAML form of a task, read and checked into a :class:`~drake_lfd.core.tasks.Task`.

A task file is YAML, loaded with ``pydrake.common.yaml.yaml_load_typed`` into the
``*Spec`` dataclasses of :mod:`drake_lfd.io.task_schema` (unknown keys are errors; that
module checks a file's structure without Drake), then checked value by value into
the :class:`~drake_lfd.core.tasks.Task` of :mod:`drake_lfd.core.tasks` (Eq. 10), whose
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
import math
import re
from pathlib import Path
from typing import Optional

import numpy as np

from drake_lfd.core.errors import InputError
from drake_lfd.core.tasks import (
    MIN_CRITICAL_CONFIGURATIONS,
    PATH_CONSTRAINT_KINDS,
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
from drake_lfd.io.people_files import CollaborationSpec, PersonSpec, collaboration_from_spec, people_from_specs
from drake_lfd.io.simulation_config import PipelineConfig

# The YAML checks (schema, duplicate keys, angle spellings) are shared with guidance
# scripts, so both report problems alike.
from drake_lfd.io.yaml_checks import load_spec, read_text
from drake_lfd.io.yaml_values import angle, coordinate, finite, pose, positive as _positive, unique_name, vector

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

#: Most critical configurations a task may have: planning time grows with the square of
#: their number (100 fixed ones plan in seconds on one core, 200 take minutes).
MAX_CRITICAL_CONFIGURATIONS = 100
#: Most obstacles, and most safety shells, a task may have: every one is a clearance
#: query per robot geometry at every step the plan-time check and the monitor take (a
#: task with thousands planned for minutes at about 1 GB).
MAX_BOXES = 100
#: Most shapes of a ``tool:`` block (each is queried against every box at every step).
MAX_TOOL_SHAPES = 20
#: Finest ``angle_grid_deg``: finer grids are far over the planning limits anyway
#: (planning/problem_size.py), and a grid of 1e-320 deg would be 0 rad.
MIN_ANGLE_GRID_DEG = 1e-3

# No ``from __future__ import annotations`` here: yaml_load_typed reads the Spec fields'
# types at run time and needs them as types, not strings.

# ------------------------------------------------------------------ schema (the YAML)

# The keys and kinds of values are io/task_schema.py's (plain Python, so the command line
# checks a file's structure before Drake loads); the loader's TaskSpec types the
# simulation: block as the Drake structs it is.
@dataclasses.dataclass
class TaskSpec(task_schema.TaskSpec):
    """The whole task file (see the module docstring): the keys of
    :class:`drake_lfd.io.task_schema.TaskSpec`, its ``simulation:`` block a
    :class:`~drake_lfd.io.simulation_config.PipelineConfig`, its ``people:`` and
    ``collaboration:`` blocks :mod:`~drake_lfd.io.people_files`' records."""

    simulation: PipelineConfig = dataclasses.field(default_factory=PipelineConfig)
    # People in the cell and speed and separation monitoring (io/people_files.py).
    people: list[PersonSpec] = dataclasses.field(default_factory=list)
    collaboration: Optional[CollaborationSpec] = dataclasses.field(
        default=None, metadata={"expected": "a mapping of collaboration keys ({} for the defaults)"})


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


def _interval(values, *, file, field, convert, context=""):
    if len(values) != 2:
        raise InputError(
            f"{context}expected [lower, upper], got {len(values)} values", file=file, field=field
        )
    lower = convert(values[0], file=file, field=f"{field}[0]")
    upper = convert(values[1], file=file, field=f"{field}[1]")
    if lower > upper:
        raise InputError(f"{context}lower {lower:g} > upper {upper:g}", file=file, field=field)
    return lower, upper


_VARIABLE_NAME = re.compile(r"^[A-Za-z_][A-Za-z0-9_]*$")


def _box(spec, *, file, field):
    if not spec.name:
        raise InputError("a box needs a non-empty name", file=file, field=f"{field}.name")
    centre = vector(spec.centre, 3, file=file, field=f"{field}.centre", convert=coordinate)
    size = vector(spec.size, 3, file=file, field=f"{field}.size", convert=coordinate)
    for axis in range(3):
        if not size[axis] > 0.0:
            raise InputError(
                f"box edge lengths must be > 0, got {size[axis]:g}", file=file, field=f"{field}.size[{axis}]"
            )
    euler = vector(spec.euler_zyx, 3, file=file, field=f"{field}.euler_zyx", convert=angle)
    rotation = rigid_transform_from_euler_zyx(np.zeros(3), euler).rotation()
    return Box(name=spec.name, centre=centre, size=size, rotation=rotation)


def _tool(specs, *, file):
    """The ``tool:`` block's shapes (None when the block is absent: the default tool)."""
    if specs is None:
        return None
    if len(specs) > MAX_TOOL_SHAPES:
        raise InputError(f"a tool has at most {MAX_TOOL_SHAPES} shapes, got {len(specs):,}", file=file, field="tool")
    shapes, names = [], {}
    for index, spec in enumerate(specs):
        field = f"tool[{index}]"
        unique_name(spec.name, names, what="tool shape", file=file, field=field)
        X_tool0_S = pose(spec, file=file, field=field)
        has_cylinder = spec.cylinder.radius != 0.0 or spec.cylinder.length != 0.0
        if bool(spec.box) == has_cylinder:
            raise InputError("give exactly one of box: [x, y, z] or cylinder: {radius: r, length: l}",
                             file=file, field=field)
        if spec.box:
            size = vector(spec.box, 3, file=file, field=f"{field}.box", convert=coordinate)
            for axis in range(3):
                _positive(size[axis], file=file, field=f"{field}.box[{axis}]")
            shapes.append(ToolShape.box(spec.name, size, X_tool0_S))
        else:
            radius = _positive(spec.cylinder.radius, file=file, field=f"{field}.cylinder.radius")
            length = _positive(spec.cylinder.length, file=file, field=f"{field}.cylinder.length")
            shapes.append(ToolShape.cylinder(spec.name, radius, length, X_tool0_S))
    return tuple(shapes)


def task_from_spec(spec, *, file=None):
    """Checks the values of a :class:`TaskSpec` and returns the :class:`Task`.

    Raises
    ------
    InputError
        Non-finite numbers, ``lower > upper``, fewer than 2 critical configurations,
        unknown variables, non-positive box sizes, constraint numbers out of range.
    """
    name = spec.name or (Path(file).stem if file is not None else "task")
    X_WB = pose(spec.X_WB, file=file, field="X_WB")
    X_tool0_E = pose(spec.X_tool0_E, file=file, field="X_tool0_E")
    grid = finite(spec.angle_grid_deg, file=file, field="angle_grid_deg")
    if not MIN_ANGLE_GRID_DEG <= grid <= 360.0:
        raise InputError(f"must be in [{MIN_ANGLE_GRID_DEG:g}, 360] degrees, got {grid:g}", file=file,
                         field="angle_grid_deg")

    variables = {}
    for variable, values in spec.variables.items():
        field = f"variables.{variable}"
        if not _VARIABLE_NAME.match(variable) or variable == "pi":
            raise InputError(
                f"{variable!r} is not a variable name (letters, digits, '_'; not 'pi')", file=file, field=field
            )
        variables[variable] = _interval(values, file=file, field=field, convert=coordinate)

    cons = []
    specs = spec.critical_configurations
    if len(specs) < MIN_CRITICAL_CONFIGURATIONS:
        raise InputError(
            f"a task needs at least {MIN_CRITICAL_CONFIGURATIONS} critical configurations, got {len(specs)}",
            file=file,
            field="critical_configurations",
        )
    if len(specs) > MAX_CRITICAL_CONFIGURATIONS:
        raise InputError(
            f"a task has at most {MAX_CRITICAL_CONFIGURATIONS} critical configurations, got {len(specs)} "
            "(planning time grows with the square of their number); split the task",
            file=file,
            field="critical_configurations",
        )
    for index, con_spec in enumerate(specs):
        base = f"critical_configurations[{index}]"
        context = f"con_{index + 1}: "
        if len(con_spec.p) != 3:
            raise InputError(f"{context}expected [x, y, z], got {len(con_spec.p)} values", file=file, field=f"{base}.p")
        if len(con_spec.euler_zyx) != 3:
            raise InputError(
                f"{context}expected [yaw, pitch, roll], got {len(con_spec.euler_zyx)} values",
                file=file,
                field=f"{base}.euler_zyx",
            )
        p_lower, p_upper, p_variables = [], [], []
        for axis, entry in enumerate(con_spec.p):
            field = f"{base}.p[{axis}]"
            variable = None
            if isinstance(entry, list):
                lower, upper = _interval(entry, file=file, field=field, convert=coordinate, context=context)
            elif isinstance(entry, str) and _VARIABLE_NAME.match(entry) and entry not in ("nan", "inf"):
                if entry not in variables:
                    known = ", ".join(variables) or "none"
                    raise InputError(
                        f"{context}unknown variable {entry!r} (variables: {known})", file=file, field=field
                    )
                variable = entry
                lower, upper = variables[entry]
            else:
                lower = upper = coordinate(entry, file=file, field=field)
            p_lower.append(lower)
            p_upper.append(upper)
            p_variables.append(variable)
        euler_lower, euler_upper = [], []
        for axis, entry in enumerate(con_spec.euler_zyx):
            field = f"{base}.euler_zyx[{axis}]"
            if isinstance(entry, list):
                lower, upper = _interval(entry, file=file, field=field, convert=angle, context=context)
            else:
                if isinstance(entry, str) and entry in variables:
                    raise InputError(
                        f"{context}variables are for positions; write a bounded angle as "
                        "[lower, upper] (the planner chooses it per configuration)",
                        file=file,
                        field=field,
                    )
                lower = upper = angle(entry, file=file, field=field)
            euler_lower.append(lower)
            euler_upper.append(upper)
        cons.append(
            CriticalConfiguration(
                p_lower=p_lower,
                p_upper=p_upper,
                p_variables=p_variables,
                euler_zyx_lower=euler_lower,
                euler_zyx_upper=euler_upper,
                stop=con_spec.stop,
            )
        )

    boxes = {}
    for group, specs_of_group in (("obstacles", spec.obstacles), ("safety_shells", spec.safety_shells)):
        if len(specs_of_group) > MAX_BOXES:
            raise InputError(f"a task has at most {MAX_BOXES} {group.replace('_', ' ')}, got {len(specs_of_group):,} "
                             "(each is a clearance query at every step of the check and the run)",
                             file=file, field=group)
    obstacles = tuple(_box(b, file=file, field=f"obstacles[{i}]") for i, b in enumerate(spec.obstacles))
    shells = tuple(_box(b, file=file, field=f"safety_shells[{i}]") for i, b in enumerate(spec.safety_shells))
    for group, items in (("obstacles", obstacles), ("safety_shells", shells)):
        for index, box in enumerate(items):
            if box.name in boxes:
                raise InputError(
                    f"box name {box.name!r} is used by {boxes[box.name]} already", file=file, field=f"{group}[{index}].name"
                )
            boxes[box.name] = f"{group}[{index}]"

    constraints = []
    for index, constraint in enumerate(spec.path_constraints):
        base = f"path_constraints[{index}]"
        if constraint.kind not in PATH_CONSTRAINT_KINDS:
            raise InputError(
                f"unknown kind {constraint.kind!r} (known: {', '.join(PATH_CONSTRAINT_KINDS)})",
                file=file,
                field=f"{base}.kind",
            )
        first, last = _between(constraint.between, len(cons), file=file, field=f"{base}.between")
        euler = vector(constraint.euler_zyx, 3, file=file, field=f"{base}.euler_zyx", convert=angle)
        tolerance = finite(constraint.tolerance_deg, file=file, field=f"{base}.tolerance_deg")
        if not 0.0 < tolerance <= 180.0:
            raise InputError(
                f"must be in (0, 180] degrees, got {tolerance:g}", file=file, field=f"{base}.tolerance_deg"
            )
        bound = _deviation(constraint.max_deviation.position_m, constraint.max_deviation.rotation_deg,
                           file=file, field=f"{base}.max_deviation")
        constraints.append(
            PathConstraint(
                kind=constraint.kind,
                con_from=first,
                con_to=last,
                euler_zyx=euler,
                tolerance_rad=math.radians(tolerance),
                max_deviation=None if bound == DeviationBound() else bound,
            )
        )

    return Task(
        name=name,
        critical_configurations=tuple(cons),
        X_WB=X_WB,
        X_tool0_E=X_tool0_E,
        angle_grid_deg=grid,
        variables=variables,
        obstacles=obstacles,
        safety_shells=shells,
        path_constraints=tuple(constraints),
        description=spec.description,
        file=None if file is None else str(file),
        simulation=spec.simulation.checked(file=file),
        tool=_tool(spec.tool, file=file),
        timing=_timing(spec.timing, file=file),
        people=people_from_specs(spec.people, file=file),
        collaboration=None if spec.collaboration is None else collaboration_from_spec(spec.collaboration, file=file),
        refinement=_refinement(spec.refinement, len(cons), file=file),
    )


def _between(values, count, *, file, field):
    """``between: [j, k]``: two critical configuration numbers, ``1 <= j < k <= count``."""
    if len(values) != 2:
        raise InputError(f"expected [j, k] (critical configuration numbers), got {len(values)} values",
                         file=file, field=field)
    first, last = (int(v) for v in values)
    if not 1 <= first < last <= count:
        raise InputError(f"[{first}, {last}] must satisfy 1 <= j < k <= {count} (con numbers start at 1)",
                         file=file, field=field)
    return first, last


def _deviation(position_m, rotation_deg, *, file, field, con_from=None, con_to=None):
    """A checked bound on refinement's deviation: ``position_m`` > 0 (metres, within
    reach), ``rotation_deg`` in (0, 180]; either may be absent (None)."""
    position = rotation = None
    if position_m is not None:
        position = _positive(coordinate(position_m, file=file, field=f"{field}.position_m"), file=file,
                             field=f"{field}.position_m")
    if rotation_deg is not None:
        degrees = finite(rotation_deg, file=file, field=f"{field}.rotation_deg")
        if not 0.0 < degrees <= 180.0:
            raise InputError(f"must be in (0, 180] degrees, got {degrees:g}", file=file, field=f"{field}.rotation_deg")
        rotation = math.radians(degrees)
    return DeviationBound(position_m=position, rotation_rad=rotation, con_from=con_from, con_to=con_to)


def _refinement(spec, count, *, file):
    """The checked ``refinement:`` block (None when it sets nothing)."""
    whole = _deviation(spec.max_deviation.position_m, spec.max_deviation.rotation_deg, file=file,
                       field="refinement.max_deviation")
    spans = []
    for index, span in enumerate(spec.spans):
        field = f"refinement.spans[{index}]"
        first, last = _between(span.between, count, file=file, field=f"{field}.between")
        if span.position_m is None and span.rotation_deg is None:
            raise InputError("give position_m, rotation_deg or both", file=file, field=field)
        spans.append(_deviation(span.position_m, span.rotation_deg, file=file, field=field, con_from=first,
                                con_to=last))
    if whole == DeviationBound() and not spans:
        return None
    return RefinementBounds(max_deviation=whole, spans=tuple(spans))


def _timing(spec, *, file):
    """The checked ``timing:`` block as :class:`~drake_lfd.core.timing.TimingLimits`."""
    values = {}
    for name in ("joint_speed_rad_s", "joint_acceleration_rad_s2", "tool_speed_m_s"):
        values[name] = _positive(getattr(spec, name), file=file, field=f"timing.{name}")
    if spec.tool_acceleration_m_s2 is not None:
        values["tool_acceleration_m_s2"] = _positive(spec.tool_acceleration_m_s2, file=file,
                                                     field="timing.tool_acceleration_m_s2")
    fraction = finite(spec.limit_fraction, file=file, field="timing.limit_fraction")
    if not 0.0 < fraction <= 1.0:
        raise InputError(f"must be in (0, 1], got {fraction:g}", file=file, field="timing.limit_fraction")
    return TimingLimits(limit_fraction=fraction, **values)


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
