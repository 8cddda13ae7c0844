"""The task data model: critical configurations, boxes, path constraints and trials (Eq. 10).

A task ``TK`` is a sequence of critical configurations ``con_i = <P_i, theta_i>`` the
end-effector frame E must pass through, numbered from 1 as in the paper. A
:class:`Task` states each con with its ranges: a position coordinate is fixed, drawn
from a range per trial, or shared with other coordinates through a named variable; an
orientation angle ``euler_zyx = [yaw, pitch, roll]`` (``R = Rz(yaw) Ry(pitch) Rx(roll)``,
Eq. 17; :func:`rigid_transform_from_euler_zyx`) is fixed or bounded, a bounded one being
a freedom the planner chooses among :func:`angle_candidates`. :func:`draw_trial` draws a
:class:`ConcreteTask` (every position fixed, bounded angles still free) from a task and a
seed; :meth:`ConcreteTask.from_fixed` builds one directly (random training tasks).
Obstacles and keep-out safety shells are :class:`Box` es in W, axis-aligned unless
given a ``rotation``; a task's ``tool`` is its shapes fixed to ``tool0``
(:mod:`drake_lfd.core.tool`; None: the default sized from ``X_tool0_E``).

The meaning of tasks is in docs/method.rst (Tasks); the file format in
docs/task_files.rst.

Not for: reading task files (:mod:`drake_lfd.io.task_files` checks the YAML into these
types), planning (the planners), simulating the scene (``robot/scene.py``, the
closed-loop diagram).
"""

import dataclasses
import fractions
import itertools
import math
from typing import TYPE_CHECKING

import numpy as np
from pydrake.math import RigidTransform, RollPitchYaw, RotationMatrix

from drake_lfd.core.errors import InputError
from drake_lfd.core.read_only_arrays import read_only_array
# Plain Python, so a task file is checked against them before Drake loads.
from drake_lfd.core.task_terms import MIN_CRITICAL_CONFIGURATIONS, PATH_CONSTRAINT_KINDS

if TYPE_CHECKING:
    from drake_lfd.core.timing import TimingLimits

__all__ = [
    "DEFAULT_ANGLE_GRID_DEG",
    "MIN_CRITICAL_CONFIGURATIONS",
    "PATH_CONSTRAINT_KINDS",
    "Box",
    "PathConstraint",
    "DeviationBound",
    "RefinementBounds",
    "DEFAULT_REFINEMENT_POSITION_M",
    "DEFAULT_REFINEMENT_ROTATION_RAD",
    "CriticalConfiguration",
    "Task",
    "ConcreteCriticalConfiguration",
    "ConcreteTask",
    "rigid_transform_from_euler_zyx",
    "angle_grid_count",
    "angle_grid",
    "angle_candidates",
    "draw_trial",
    "stops_of",
]

DEFAULT_ANGLE_GRID_DEG = 15.0
#: How far ``--refine`` may move E from the composed path where the task file does not
#: say (docs/method.rst, Refinement by trajectory optimization, measures the trade-off).
DEFAULT_REFINEMENT_POSITION_M = 0.15
DEFAULT_REFINEMENT_ROTATION_RAD = math.radians(30.0)


def rigid_transform_from_euler_zyx(p, euler_zyx):
    """The ``RigidTransform`` of a position and [yaw, pitch, roll], ``R = Rz Ry Rx``
    (docs/method.rst, Conventions)."""
    yaw, pitch, roll = (float(v) for v in euler_zyx)
    return RigidTransform(RollPitchYaw(roll, pitch, yaw), np.asarray(p, dtype=float))


# ------------------------------------------------------------------------- task types


@dataclasses.dataclass(frozen=True, eq=False)
class Box:
    """A box: ``centre`` (3,) and full edge lengths ``size`` (3,), metres, its edges along
    the columns of ``rotation`` (3, 3), the box frame's axes in W (default identity:
    axis-aligned)."""

    name: str
    centre: np.ndarray
    size: np.ndarray
    rotation: np.ndarray = dataclasses.field(default_factory=lambda: np.eye(3))

    def __post_init__(self):
        object.__setattr__(self, "centre", read_only_array(self.centre, (3,)))
        object.__setattr__(self, "size", read_only_array(self.size, (3,)))
        rotation = self.rotation
        if isinstance(rotation, RotationMatrix):
            rotation = rotation.matrix()
        object.__setattr__(self, "rotation", read_only_array(rotation, (3, 3)))
        if not np.allclose(self.rotation.T @ self.rotation, np.eye(3), rtol=0.0, atol=1e-9):
            raise ValueError("Box.rotation must be a rotation matrix")

    @property
    def is_axis_aligned(self) -> bool:
        return bool(np.array_equal(self.rotation, np.eye(3)))

    @property
    def X_WBox(self) -> RigidTransform:
        """The box frame (centre, axes along the edges) in W."""
        return RigidTransform(RotationMatrix(np.array(self.rotation)), np.array(self.centre))

    def _local(self, points) -> np.ndarray:
        points = np.atleast_2d(np.asarray(points, dtype=float))
        return (points - self.centre) @ self.rotation  # rows: R^T (p - centre)

    def signed_distance(self, points) -> np.ndarray:
        """Signed distance of points (n, 3) in W to the box (negative inside), (n,), m."""
        q = np.abs(self._local(points)) - self.size / 2.0
        outside = np.linalg.norm(np.maximum(q, 0.0), axis=1)
        return outside + np.minimum(q.max(axis=1), 0.0)

    def height_above_top(self, points) -> np.ndarray:
        """Height of points (n, 3) above the plane of the box's top face (the face its
        own +z axis points out of), (n,), m: a table top as an unbounded floor."""
        return self._local(points)[:, 2] - self.size[2] / 2.0

    def corners(self) -> np.ndarray:
        """The 8 corners in W, shape (8, 3), ordered as ``itertools.product((-1, 1),
        repeat=3)`` of the half edges."""
        signs = np.array(list(itertools.product((-1.0, 1.0), repeat=3)))
        return self.centre + (signs * (self.size / 2.0)) @ self.rotation.T


@dataclasses.dataclass(frozen=True)
class DeviationBound:
    """How far refinement (``--refine``) may move E from the composed path, at matching
    path fractions: within ``position_m`` and ``rotation_rad`` (None: this bound leaves
    that one to the wider bounds), from ``con_from`` to ``con_to`` (1-based, inclusive;
    None for the whole task)."""

    position_m: float | None = None
    rotation_rad: float | None = None
    con_from: int | None = None
    con_to: int | None = None


@dataclasses.dataclass(frozen=True)
class RefinementBounds:
    """The task file's ``refinement:`` block: ``max_deviation`` for the whole task (None
    fields: :data:`DEFAULT_REFINEMENT_POSITION_M`, :data:`DEFAULT_REFINEMENT_ROTATION_RAD`,
    or the refinement's options) and ``spans``, :class:`DeviationBound` s that replace it
    from one critical configuration to another (the tighter where two overlap). A path
    constraint bounds the rotation besides (:attr:`PathConstraint.max_deviation`)."""

    max_deviation: DeviationBound = DeviationBound()
    spans: tuple = ()

    def __post_init__(self):
        object.__setattr__(self, "spans", tuple(self.spans))


@dataclasses.dataclass(frozen=True, eq=False)
class PathConstraint:
    """Keep the tool orientation within ``tolerance_rad`` of ``euler_zyx`` (3,) from
    ``con_from`` to ``con_to`` (1-based, inclusive).

    ``max_deviation`` bounds how far refinement may move E from the composed path over
    the constraint's spans, on top of every other bound (a :class:`DeviationBound`; None:
    the rotation within ``tolerance_rad``, the position as the other bounds say), so a
    refined motion does not turn what the constraint holds still."""

    kind: str
    con_from: int
    con_to: int
    euler_zyx: np.ndarray
    tolerance_rad: float
    max_deviation: DeviationBound | None = None

    def __post_init__(self):
        object.__setattr__(self, "euler_zyx", read_only_array(self.euler_zyx, (3,)))


@dataclasses.dataclass(frozen=True, eq=False)
class CriticalConfiguration:
    """``con_i`` as the task file states it, with its ranges.

    Attributes
    ----------
    p_lower, p_upper : array, shape (3,)
        Position bounds (equal for a fixed coordinate), metres.
    p_variables : tuple of 3 (str or None)
        The variable each coordinate names, or None.
    euler_zyx_lower, euler_zyx_upper : array, shape (3,)
        [yaw, pitch, roll] bounds (equal for a fixed angle), radians.
    stop : bool or None
        Whether the tool comes to rest here; None: the default (at the first and the
        last configuration only; see :func:`stops_of`).
    """

    p_lower: np.ndarray
    p_upper: np.ndarray
    p_variables: tuple
    euler_zyx_lower: np.ndarray
    euler_zyx_upper: np.ndarray
    stop: bool | None = None

    def __post_init__(self):
        for name in ("p_lower", "p_upper", "euler_zyx_lower", "euler_zyx_upper"):
            object.__setattr__(self, name, read_only_array(getattr(self, name), (3,)))
        object.__setattr__(self, "p_variables", tuple(self.p_variables))


@dataclasses.dataclass(frozen=True, eq=False)
class Task:
    """A checked task (a task file as :func:`~drake_lfd.io.task_files.load_task` returns it);
    :func:`draw_trial` makes concrete trials of it."""

    name: str
    critical_configurations: tuple
    X_WB: RigidTransform = dataclasses.field(default_factory=RigidTransform)
    X_tool0_E: RigidTransform = dataclasses.field(default_factory=RigidTransform)
    angle_grid_deg: float = DEFAULT_ANGLE_GRID_DEG
    variables: dict = dataclasses.field(default_factory=dict)  # name -> (lower, upper)
    obstacles: tuple = ()
    safety_shells: tuple = ()
    path_constraints: tuple = ()
    description: str = ""
    file: str | None = None
    # The task file's optional ``simulation:`` block, checked: an
    # ``io.simulation_config.PipelineConfig`` (None: the defaults).
    simulation: object = None
    # The tool's shapes on tool0 (tuple of core.tool.ToolShape); None: the default
    # sized from X_tool0_E (core.tool.default_tool), () for no tool geometry.
    tool: tuple | None = None
    # The task file's ``timing:`` block, checked (None: the defaults).
    timing: "TimingLimits | None" = None
    # The people in the cell (tuple of core.people.Person; () for none) and the task
    # file's ``collaboration:`` block, checked: a core.people.CollaborationParameters
    # (None: the defaults).
    people: tuple = ()
    collaboration: object = None
    # The task file's ``refinement:`` block: a RefinementBounds (None: the defaults).
    refinement: RefinementBounds | None = None

    def __len__(self):
        return len(self.critical_configurations)


@dataclasses.dataclass(frozen=True, eq=False)
class ConcreteCriticalConfiguration:
    """``con_i`` of one trial: a fixed position, angles fixed or bounded.

    Attributes
    ----------
    p : array, shape (3,)
        Position in W, metres.
    euler_zyx_lower, euler_zyx_upper : array, shape (3,)
        [yaw, pitch, roll] bounds in radians; equal where the angle is fixed.
    angle_grid_deg : float
        Grid step for the bounded angles (:func:`angle_candidates`).
    stop : bool or None
        As :attr:`CriticalConfiguration.stop`.
    """

    p: np.ndarray
    euler_zyx_lower: np.ndarray
    euler_zyx_upper: np.ndarray
    angle_grid_deg: float = DEFAULT_ANGLE_GRID_DEG
    stop: bool | None = None

    def __post_init__(self):
        for name in ("p", "euler_zyx_lower", "euler_zyx_upper"):
            object.__setattr__(self, name, read_only_array(getattr(self, name), (3,)))
        if np.any(self.euler_zyx_lower > self.euler_zyx_upper):
            raise ValueError("euler_zyx_lower must be <= euler_zyx_upper")
        if not self.angle_grid_deg > 0.0:
            raise ValueError(f"angle_grid_deg must be > 0, got {self.angle_grid_deg}")

    @classmethod
    def fixed(cls, p, euler_zyx):
        """A configuration with every angle fixed."""
        return cls(p=p, euler_zyx_lower=euler_zyx, euler_zyx_upper=euler_zyx)

    @property
    def is_orientation_fixed(self) -> bool:
        return bool(np.all(self.euler_zyx_lower == self.euler_zyx_upper))

    @property
    def euler_zyx(self) -> np.ndarray:
        """The fixed [yaw, pitch, roll], shape (3,); ValueError if any angle is bounded."""
        if not self.is_orientation_fixed:
            raise ValueError("this configuration has bounded angles; choose one of angle_candidates()")
        return self.euler_zyx_lower


@dataclasses.dataclass(frozen=True, eq=False)
class ConcreteTask:
    """One trial of a task: every position drawn, bounded angles still free."""

    name: str
    critical_configurations: tuple
    X_WB: RigidTransform = dataclasses.field(default_factory=RigidTransform)
    X_tool0_E: RigidTransform = dataclasses.field(default_factory=RigidTransform)
    obstacles: tuple = ()
    safety_shells: tuple = ()
    path_constraints: tuple = ()
    seed: int | None = None
    variable_values: dict = dataclasses.field(default_factory=dict)  # name -> drawn value
    file: str | None = None
    tool: tuple | None = None  # as Task.tool
    timing: "TimingLimits | None" = None  # as Task.timing
    simulation: object = None  # as Task.simulation (the checker of drake_lfd.plan_task reads its margins)
    refinement: RefinementBounds | None = None  # as Task.refinement

    def __post_init__(self):
        object.__setattr__(self, "critical_configurations", tuple(self.critical_configurations))

    def __len__(self):
        return len(self.critical_configurations)

    @property
    def positions(self) -> np.ndarray:
        """Positions of con_1 .. con_n, shape (n, 3)."""
        return np.array([con.p for con in self.critical_configurations])

    @classmethod
    def from_fixed(cls, name, positions, euler_zyx, **kwargs):
        """A task with every angle fixed (for example a random training task).

        Parameters
        ----------
        name : str
        positions : array-like, shape (n, 3)
        euler_zyx : array-like, shape (n, 3)
            [yaw, pitch, roll] per configuration, radians.
        **kwargs
            Other :class:`ConcreteTask` fields (``X_WB``, ``obstacles``, ...).
        """
        positions = np.asarray(positions, dtype=float)
        euler_zyx = np.asarray(euler_zyx, dtype=float)
        return cls(
            name=name,
            critical_configurations=tuple(
                ConcreteCriticalConfiguration.fixed(p, e) for p, e in zip(positions, euler_zyx)
            ),
            **kwargs,
        )


def stops_of(task) -> tuple[bool, ...]:
    """Where the tool comes to rest, one flag per critical configuration: each one's
    ``stop`` where it says, else True at the first and the last and False between."""
    cons = task.critical_configurations
    last = len(cons) - 1
    return tuple(bool(con.stop) if con.stop is not None else i in (0, last) for i, con in enumerate(cons))


# ------------------------------------------------------------------------------ angles


def angle_grid(lower, upper, step_rad):
    """Samples of a bounded angle: ``lower`` to ``upper``, both included, evenly spaced
    at most ``step_rad`` apart. A fixed angle (``lower == upper``) gives one sample.

    Returns
    -------
    angles : array, shape (k,)
    """
    count = angle_grid_count(lower, upper, step_rad)
    if count == 1:
        return np.array([float(lower)])
    return np.linspace(float(lower), float(upper), count)


def angle_grid_count(lower, upper, step_rad):
    """How many samples :func:`angle_grid` gives, computed without making them (a
    Python int, however large: ``planning/problem_size.py`` checks it before anything
    is allocated)."""
    if not step_rad > 0.0:
        raise ValueError(f"the grid step must be positive, got {step_rad!r}")
    span = float(upper) - float(lower)
    if span <= 0.0:
        return 1
    ratio = span / step_rad
    if not math.isfinite(ratio):  # bounds near the float limit: count exactly
        exact = (fractions.Fraction(float(upper)) - fractions.Fraction(float(lower))) / fractions.Fraction(step_rad)
        return math.ceil(exact) + 1
    return int(math.ceil(ratio - 1e-9)) + 1


def angle_candidates(con):
    """Every [yaw, pitch, roll] the planner may choose for ``con`` (docs/method.rst, Tasks).

    Fixed angles keep their value; each bounded one runs over :func:`angle_grid` with
    ``con.angle_grid_deg``; the result is their Cartesian product (yaw slowest).
    A full turn such as ``[-pi, pi]`` includes both ends (the same rotation).

    Parameters
    ----------
    con : ConcreteCriticalConfiguration

    Returns
    -------
    candidates : array, shape (k, 3)
        Rows are (yaw, pitch, roll) in radians; iterate to get triples.
    """
    step = math.radians(con.angle_grid_deg)
    axes = [angle_grid(lo, hi, step) for lo, hi in zip(con.euler_zyx_lower, con.euler_zyx_upper)]
    return np.array(list(itertools.product(*axes)), dtype=float).reshape(-1, 3)


# ------------------------------------------------------------------------------ trials


def draw_trial(task, seed):
    """Draws one concrete trial of a task (the paper runs 20 per task).

    Variables are drawn first, uniformly in their ranges, in sorted name order; then
    each inline position range, con by con, x before y before z. Fixed values draw
    nothing. Bounded angles stay bounded (the planner chooses them).

    Parameters
    ----------
    task : Task
    seed : int
        Non-negative; the same seed gives the same trial.

    Returns
    -------
    trial : ConcreteTask
    """
    if isinstance(seed, bool) or not isinstance(seed, (int, np.integer)) or seed < 0:
        raise InputError(f"expected a non-negative integer, got {seed!r}", field="seed")
    rng = np.random.default_rng(int(seed))
    values = {name: float(rng.uniform(*task.variables[name])) for name in sorted(task.variables)}
    cons = []
    for con in task.critical_configurations:
        p = np.empty(3)
        for axis in range(3):
            variable = con.p_variables[axis]
            lower, upper = con.p_lower[axis], con.p_upper[axis]
            if variable is not None:
                p[axis] = values[variable]
            elif lower == upper:
                p[axis] = lower
            else:
                p[axis] = rng.uniform(lower, upper)
        cons.append(
            ConcreteCriticalConfiguration(
                p=p,
                euler_zyx_lower=con.euler_zyx_lower,
                euler_zyx_upper=con.euler_zyx_upper,
                angle_grid_deg=task.angle_grid_deg,
                stop=con.stop,
            )
        )
    return ConcreteTask(
        name=task.name,
        critical_configurations=tuple(cons),
        X_WB=task.X_WB,
        X_tool0_E=task.X_tool0_E,
        obstacles=task.obstacles,
        safety_shells=task.safety_shells,
        path_constraints=task.path_constraints,
        seed=int(seed),
        variable_values=values,
        file=task.file,
        tool=task.tool,
        timing=task.timing,
        simulation=task.simulation,
        refinement=task.refinement,
    )
