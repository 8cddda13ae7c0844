"""The task's scene on the plant: obstacles, keep-out safety shells and an optional table.

Every box is registered through the MultibodyPlant on its world body, with a collision
(proximity) and a visual (illustration) geometry: obstacles red, safety shells
translucent purple (as in the paper's Fig. 8), the table grey. Nothing here registers
geometry in SceneGraph directly (the plant throws on first contact with geometry it did
not register itself); SceneGraph is only asked to filter collisions.

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
(``systems/shell_monitor.py``), or the boxes themselves (:class:`~drake_lfd.core.tasks.Box`).
"""

from __future__ import annotations

from collections.abc import Iterable, Mapping
from dataclasses import dataclass, field

import numpy as np
from pydrake.geometry import (
    Box as BoxShape,
    CollisionFilterDeclaration,
    GeometryId,
    GeometrySet,
    QueryObject,
    SceneGraph,
)
from pydrake.math import RigidTransform
from pydrake.multibody.plant import AddMultibodyPlantSceneGraph, CoulombFriction, MultibodyPlant
from pydrake.multibody.tree import ModelInstanceIndex
from pydrake.systems.framework import DiagramBuilder

from drake_lfd.core.tasks import Box
from drake_lfd.robot.kinematics import add_ur5e

__all__ = [
    "OBSTACLE_RGBA",
    "SAFETY_SHELL_RGBA",
    "TABLE_RGBA",
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
# Dry steel-ish friction; only obstacles and the table can touch the robot.
_FRICTION = CoulombFriction(static_friction=0.5, dynamic_friction=0.5)

OBSTACLE = "obstacle"
SAFETY_SHELL = "safety shell"


@dataclass(frozen=True)
class SceneGeometry:
    """Geometry ids of the robot and the scene, and the names to report them by.

    Attributes
    ----------
    robot_geometry_ids : tuple of GeometryId
        Every collision geometry of the robot model.
    obstacle_geometry_ids, shell_geometry_ids : tuple of GeometryId
        One per obstacle / safety shell, in the order given.
    table_geometry_id : GeometryId or None
    names : mapping GeometryId -> str
        Robot geometries as ``<link>/<geometry>`` (``forearm_link/forearm_tube``), boxes
        by their task name (``shell_1``).
    kinds : mapping GeometryId -> str
        ``"obstacle"`` or ``"safety shell"`` for each box.
    """

    robot_geometry_ids: tuple
    obstacle_geometry_ids: tuple = ()
    shell_geometry_ids: tuple = ()
    table_geometry_id: GeometryId | None = None
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


def table_under_robot(X_WB: RigidTransform | None = None, *, size=(1.6, 1.2, 0.04), name="table") -> Box:
    """A table whose top is flush with the base of an upright robot, centred under it.

    Not watched by the shell monitor (the base stands on it); the arm touching it is
    real contact.
    """
    X_WB = RigidTransform() if X_WB is None else X_WB
    size = np.asarray(size, dtype=float)
    centre = X_WB.translation() - np.array([0.0, 0.0, 0.5 * size[2]])
    return Box(name=name, centre=centre, size=size)


def _register_box(plant: MultibodyPlant, box: Box, prefix: str, rgba: np.ndarray) -> GeometryId:
    shape = BoxShape(*np.asarray(box.size, dtype=float))
    X_WG = RigidTransform(np.asarray(box.centre, dtype=float))
    name = f"{prefix}::{box.name}"
    geometry_id = plant.RegisterCollisionGeometry(plant.world_body(), X_WG, shape, name, _FRICTION)
    plant.RegisterVisualGeometry(plant.world_body(), X_WG, shape, name, rgba)
    return geometry_id


def robot_geometry_names(plant: MultibodyPlant, scene_graph: SceneGraph, model: ModelInstanceIndex) -> dict:
    """``{GeometryId: "<link>/<geometry>"}`` for every collision geometry of ``model``."""
    inspector = scene_graph.model_inspector()
    names = {}
    for body_index in plant.GetBodyIndices(model):
        body = plant.get_body(body_index)
        for geometry_id in plant.GetCollisionGeometriesForBody(body):
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
) -> SceneGeometry:
    """Registers the boxes on ``plant``'s world body and keeps shells from pushing ``model``.

    Call after the robot ``model`` has been added (its geometries must exist) and before
    ``plant.Finalize()``. ``plant`` must be registered with ``scene_graph``.

    Parameters
    ----------
    obstacles, safety_shells : iterable of :class:`drake_lfd.core.tasks.Box`
        Axis-aligned boxes in W (``name``, ``centre`` (3,), ``size`` (3,) full edges).
    table : Box, optional
        A grey box the robot can rest on or touch (see :func:`table_under_robot`).

    Returns
    -------
    SceneGeometry
    """
    obstacles, safety_shells = tuple(obstacles), tuple(safety_shells)
    names = robot_geometry_names(plant, scene_graph, model)
    robot_ids = tuple(names)
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
    """The robot and the scene on a kinematics-only plant: clearances of configurations.

    Parameters
    ----------
    X_WB, X_tool0_E : RigidTransform, optional
    obstacles, safety_shells : iterable of Box
    table : Box, optional

    Attributes
    ----------
    plant, scene_graph, model, diagram, geometry (SceneGeometry)
    """

    def __init__(
        self,
        *,
        X_WB: RigidTransform | None = None,
        X_tool0_E: RigidTransform | None = None,
        obstacles: Iterable[Box] = (),
        safety_shells: Iterable[Box] = (),
        table: Box | None = None,
    ):
        builder = DiagramBuilder()
        self.plant, self.scene_graph = AddMultibodyPlantSceneGraph(builder, time_step=0.0)
        self.model = add_ur5e(self.plant, X_WB=X_WB, X_tool0_E=X_tool0_E)
        self.geometry = add_scene(
            self.plant,
            self.scene_graph,
            model=self.model,
            obstacles=obstacles,
            safety_shells=safety_shells,
            table=table,
        )
        self.plant.Finalize()
        self.diagram = builder.Build()
        self.context = self.diagram.CreateDefaultContext()
        self.plant_context = self.plant.GetMyMutableContextFromRoot(self.context)
        self._scene_graph_context = self.scene_graph.GetMyContextFromRoot(self.context)

    def signed_distances(self, q) -> np.ndarray:
        """Signed distances of every robot geometry to every obstacle then shell.

        Parameters
        ----------
        q : array-like, shape (6,)

        Returns
        -------
        array, shape (n_robot_geometries, n_obstacles + n_shells), metres
        """
        self.plant.SetPositions(self.plant_context, self.model, np.asarray(q, dtype=float))
        query_object = self.scene_graph.get_query_output_port().Eval(self._scene_graph_context)
        return min_signed_distances(
            query_object, self.geometry.robot_geometry_ids, self.geometry.keep_out_geometry_ids
        )

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
