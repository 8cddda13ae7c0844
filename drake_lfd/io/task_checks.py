"""A task file's values checked, in plain Python, and the command line's check before Drake loads.

:func:`check_task_values` checks every value of a task file's ``*Spec`` records
(``task_schema.py``) in the order the file is read: poses, the angle grid, variables,
critical configurations (ranges ``[lower, upper]`` with ``lower <= upper``, known
variables), boxes, path constraints, the ``simulation:`` block, the tool, timing,
people, collaboration, refinement. It returns them as plain numbers
(:class:`CheckedTask`), which :func:`drake_lfd.io.task_files.task_from_spec` makes the
:class:`~drake_lfd.core.tasks.Task` of; nothing here imports Drake or numpy.

So the command line checks a task file whole before Drake loads (:func:`precheck_task_file`,
and :func:`precheck_people_file` for ``simulate --people``): the structure as today, the
loader's structure check with the typed blocks, the values as the loader reads them
(``yaml_checks.plain_load``), then these checks, with the loader's messages in the
loader's order. Where only Drake can judge (Drake's structs in a ``simulation:`` block,
a body's proportions, a track's CSV) the early check stops, and loading the file finds
the rest, as before.

Every problem is one :class:`~drake_lfd.core.errors.InputError` naming the file and the
field (``critical_configurations[3].p[2]``, list indices from 0; the message also names
the 1-based ``con_4``).

Not for: the keys (``task_schema.py``), the records (``task_files.py``, ``core/tasks.py``),
people's values (``people_checks.py``), the simulation block's (``simulation_schema.py``).
"""

from __future__ import annotations

import dataclasses
import math
import re
from pathlib import Path
from typing import Any

from drake_lfd.core.errors import InputError
from drake_lfd.core.task_terms import MIN_CRITICAL_CONFIGURATIONS, PATH_CONSTRAINT_KINDS
from drake_lfd.io import people_checks
from drake_lfd.io.people_schema import PEOPLE_FILE_WORDS, PeopleFileSpec
from drake_lfd.io.simulation_schema import drake_struct_keys_in
from drake_lfd.io.task_schema import TypedTaskSpec, check_task_text
from drake_lfd.io.yaml_checks import NeedsDrake, check_schema, check_yaml_file, plain_load, read_text
from drake_lfd.io.yaml_values import angle, coordinate, finite, numbers, pose_values, positive, unique_name

__all__ = [
    "MAX_CRITICAL_CONFIGURATIONS",
    "MAX_BOXES",
    "MAX_TOOL_SHAPES",
    "MIN_ANGLE_GRID_DEG",
    "CheckedTask",
    "check_task_values",
    "precheck_task_file",
    "precheck_people_file",
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

_VARIABLE_NAME = re.compile(r"^[A-Za-z_][A-Za-z0-9_]*$")


@dataclasses.dataclass(frozen=True)
class CheckedTask:
    """A task file's values, checked, as plain numbers (the Task's fields).

    Poses are ``(p, euler_zyx)``; a box ``(name, centre, size, euler_zyx)``; a critical
    configuration, a path constraint and a deviation bound the keyword arguments of
    their records (a deviation None when it bounds nothing); a tool shape ``("box", name,
    size, pose)`` or ``("cylinder", name, radius, length, pose)``; ``timing`` and
    ``collaboration`` the values the file gives; ``refinement`` ``(whole, spans)`` or
    None. ``angle_grid_deg`` is None where the file is silent. ``simulation`` is what the
    block's ``checked`` returned.
    """

    name: str
    description: str
    X_WB: tuple
    X_tool0_E: tuple
    angle_grid_deg: float | None
    variables: dict[str, tuple[float, float]]
    critical_configurations: tuple[dict[str, Any], ...]
    obstacles: tuple
    safety_shells: tuple
    path_constraints: tuple[dict[str, Any], ...]
    simulation: Any
    tool: tuple | None
    timing: dict[str, float]
    people: tuple
    collaboration: dict[str, Any] | None
    refinement: tuple | None


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


def _box(spec, *, file, field):
    if not spec.name:
        raise InputError("a box needs a non-empty name", file=file, field=f"{field}.name")
    centre = numbers(spec.centre, 3, file=file, field=f"{field}.centre", convert=coordinate)
    size = numbers(spec.size, 3, file=file, field=f"{field}.size", convert=coordinate)
    for axis in range(3):
        if not size[axis] > 0.0:
            raise InputError(
                f"box edge lengths must be > 0, got {size[axis]:g}", file=file, field=f"{field}.size[{axis}]"
            )
    euler = numbers(spec.euler_zyx, 3, file=file, field=f"{field}.euler_zyx", convert=angle)
    return spec.name, centre, size, euler


def _critical_configuration(con_spec, index, variables, *, file):
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
    return dict(p_lower=p_lower, p_upper=p_upper, p_variables=p_variables, euler_zyx_lower=euler_lower,
                euler_zyx_upper=euler_upper, stop=con_spec.stop)


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
        X_tool0_S = pose_values(spec, file=file, field=field)
        has_cylinder = spec.cylinder.radius != 0.0 or spec.cylinder.length != 0.0
        if bool(spec.box) == has_cylinder:
            raise InputError("give exactly one of box: [x, y, z] or cylinder: {radius: r, length: l}",
                             file=file, field=field)
        if spec.box:
            size = numbers(spec.box, 3, file=file, field=f"{field}.box", convert=coordinate)
            for axis in range(3):
                positive(size[axis], file=file, field=f"{field}.box[{axis}]")
            shapes.append(("box", spec.name, size, X_tool0_S))
        else:
            radius = positive(spec.cylinder.radius, file=file, field=f"{field}.cylinder.radius")
            length = positive(spec.cylinder.length, file=file, field=f"{field}.cylinder.length")
            shapes.append(("cylinder", spec.name, radius, length, X_tool0_S))
    return tuple(shapes)


def check_task_values(spec, *, file=None, judge: people_checks.Judge) -> CheckedTask:
    """Checks the values of a task file's Spec (:class:`~drake_lfd.io.task_schema.TypedTaskSpec`
    or the loader's :class:`~drake_lfd.io.task_files.TaskSpec`); ``judge`` judges what
    plain Python cannot (:class:`~drake_lfd.io.people_checks.Judge`).

    Raises
    ------
    InputError
        Non-finite numbers, ``lower > upper``, fewer than 2 critical configurations,
        unknown variables, non-positive box sizes, constraint numbers out of range.
    NeedsDrake
        Where ``judge`` (or the ``simulation:`` block) needs Drake to go on.
    """
    name = spec.name or (Path(file).stem if file is not None else "task")
    X_WB = pose_values(spec.X_WB, file=file, field="X_WB")
    X_tool0_E = pose_values(spec.X_tool0_E, file=file, field="X_tool0_E")
    grid = None
    if spec.angle_grid_deg is not None:  # None: the Task's default
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
    cons = tuple(_critical_configuration(con_spec, index, variables, file=file)
                 for index, con_spec in enumerate(specs))

    for group, specs_of_group in (("obstacles", spec.obstacles), ("safety_shells", spec.safety_shells)):
        if len(specs_of_group) > MAX_BOXES:
            raise InputError(f"a task has at most {MAX_BOXES} {group.replace('_', ' ')}, got {len(specs_of_group):,} "
                             "(each is a clearance query at every step of the check and the run)",
                             file=file, field=group)
    obstacles = tuple(_box(b, file=file, field=f"obstacles[{i}]") for i, b in enumerate(spec.obstacles))
    shells = tuple(_box(b, file=file, field=f"safety_shells[{i}]") for i, b in enumerate(spec.safety_shells))
    boxes: dict[str, str] = {}
    for group, items in (("obstacles", obstacles), ("safety_shells", shells)):
        for index, box in enumerate(items):
            if box[0] in boxes:
                raise InputError(
                    f"box name {box[0]!r} is used by {boxes[box[0]]} already", file=file, field=f"{group}[{index}].name"
                )
            boxes[box[0]] = f"{group}[{index}]"

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
        euler = numbers(constraint.euler_zyx, 3, file=file, field=f"{base}.euler_zyx", convert=angle)
        tolerance = finite(constraint.tolerance_deg, file=file, field=f"{base}.tolerance_deg")
        if not 0.0 < tolerance <= 180.0:
            raise InputError(
                f"must be in (0, 180] degrees, got {tolerance:g}", file=file, field=f"{base}.tolerance_deg"
            )
        bound = _deviation(constraint.max_deviation.position_m, constraint.max_deviation.rotation_deg,
                           file=file, field=f"{base}.max_deviation")
        constraints.append(dict(kind=constraint.kind, con_from=first, con_to=last, euler_zyx=euler,
                                tolerance_rad=math.radians(tolerance), max_deviation=_bounding(bound)))

    # In the order the Task's keyword arguments were checked when they were built in one place.
    simulation = spec.simulation.checked(file=file)
    tool = _tool(spec.tool, file=file)
    timing = _timing(spec.timing, file=file)
    people = people_checks.check_people(spec.people, file=file, judge=judge)
    collaboration = None if spec.collaboration is None else people_checks.check_collaboration(spec.collaboration,
                                                                                              file=file)
    refinement = _refinement(spec.refinement, len(cons), file=file)
    return CheckedTask(
        name=name, description=spec.description, X_WB=X_WB, X_tool0_E=X_tool0_E, angle_grid_deg=grid,
        variables=variables, critical_configurations=cons, obstacles=obstacles, safety_shells=shells,
        path_constraints=tuple(constraints), simulation=simulation, tool=tool, timing=timing, people=people,
        collaboration=collaboration, refinement=refinement,
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
    """A checked bound on refinement's deviation (the keyword arguments of a
    ``DeviationBound``): ``position_m`` > 0 (metres, within reach), ``rotation_deg`` in
    (0, 180]; either may be absent (None)."""
    position = rotation = None
    if position_m is not None:
        position = positive(coordinate(position_m, file=file, field=f"{field}.position_m"), file=file,
                            field=f"{field}.position_m")
    if rotation_deg is not None:
        degrees = finite(rotation_deg, file=file, field=f"{field}.rotation_deg")
        if not 0.0 < degrees <= 180.0:
            raise InputError(f"must be in (0, 180] degrees, got {degrees:g}", file=file, field=f"{field}.rotation_deg")
        rotation = math.radians(degrees)
    return dict(position_m=position, rotation_rad=rotation, con_from=con_from, con_to=con_to)


def _bounding(bound):
    """``bound``, or None when it bounds nothing (a ``DeviationBound()``)."""
    return None if all(value is None for value in bound.values()) else bound


def _refinement(spec, count, *, file):
    """The checked ``refinement:`` block: ``(whole, spans)``, or None when it sets nothing."""
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
    if _bounding(whole) is None and not spans:
        return None
    return whole, tuple(spans)


def _timing(spec, *, file):
    """The values the ``timing:`` block gives, checked (the rest are TimingLimits' defaults)."""
    values = {}
    for name in ("joint_speed_rad_s", "joint_acceleration_rad_s2", "tool_speed_m_s"):
        if getattr(spec, name) is not None:
            values[name] = positive(getattr(spec, name), file=file, field=f"timing.{name}")
    if spec.tool_acceleration_m_s2 is not None:
        values["tool_acceleration_m_s2"] = positive(spec.tool_acceleration_m_s2, file=file,
                                                    field="timing.tool_acceleration_m_s2")
    if spec.limit_fraction is not None:
        fraction = finite(spec.limit_fraction, file=file, field="timing.limit_fraction")
        if not 0.0 < fraction <= 1.0:
            raise InputError(f"must be in (0, 1], got {fraction:g}", file=file, field="timing.limit_fraction")
        values["limit_fraction"] = fraction
    return values


# ------------------------------------------------------------ the check before Drake loads


def precheck_task_file(path) -> bool:
    """Checks the task file at ``path`` as far as plain Python can, before Drake is
    imported, with the messages and in the order of loading it (:func:`~drake_lfd.io.task_files.load_task`).

    Returns
    -------
    bool
        True when every check ran (loading the file will find nothing more); False when
        it stopped where only Drake can judge (the rest is found when the file is loaded).

    Raises
    ------
    InputError
        A missing or unreadable file, invalid YAML, a typo'd key, a value of the wrong
        kind or out of range, naming the file and the field.
    """
    path = Path(path)
    raw = check_task_text(read_text(path), file=path)  # the structure, simulation and people as mappings
    try:
        if drake_struct_keys_in(raw.get("simulation")):  # only Drake knows their keys
            raise NeedsDrake("Drake's structs in the simulation block")
        check_schema(raw, TypedTaskSpec, "", path)  # as the loader checks it, the blocks typed
        spec = plain_load(raw, TypedTaskSpec)
        check_task_values(spec, file=path, judge=people_checks.EARLY)
    except NeedsDrake:
        return False
    return True


def precheck_people_file(path) -> bool:
    """:func:`precheck_task_file` for a people file (``simulate --people``), as
    :func:`~drake_lfd.io.people_files.load_people_file` reads it."""
    path = Path(path)
    raw = check_yaml_file(read_text(path), PeopleFileSpec, file=path, **PEOPLE_FILE_WORDS)
    try:
        spec = plain_load(raw, PeopleFileSpec)
        people_checks.check_people(spec.people, file=path, judge=people_checks.EARLY)
        if spec.collaboration is not None:
            people_checks.check_collaboration(spec.collaboration, file=path)
    except NeedsDrake:
        return False
    return True
