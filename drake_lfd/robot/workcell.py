"""The one description of the work cell: robot base, table, obstacles, shells and tool.

:class:`Workcell` is what every consumer of a task's scene reads: ``drake-lfd plan`` (the
floor it keeps the tool above), the pipeline Diagram and its station (the geometry on
the plant, the planner system's floor), the initial inverse kinematics and the
kinematic checks (:class:`~drake_lfd.robot.scene.KinematicScene`), recordings and
figures. :meth:`Workcell.of` makes it from a task, so a plan and a run of the same task
see the same scene.

Transformed with the robot base: the table under the robot (:func:`table_under_robot`)
is turned with ``X_WB``, its top in the base's xy plane; the tool's shapes are fixed to
``tool0`` (:mod:`drake_lfd.core.tool`). Obstacles and shells are the task's, in W.

Not for: putting the geometry on a plant (``scene.py``).
"""

from __future__ import annotations

import dataclasses

import numpy as np
from pydrake.math import RigidTransform

from drake_lfd.core.tasks import Box
from drake_lfd.core.tool import tool_shapes

__all__ = ["TABLE_SIZE_M", "LEVEL_TOLERANCE", "table_under_robot", "Workcell"]

#: The default table: 1.6 x 1.2 m, 4 cm thick.
TABLE_SIZE_M = (1.6, 1.2, 0.04)
#: A table is level when each component of its top's normal is this close to +z's: the
#: planner's floor is then the plane z = top.
LEVEL_TOLERANCE = 1e-12


def table_under_robot(X_WB: RigidTransform | None = None, *, size=TABLE_SIZE_M, name="table") -> Box:
    """A table whose top is flush with the base of the robot, centred under it and turned
    with it (the base's z axis is the top's normal).

    Not watched by the shell monitor (the base stands on it); the arm touching it is
    real contact.
    """
    X_WB = RigidTransform() if X_WB is None else X_WB
    size = np.asarray(size, dtype=float)
    centre = X_WB.multiply(np.array([0.0, 0.0, -0.5 * size[2]]))
    return Box(name=name, centre=centre, size=size, rotation=X_WB.rotation().matrix())


@dataclasses.dataclass(frozen=True, eq=False)
class Workcell:
    """The scene of a task, as planning and simulation both see it.

    Attributes
    ----------
    X_WB, X_tool0_E : RigidTransform
    obstacles, safety_shells : tuple of Box
        In W.
    table : Box or None
        The table the robot stands on.
    tool : tuple of :class:`~drake_lfd.core.tool.ToolShape`
        Resolved: the task's shapes, or the default sized from ``X_tool0_E``.
    """

    X_WB: RigidTransform = dataclasses.field(default_factory=RigidTransform)
    X_tool0_E: RigidTransform = dataclasses.field(default_factory=RigidTransform)
    obstacles: tuple = ()
    safety_shells: tuple = ()
    table: Box | None = None
    tool: tuple = ()

    def __post_init__(self):
        object.__setattr__(self, "X_WB", RigidTransform(self.X_WB))
        object.__setattr__(self, "X_tool0_E", RigidTransform(self.X_tool0_E))
        for name in ("obstacles", "safety_shells", "tool"):
            object.__setattr__(self, name, tuple(getattr(self, name)))

    @classmethod
    def make(cls, *, X_WB=None, X_tool0_E=None, obstacles=(), safety_shells=(), table=None,
             tool=None) -> "Workcell":
        """A work cell from its parts; ``tool`` None gives the default tool of
        ``X_tool0_E`` (``()``: none)."""
        X_WB = RigidTransform() if X_WB is None else X_WB
        X_tool0_E = RigidTransform() if X_tool0_E is None else X_tool0_E
        return cls(X_WB=X_WB, X_tool0_E=X_tool0_E, obstacles=tuple(obstacles),
                   safety_shells=tuple(safety_shells), table=table, tool=tool_shapes(tool, X_tool0_E))

    @classmethod
    def of(cls, task, *, with_table: bool = True) -> "Workcell":
        """The work cell of a task (a ``Task`` or ``ConcreteTask``): its base, tool frame,
        boxes and tool, and (``with_table``) the table under the robot."""
        return cls.make(X_WB=task.X_WB, X_tool0_E=task.X_tool0_E, obstacles=task.obstacles,
                        safety_shells=task.safety_shells,
                        table=table_under_robot(task.X_WB) if with_table else None,
                        tool=getattr(task, "tool", None))

    @property
    def keep_out(self) -> tuple:
        """Obstacles then shells: what no robot or tool geometry may penetrate."""
        return self.obstacles + self.safety_shells

    @property
    def planner_floor(self) -> float | Box | None:
        """What the SE(3) planner keeps the tool above (its ``floor_z``): the height of a
        level table's top, the table itself when it is tilted (the plane of its top
        face), None without a table."""
        table = self.table
        if table is None:
            return None
        if np.allclose(table.rotation[:, 2], [0.0, 0.0, 1.0], rtol=0.0, atol=LEVEL_TOLERANCE):
            return float(table.centre[2] + table.size[2] / 2)
        return table
