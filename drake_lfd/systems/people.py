"""The people in the cell as a SceneGraph geometry source: capsules that move with time.

:class:`PeopleGeometry` registers every person's four capsules
(:data:`~drake_lfd.core.people.CAPSULE_NAMES`) with SceneGraph, one frame each, with the
proximity role (so SceneGraph's signed-distance queries see them) and the illustration
role (so Meshcat shows them and records them). Its ``geometry_pose`` output gives the
frames' poses at the Context's time (:meth:`~drake_lfd.core.people.Person.capsules`): a
function of time alone, so the system has no state. Collisions between people and
anything else are filtered out (:meth:`PeopleGeometry.exclude_collisions`): the plant
must not make contact with geometry it does not own, and a person is measured, not
pushed.

Not for: the people's motion (``core/people.py``) or the distances
(``separation.py``).
"""

from __future__ import annotations

import numpy as np
from pydrake.common.value import AbstractValue
from pydrake.math import RigidTransform
from pydrake.systems.framework import LeafSystem
from pydrake.geometry import (
    Capsule, CollisionFilterDeclaration, FramePoseVector, GeometryFrame, GeometryInstance, GeometrySet,
    MakePhongIllustrationProperties, ProximityProperties, Role, SceneGraph,
)

from drake_lfd.core.people import Person

__all__ = ["PeopleGeometry", "PERSON_RGBA"]

#: A person's colour in Meshcat: a high-visibility orange, half opaque so the robot
#: stays visible behind.
PERSON_RGBA = np.array([1.0, 0.45, 0.05, 0.6])


class PeopleGeometry(LeafSystem):
    """Registers ``people`` with ``scene_graph`` and puts out their capsules' poses.

    .. pydrake_system::

        name: PeopleGeometry
        output_ports:
        - geometry_pose

    ``geometry_pose``: the ``FramePoseVector`` of this source (connect it to
    ``scene_graph.get_source_pose_port(source_id)``; :meth:`AddToBuilder` does).

    Parameters
    ----------
    people : sequence of Person
    scene_graph : SceneGraph
        Registered with at construction (before the Diagram is built).
    floor_z : float
        Where the floor is in W (scripted people stand on it).
    face_xy : array (2,)
        The point scripted people face (the robot's base).
    """

    def __init__(self, *, people, scene_graph: SceneGraph, floor_z: float, face_xy):
        super().__init__()
        self.people: tuple[Person, ...] = tuple(people)
        names = [person.name for person in self.people]
        if len(set(names)) != len(names):
            raise ValueError(f"people need distinct names (they name their geometry), got {names}")
        self._floor_z = float(floor_z)
        self._face_xy = np.asarray(face_xy, dtype=float)[:2].copy()
        self.source_id = scene_graph.RegisterSource("people")
        self._frame_ids = []
        #: Per person, its capsules' geometry ids (CAPSULE_NAMES order).
        self.geometry_ids: list[list] = []
        for person in self.people:
            ids = []
            for capsule in person.capsules(0.0, floor_z=self._floor_z, face_xy=self._face_xy):
                frame_id = scene_graph.RegisterFrame(self.source_id, GeometryFrame(f"{person.name}::{capsule.name}"))
                geometry_id = scene_graph.RegisterGeometry(
                    self.source_id, frame_id,
                    GeometryInstance(RigidTransform(), Capsule(capsule.radius, capsule.length),
                                     f"{person.name}::{capsule.name}"))
                scene_graph.AssignRole(self.source_id, geometry_id, ProximityProperties())
                scene_graph.AssignRole(self.source_id, geometry_id, MakePhongIllustrationProperties(PERSON_RGBA))
                self._frame_ids.append(frame_id)
                ids.append(geometry_id)
            self.geometry_ids.append(ids)
        self.geometry_pose_output_port = self.DeclareAbstractOutputPort(
            "geometry_pose", lambda: AbstractValue.Make(FramePoseVector()), self._calc_poses)

    @staticmethod
    def AddToBuilder(*, builder, scene_graph: SceneGraph, people, floor_z: float, face_xy,
                     name: str = "people") -> "PeopleGeometry":
        """Adds the people named ``name``, registered with ``scene_graph`` (in
        ``builder``), its pose port connected, collisions with them filtered out."""
        system = builder.AddNamedSystem(name, PeopleGeometry(people=people, scene_graph=scene_graph,
                                                             floor_z=floor_z, face_xy=face_xy))
        builder.Connect(system.geometry_pose_output_port, scene_graph.get_source_pose_port(system.source_id))
        system.exclude_collisions(scene_graph)
        return system

    def exclude_collisions(self, scene_graph: SceneGraph) -> None:
        """Filters every pair of a person's capsule with any other proximity geometry (and
        with each other) out of SceneGraph's collision queries: the plant must not make
        contact with geometry it does not own. Signed-distance queries of given pairs
        (``ComputeSignedDistancePairClosestPoints``) ignore filters and still see them."""
        inspector = scene_graph.model_inspector()
        people_ids = [g for ids in self.geometry_ids for g in ids]
        people = GeometrySet(people_ids)
        others = GeometrySet([g for g in inspector.GetAllGeometryIds(Role.kProximity) if g not in set(people_ids)])
        declaration = CollisionFilterDeclaration().ExcludeWithin(people).ExcludeBetween(people, others)
        scene_graph.collision_filter_manager().Apply(declaration)

    def capsule_poses(self, t: float) -> list:
        """Every capsule's pose at ``t``, person by person (CAPSULE_NAMES order)."""
        return [capsule.X_WC for person in self.people
                for capsule in person.capsules(t, floor_z=self._floor_z, face_xy=self._face_xy)]

    def _calc_poses(self, context, value):
        poses = value.get_mutable_value()
        poses.clear()
        for frame_id, X_WC in zip(self._frame_ids, self.capsule_poses(context.get_time())):
            poses.set_value(frame_id, X_WC)
