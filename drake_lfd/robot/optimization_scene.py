"""The work cell as the trajectory program's clearance constraint sees it (``OptimizationScene``).

A plant with the UR5e, its tool and the work cell's boxes whose collision filters leave
exactly the pairs to keep clear: robot and tool against obstacles, shells and (but for
the base and shoulder links, which stand on it) the table. The scene also gives E's pose
and translational Jacobian at a configuration, and remembers the programs solved on it
(``solutions``, :mod:`~drake_lfd.core.exact_memo`).

Not for: the joint-path check's scene (``scene.py``) or the program itself
(``trajectory_optimization.py``).
"""

from __future__ import annotations

import dataclasses

import numpy as np
from pydrake.geometry import CollisionFilterDeclaration, GeometrySet
from pydrake.math import RigidTransform
from pydrake.multibody.plant import AddMultibodyPlantSceneGraph
from pydrake.multibody.tree import JacobianWrtVariable
from pydrake.systems.framework import DiagramBuilder

from drake_lfd.core.exact_memo import ExactMemo
from drake_lfd.robot.kinematics import END_EFFECTOR_FRAME_NAME, add_ur5e
from drake_lfd.robot.scene import ON_TABLE_LINKS, add_scene
from drake_lfd.robot.workcell import Workcell

__all__ = ["OptimizationScene"]



class OptimizationScene:
    """The work cell on a plant whose collision filters leave exactly the pairs to keep
    clear: robot and tool against obstacles, shells and (but for the links standing on
    it) the table; robot geometries among themselves are not checked.

    Attributes
    ----------
    plant, scene_graph, model, diagram, context, plant_context, frame_E
    solutions : ExactMemo
        The last solutions of programs on this scene, by their exact inputs (module
        docstring); ``solutions.clear()`` forgets them.
    """

    #: Programs remembered per scene (a refinement solves at most 14, two rounds of the plain
    #: program and three starts, each repaired once).
    REMEMBERED_SOLUTIONS = 16

    def __init__(self, workcell: Workcell):
        builder = DiagramBuilder()
        self.plant, self.scene_graph = AddMultibodyPlantSceneGraph(builder, time_step=0.0)
        self.model = add_ur5e(self.plant, X_WB=workcell.X_WB, X_tool0_E=workcell.X_tool0_E)
        # Shells join the obstacles here: in the station they are filtered out of contact,
        # which would hide them from the distance constraint.
        shells = tuple(dataclasses.replace(box, name=f"shell_{i}_{box.name}")
                       for i, box in enumerate(workcell.safety_shells))
        geometry = add_scene(self.plant, self.scene_graph, model=self.model,
                             obstacles=tuple(workcell.obstacles) + shells, table=workcell.table,
                             tool=workcell.tool)
        manager = self.scene_graph.collision_filter_manager()
        robot = GeometrySet(list(geometry.robot_geometry_ids))
        manager.Apply(CollisionFilterDeclaration().ExcludeWithin(robot))
        if geometry.table_geometry_id is not None:
            on_table = [g for g in geometry.robot_geometry_ids
                        if geometry.names.get(g, "").split("/")[0] in ON_TABLE_LINKS]
            if on_table:
                manager.Apply(CollisionFilterDeclaration().ExcludeBetween(
                    GeometrySet(on_table), GeometrySet([geometry.table_geometry_id])))
        self.has_boxes = bool(geometry.keep_out_geometry_ids) or geometry.table_geometry_id is not None
        self.plant.Finalize()
        self.diagram = builder.Build()
        self.context = self.diagram.CreateDefaultContext()
        self.plant_context = self.plant.GetMyMutableContextFromRoot(self.context)
        self.frame_E = self.plant.GetFrameByName(END_EFFECTOR_FRAME_NAME)
        self.solutions = ExactMemo(maxsize=self.REMEMBERED_SOLUTIONS)

    def translational_jacobian(self, q: np.ndarray) -> np.ndarray:
        """d p_WE / d v at configuration ``q`` (6,): (3, 6)."""
        self.plant.SetPositions(self.plant_context, self.model, np.asarray(q, dtype=float))
        return self.plant.CalcJacobianTranslationalVelocity(
            self.plant_context, JacobianWrtVariable.kV, self.frame_E, np.zeros(3), self.plant.world_frame(),
            self.plant.world_frame())

    def X_WE(self, q: np.ndarray) -> RigidTransform:
        """E's pose at configuration ``q`` (6,)."""
        self.plant.SetPositions(self.plant_context, self.model, np.asarray(q, dtype=float))
        return self.plant.CalcRelativeTransform(self.plant_context, self.plant.world_frame(), self.frame_E)
