"""The tool and what it holds: boxes and cylinders fixed to the flange frame ``tool0``.

A :class:`ToolShape` is one solid of the tool (a gripper body, a held cup, a
screwdriver), posed in ``tool0`` by ``X_tool0_S``; a cylinder's axis is the shape
frame's z axis, centred on its origin (Drake's ``Cylinder``). A task's tool is a tuple
of them: the task file's ``tool:`` block (docs/task_files.rst), or, when the block is
absent, :func:`default_tool` of the task's end-effector frame: a cylinder of
:data:`DEFAULT_TOOL_RADIUS_M` from the flange to E, so whatever carries E out there is
part of every collision and shell check. :func:`tool_shapes` resolves the two.

Not for: registering the shapes on a plant (``robot/scene.py``) or reading the YAML
(:mod:`drake_lfd.io.task_files`).
"""

from __future__ import annotations

import dataclasses

import numpy as np
from pydrake.math import RigidTransform, RotationMatrix

from drake_lfd.core.read_only_arrays import read_only_array

__all__ = [
    "TOOL_SHAPE_KINDS",
    "DEFAULT_TOOL_RADIUS_M",
    "DEFAULT_TOOL_NAME",
    "MIN_DEFAULT_TOOL_LENGTH_M",
    "ToolShape",
    "default_tool",
    "tool_shapes",
]

TOOL_SHAPE_KINDS = ("box", "cylinder")
#: Radius of the default tool: the UR5e's flange (ISO 9409-1-50-4-M6) is 63 mm across,
#: and a tool bolted to it (the cup holder and screwdriver of the paper's tasks) is about
#: as wide, so 30 mm, just inside the model's 32 mm flange disc.
DEFAULT_TOOL_RADIUS_M = 0.03
DEFAULT_TOOL_NAME = "default"
#: E closer to the flange than this has no default tool: the flange itself covers it.
MIN_DEFAULT_TOOL_LENGTH_M = 0.005


@dataclasses.dataclass(frozen=True, eq=False)
class ToolShape:
    """One solid of the tool, fixed to ``tool0``.

    Attributes
    ----------
    name : str
        Unique in the tool; the geometry is reported as ``tool/<name>``.
    kind : {"box", "cylinder"}
    size : array, shape (3,)
        Full edge lengths of a box, metres (zeros for a cylinder).
    radius, length : float
        A cylinder's radius and full length along its z axis, metres (0 for a box).
    X_tool0_S : RigidTransform
        The shape's frame S in ``tool0`` (its centre; a cylinder's axis is S's z).
    """

    name: str
    kind: str
    size: np.ndarray = dataclasses.field(default_factory=lambda: np.zeros(3))
    radius: float = 0.0
    length: float = 0.0
    X_tool0_S: RigidTransform = dataclasses.field(default_factory=RigidTransform)

    def __post_init__(self):
        if self.kind not in TOOL_SHAPE_KINDS:
            raise ValueError(f"kind must be one of {TOOL_SHAPE_KINDS}, got {self.kind!r}")
        object.__setattr__(self, "size", read_only_array(self.size, (3,)))
        object.__setattr__(self, "X_tool0_S", RigidTransform(self.X_tool0_S))
        if self.kind == "box" and not np.all(self.size > 0.0):
            raise ValueError(f"a box tool shape needs edges > 0, got {self.size.tolist()}")
        if self.kind == "cylinder" and not (self.radius > 0.0 and self.length > 0.0):
            raise ValueError(f"a cylinder tool shape needs radius and length > 0, got {self.radius}, {self.length}")

    @classmethod
    def box(cls, name, size, X_tool0_S=None) -> "ToolShape":
        return cls(name=name, kind="box", size=size, X_tool0_S=RigidTransform() if X_tool0_S is None else X_tool0_S)

    @classmethod
    def cylinder(cls, name, radius, length, X_tool0_S=None) -> "ToolShape":
        return cls(name=name, kind="cylinder", radius=float(radius), length=float(length),
                   X_tool0_S=RigidTransform() if X_tool0_S is None else X_tool0_S)

    @property
    def geometry_name(self) -> str:
        """``tool/<name>``, how checks and monitors report it."""
        return f"tool/{self.name}"


def default_tool(X_tool0_E: RigidTransform | None) -> tuple:
    """The tool assumed when a task does not describe one: a cylinder of radius
    :data:`DEFAULT_TOOL_RADIUS_M` whose axis runs from the flange's centre to E's origin,
    or nothing when E is within :data:`MIN_DEFAULT_TOOL_LENGTH_M` of the flange.

    Returns
    -------
    tuple of ToolShape
        ``()`` or one cylinder named ``default``.
    """
    p = np.zeros(3) if X_tool0_E is None else np.asarray(X_tool0_E.translation(), dtype=float)
    length = float(np.linalg.norm(p))
    if length < MIN_DEFAULT_TOOL_LENGTH_M:
        return ()
    # A rotation taking z onto the flange-to-E direction (any one: the cylinder is round).
    axis = p / length
    R = RotationMatrix.MakeFromOneVector(axis, 2)
    return (ToolShape.cylinder(DEFAULT_TOOL_NAME, DEFAULT_TOOL_RADIUS_M, length, RigidTransform(R, p / 2.0)),)


def tool_shapes(tool, X_tool0_E: RigidTransform | None) -> tuple:
    """The tool's shapes: ``tool`` itself, or :func:`default_tool` when it is None."""
    return default_tool(X_tool0_E) if tool is None else tuple(tool)
