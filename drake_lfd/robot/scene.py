"""The work cell on the plant: obstacles, keep-out safety shells, the table and the tool.

:func:`add_scene` puts a :class:`~drake_lfd.robot.workcell.Workcell`'s geometry on a
plant. Every box is registered through the MultibodyPlant on its world body, posed by
its centre and rotation, with a collision (proximity) and a visual (illustration)
geometry: obstacles red, safety shells translucent purple (as in the paper's Fig. 8),
the table grey. The tool's shapes (:mod:`drake_lfd.core.tool`) are registered on the
body of ``tool0`` (``wrist_3_link``), collision and visual, named ``tool/<name>``: they
join the robot's geometries in every clearance and shell check, and, like the arm's
links (the URDF filters them among themselves), they are filtered out of contact with
the arm. Nothing here registers geometry in SceneGraph directly (the plant throws on
first contact with geometry it did not register itself); SceneGraph is only asked to
filter collisions.

A safety shell is a keep-out volume, not a wall: robot-vs-shell pairs are excluded from
contact with a ``CollisionFilterDeclaration``, so a shell never pushes the robot.
:func:`min_signed_distances` measures those pairs with
``ComputeSignedDistancePairClosestPoints``, which ignores filters; the shell monitor
system and :class:`KinematicScene` both use it. Obstacles are real: the robot would
touch them physically.

:class:`KinematicScene` is the same scene on a kinematics-only plant, to check single
configurations (the initial inverse kinematics, an independent recomputation of a run's
clearances from its logged joint positions).

Not for: building the simulation diagram (``diagrams/station.py``), monitoring a run
(``systems/shell_monitor.py``), the boxes themselves (:class:`~drake_lfd.core.tasks.Box`),
or what the scene holds (``workcell.py``).
"""

from __future__ import annotations

from collections.abc import Iterable, Mapping
from dataclasses import dataclass, field

import numpy as np
from pydrake.geometry import (
    Box as BoxShape,
    CollisionFilterDeclaration,
    Cylinder,
    GeometryId,
    GeometrySet,
    QueryObject,
    Role,
    SceneGraph,
)
from pydrake.math import RigidTransform
from pydrake.multibody.plant import AddMultibodyPlantSceneGraph, CoulombFriction, MultibodyPlant
from pydrake.multibody.tree import ModelInstanceIndex
from pydrake.systems.framework import DiagramBuilder

from drake_lfd.core.exact_memo import ExactMemo, exact_key
from drake_lfd.core.tasks import Box
from drake_lfd.core.tool import ToolShape
from drake_lfd.robot.kinematics import TOOL0_FRAME_NAME, add_ur5e
from drake_lfd.robot.pan_only import pan_only_configuration, pan_only_geometry_ids
from drake_lfd.robot.workcell import Workcell, table_under_robot

__all__ = [
    "ON_TABLE_LINKS",
    "OBSTACLE_RGBA",
    "SAFETY_SHELL_RGBA",
    "TABLE_RGBA",
    "TOOL_RGBA",
    "OBSTACLE",
    "SAFETY_SHELL",
    "SceneGeometry",
    "table_under_robot",
    "robot_geometry_names",
    "add_scene",
    "min_signed_distances",
    "KinematicScene",
]

OBSTACLE_RGBA = np.array([0.85, 0.12, 0.10, 1.0])
SAFETY_SHELL_RGBA = np.array([0.55, 0.25, 0.85, 0.25])
TABLE_RGBA = np.array([0.55, 0.55, 0.55, 1.0])
TOOL_RGBA = np.array([0.25, 0.45, 0.30, 1.0])
# Dry steel-ish friction; only obstacles and the table can touch the robot.
_FRICTION = CoulombFriction(static_friction=0.5, dynamic_friction=0.5)

# Links standing on the table: never checked against it (the joint-path check and the
# trajectory optimization's scene alike).
ON_TABLE_LINKS = ("base_link", "shoulder_link")

OBSTACLE = "obstacle"
SAFETY_SHELL = "safety shell"


@dataclass(frozen=True)
class SceneGeometry:
    """Geometry ids of the robot and the scene, and the names to report them by.

    Attributes
    ----------
    robot_geometry_ids : tuple of GeometryId
        Every collision geometry of the robot model, then the tool's.
    obstacle_geometry_ids, shell_geometry_ids : tuple of GeometryId
        One per obstacle / safety shell, in the order given.
    table_geometry_id : GeometryId or None
    tool_geometry_ids : tuple of GeometryId
        The tool's shapes, in the order given (also in ``robot_geometry_ids``).
    names : mapping GeometryId -> str
        Robot geometries as ``<link>/<geometry>`` (``forearm_link/forearm_tube``), tool
        shapes as ``tool/<name>``, boxes by their task name (``shell_1``).
    kinds : mapping GeometryId -> str
        ``"obstacle"`` or ``"safety shell"`` for each box.
    """

    robot_geometry_ids: tuple
    obstacle_geometry_ids: tuple = ()
    shell_geometry_ids: tuple = ()
    table_geometry_id: GeometryId | None = None
    tool_geometry_ids: tuple = ()
    names: Mapping = field(default_factory=dict)
    kinds: Mapping = field(default_factory=dict)

    @property
    def keep_out_geometry_ids(self) -> tuple:
        """Obstacles then shells: what no robot geometry may penetrate (docs/method.rst,
        Closed loop and success)."""
        return tuple(self.obstacle_geometry_ids) + tuple(self.shell_geometry_ids)

    def describe(self, geometry_id: GeometryId) -> str:
        """``safety shell 'shell_1'``, ``obstacle 'cube'`` or a robot geometry's name."""
        if geometry_id in self.kinds:
            return f"{self.kinds[geometry_id]} '{self.names[geometry_id]}'"
        return self.names.get(geometry_id, str(geometry_id))


def _register_box(plant: MultibodyPlant, box: Box, prefix: str, rgba: np.ndarray) -> GeometryId:
    shape = BoxShape(*np.asarray(box.size, dtype=float))
    X_WG = box.X_WBox
    name = f"{prefix}::{box.name}"
    geometry_id = plant.RegisterCollisionGeometry(plant.world_body(), X_WG, shape, name, _FRICTION)
    plant.RegisterVisualGeometry(plant.world_body(), X_WG, shape, name, rgba)
    return geometry_id


def _register_tool_shape(plant: MultibodyPlant, model: ModelInstanceIndex, shape: ToolShape) -> GeometryId:
    """One tool shape on the body of ``tool0``, collision and visual."""
    tool0 = plant.GetFrameByName(TOOL0_FRAME_NAME, model)
    X_BS = tool0.GetFixedPoseInBodyFrame().multiply(shape.X_tool0_S)
    if shape.kind == "box":
        geometry = BoxShape(*np.asarray(shape.size, dtype=float))
    else:
        geometry = Cylinder(shape.radius, shape.length)
    name = shape.geometry_name
    geometry_id = plant.RegisterCollisionGeometry(tool0.body(), X_BS, geometry, name, _FRICTION)
    plant.RegisterVisualGeometry(tool0.body(), X_BS, geometry, name, TOOL_RGBA)
    return geometry_id


def robot_geometry_names(plant: MultibodyPlant, scene_graph: SceneGraph, model: ModelInstanceIndex) -> dict:
    """``{GeometryId: "<link>/<geometry>"}`` for every collision geometry of ``model``."""
    inspector = scene_graph.model_inspector()
    names = {}
    for body_index in plant.GetBodyIndices(model):
        body = plant.get_body(body_index)
        # The plant's list holds references into a vector that registering more geometry
        # on the body (the tool) reallocates; keep the inspector's copies, in its order.
        copies = inspector.GetGeometries(plant.GetBodyFrameIdOrThrow(body_index), Role.kProximity)
        for reference in plant.GetCollisionGeometriesForBody(body):
            geometry_id = next(copy for copy in copies if copy == reference)
            # SceneGraph names are scoped "<model>::<geometry>"; keep the geometry part.
            short = inspector.GetName(geometry_id).split("::")[-1]
            names[geometry_id] = f"{body.name()}/{short}"
    return names


def add_scene(
    plant: MultibodyPlant,
    scene_graph: SceneGraph,
    *,
    model: ModelInstanceIndex,
    obstacles: Iterable[Box] = (),
    safety_shells: Iterable[Box] = (),
    table: Box | None = None,
    tool: Iterable[ToolShape] = (),
) -> SceneGeometry:
    """Registers the boxes on ``plant``'s world body and the tool on ``model``'s flange,
    and keeps shells from pushing the robot.

    Call after the robot ``model`` has been added (its geometries must exist) and before
    ``plant.Finalize()``. ``plant`` must be registered with ``scene_graph``.

    Parameters
    ----------
    obstacles, safety_shells : iterable of :class:`drake_lfd.core.tasks.Box`
        Boxes in W (``name``, ``centre`` (3,), ``size`` (3,) full edges, ``rotation``).
    table : Box, optional
        A grey box the robot can rest on or touch (see
        :func:`~drake_lfd.robot.workcell.table_under_robot`).
    tool : iterable of :class:`~drake_lfd.core.tool.ToolShape`
        Shapes fixed to ``tool0``; none by default (here: the defaults are the
        work cell's, :class:`~drake_lfd.robot.workcell.Workcell`).

    Returns
    -------
    SceneGeometry
    """
    obstacles, safety_shells = tuple(obstacles), tuple(safety_shells)
    names = robot_geometry_names(plant, scene_graph, model)
    arm_ids = tuple(names)
    tool_ids = []
    for shape in tool:
        geometry_id = _register_tool_shape(plant, model, shape)
        tool_ids.append(geometry_id)
        names[geometry_id] = shape.geometry_name
    if tool_ids:
        # Like the arm's links among themselves (the URDF's filter group): no self-contact.
        scene_graph.collision_filter_manager().Apply(
            CollisionFilterDeclaration().ExcludeBetween(GeometrySet(list(arm_ids)), GeometrySet(tool_ids))
        )
    robot_ids = arm_ids + tuple(tool_ids)
    kinds = {}
    obstacle_ids = []
    for box in obstacles:
        geometry_id = _register_box(plant, box, "obstacle", OBSTACLE_RGBA)
        obstacle_ids.append(geometry_id)
        names[geometry_id], kinds[geometry_id] = box.name, OBSTACLE
    shell_ids = []
    for box in safety_shells:
        geometry_id = _register_box(plant, box, "safety_shell", SAFETY_SHELL_RGBA)
        shell_ids.append(geometry_id)
        names[geometry_id], kinds[geometry_id] = box.name, SAFETY_SHELL
    table_id = None
    if table is not None:
        table_id = _register_box(plant, table, "table", TABLE_RGBA)
        names[table_id] = table.name
    if shell_ids:
        scene_graph.collision_filter_manager().Apply(
            CollisionFilterDeclaration().ExcludeBetween(GeometrySet(list(robot_ids)), GeometrySet(shell_ids))
        )
    return SceneGeometry(
        robot_geometry_ids=robot_ids,
        obstacle_geometry_ids=tuple(obstacle_ids),
        shell_geometry_ids=tuple(shell_ids),
        table_geometry_id=table_id,
        tool_geometry_ids=tuple(tool_ids),
        names=names,
        kinds=kinds,
    )


def min_signed_distances(query_object: QueryObject, robot_geometry_ids, box_geometry_ids) -> np.ndarray:
    """Signed distance of every (robot geometry, box) pair, shape (n_robot, n_boxes), m.

    Filters are ignored, so shells filtered out of contact are measured too.
    """
    distances = np.empty((len(robot_geometry_ids), len(box_geometry_ids)))
    for j, box_id in enumerate(box_geometry_ids):
        for i, robot_id in enumerate(robot_geometry_ids):
            distances[i, j] = query_object.ComputeSignedDistancePairClosestPoints(robot_id, box_id).distance
    return distances


class KinematicScene:
    """The robot, its tool and the scene on a kinematics-only plant: clearances of
    configurations.

    Parameters
    ----------
    workcell : Workcell, optional
        The scene (:meth:`Workcell.of` a task); or give its parts:
    X_WB, X_tool0_E : RigidTransform, optional
    obstacles, safety_shells : iterable of Box
    table : Box, optional
    tool : iterable of ToolShape, optional
        None: the default tool of ``X_tool0_E`` (:func:`drake_lfd.core.tool.default_tool`).

    Attributes
    ----------
    plant, scene_graph, model, diagram, geometry (SceneGeometry), workcell
    """

    def __init__(
        self,
        workcell: Workcell | None = None,
        *,
        X_WB: RigidTransform | None = None,
        X_tool0_E: RigidTransform | None = None,
        obstacles: Iterable[Box] = (),
        safety_shells: Iterable[Box] = (),
        table: Box | None = None,
        tool: Iterable[ToolShape] | None = None,
    ):
        if workcell is None:
            workcell = Workcell.make(X_WB=X_WB, X_tool0_E=X_tool0_E, obstacles=obstacles,
                                     safety_shells=safety_shells, table=table, tool=tool)
        self.workcell = workcell
        builder = DiagramBuilder()
        self.plant, self.scene_graph = AddMultibodyPlantSceneGraph(builder, time_step=0.0)
        self.model = add_ur5e(self.plant, X_WB=workcell.X_WB, X_tool0_E=workcell.X_tool0_E)
        self.geometry = add_scene(
            self.plant,
            self.scene_graph,
            model=self.model,
            obstacles=workcell.obstacles,
            safety_shells=workcell.safety_shells,
            table=workcell.table,
            tool=workcell.tool,
        )
        self.plant.Finalize()
        self.diagram = builder.Build()
        self.context = self.diagram.CreateDefaultContext()
        self.plant_context = self.plant.GetMyMutableContextFromRoot(self.context)
        self._scene_graph_context = self.scene_graph.GetMyContextFromRoot(self.context)
        robot_ids = self.geometry.robot_geometry_ids
        pan_only = set(pan_only_geometry_ids(self.plant, self.model, self.scene_graph.model_inspector(), robot_ids))
        #: Rows of :meth:`signed_distances` whose shapes' place depends on shoulder_pan alone
        #: (:mod:`~drake_lfd.robot.pan_only`), measured at its configuration.
        self.pan_only_rows = np.array([i for i, g in enumerate(robot_ids) if g in pan_only], dtype=int)
        self._other_rows = np.array([i for i, g in enumerate(robot_ids) if g not in pan_only], dtype=int)
        # Their distances by pan (the branches of a pose share two pans; trials revisit them).
        self._at_pan = ExactMemo(maxsize=256)

    def signed_distances(self, q) -> np.ndarray:
        """Signed distances of every robot geometry to every obstacle then shell.

        Parameters
        ----------
        q : array-like, shape (6,)

        Returns
        -------
        array, shape (n_robot_geometries, n_obstacles + n_shells), metres

        The rows of :attr:`pan_only_rows` are measured at
        :func:`~drake_lfd.robot.pan_only.pan_only_configuration` (the same shapes'
        places; Drake's query returns the same number for them then, whatever the
        other joints).
        """
        q = np.asarray(q, dtype=float)
        ids, boxes = self.geometry.robot_geometry_ids, self.geometry.keep_out_geometry_ids
        canonical = pan_only_configuration(q)
        if not len(self.pan_only_rows) or np.array_equal(q, canonical):
            return self._distances_at(q, ids)
        distances = np.empty((len(ids), len(boxes)))
        distances[self._other_rows] = self._distances_at(q, [ids[i] for i in self._other_rows])
        distances[self.pan_only_rows] = self._at_pan.get(exact_key(canonical[:1]), lambda: self._distances_at(
            canonical, [ids[i] for i in self.pan_only_rows]))
        return distances

    def _distances_at(self, q: np.ndarray, robot_ids) -> np.ndarray:
        """:func:`min_signed_distances` of ``robot_ids`` with the arm at ``q``."""
        self.plant.SetPositions(self.plant_context, self.model, q)
        query_object = self.scene_graph.get_query_output_port().Eval(self._scene_graph_context)
        return min_signed_distances(query_object, robot_ids, self.geometry.keep_out_geometry_ids)

    def clearance(self, q) -> tuple[float, str | None, str | None]:
        """Minimum signed distance of configuration ``q`` to any obstacle or shell.

        Returns
        -------
        distance_m : float
            ``inf`` when the scene has no boxes.
        robot_geometry : str or None
            The closest robot geometry.
        box : str or None
            The closest box, described (``safety shell 'shell_1'``).
        """
        boxes = self.geometry.keep_out_geometry_ids
        if not boxes:
            return np.inf, None, None
        distances = self.signed_distances(q)
        i, j = np.unravel_index(np.argmin(distances), distances.shape)
        return (
            float(distances[i, j]),
            self.geometry.names[self.geometry.robot_geometry_ids[i]],
            self.geometry.describe(boxes[j]),
        )
