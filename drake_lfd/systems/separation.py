"""How close each person is to the robot, how fast the robot approaches, and ISO/TS 15066's
protective separation distance.

:class:`SeparationMonitor` reads SceneGraph's query object, the arm's state and the
path's joint rate (``dq/ds``, the joint velocity at a speed override of 1, from the
time-scaled source) and puts out, per person, five numbers:

- ``d``: the least signed distance between the person's capsules and any robot or tool
  geometry (``ComputeSignedDistancePairClosestPoints`` over every robot x person pair;
  it ignores collision filters, so the people, filtered out of contact, are measured);
- ``v_r``: the robot's speed toward the person, the velocity of the robot's closest
  point (``J(q) v``, the point fixed on its link) along the direction from it to the
  person's closest point (negative when moving away);
- ``S_p``: ISO/TS 15066's protective separation distance at that ``v_r``
  (:func:`~drake_lfd.core.people.protective_separation_distance`);
- ``d - S_p``: the margin;
- ``u``: how fast the closest point would move at a speed override of 1 (``|J(q) dq/ds|``),
  what the speed override needs.

The output is computed when evaluated: the time-scaled source evaluates it once every
controller period (its update), which is the monitor's rate. The Jacobian is taken on a
kinematics Context of the station's plant kept as a cache entry of the monitor's own
Context (scratch space set from the inputs at every evaluation, so it carries nothing
from one evaluation to the next and each Context has its own).

Not for: the people's geometry (``people.py``) or choosing the override
(``speed_override.py``).
"""

from __future__ import annotations

import numpy as np
from pydrake.common.value import AbstractValue
from pydrake.geometry import QueryObject
from pydrake.multibody.tree import JacobianWrtVariable
from pydrake.systems.framework import LeafSystem, ValueProducer

from drake_lfd.core.people import CollaborationParameters, protective_separation_distance

__all__ = ["SeparationMonitor", "SEPARATION_FIELDS"]

#: The numbers put out per person, in this order.
SEPARATION_FIELDS = ("distance_m", "speed_toward_m_s", "protective_distance_m", "margin_m", "full_speed_m_s")


class SeparationMonitor(LeafSystem):
    """Per person: distance to the robot, approach speed, ``S_p``, margin, full-speed
    point speed.

    .. pydrake_system::

        name: SeparationMonitor
        input_ports:
        - query_object
        - state
        - path_rate
        output_ports:
        - separation

    ``query_object``: SceneGraph's; ``state``: the arm's (12,) positions and
    velocities; ``path_rate``: (6,) ``dq/ds`` of the followed path; ``separation``:
    ``5 P`` numbers, :data:`SEPARATION_FIELDS` for each of the P people in turn.

    Parameters
    ----------
    plant : MultibodyPlant
        The station's plant (its geometries are the robot's; it holds only the arm, so
        its velocities are the arm's).
    model : ModelInstanceIndex
        The arm.
    scene_graph : SceneGraph
        The plant's (to find each robot geometry's body).
    robot_geometry_ids : sequence of GeometryId
        Every robot and tool geometry.
    people_geometry_ids : sequence of sequences of GeometryId
        Each person's capsules.
    parameters : CollaborationParameters
    stopping_time_s : float
        T_s.
    """

    def __init__(self, *, plant, model, scene_graph, robot_geometry_ids, people_geometry_ids,
                 parameters: CollaborationParameters, stopping_time_s: float):
        super().__init__()
        self._plant, self._model = plant, model
        self._parameters = parameters
        self._stopping_time_s = float(stopping_time_s)
        self._people_ids = [tuple(ids) for ids in people_geometry_ids]
        inspector = scene_graph.model_inspector()
        # Each robot geometry's link frame and its pose there (the closest point is
        # fixed on the link while the Jacobian is taken).
        self._robot = []
        for geometry_id in robot_geometry_ids:
            body = plant.GetBodyFromFrameId(inspector.GetFrameId(geometry_id))
            self._robot.append((geometry_id, body.body_frame(), inspector.GetPoseInFrame(geometry_id)))
        self.num_people = len(self._people_ids)
        self.query_object_input_port = self.DeclareAbstractInputPort("query_object", AbstractValue.Make(QueryObject()))
        self.state_input_port = self.DeclareVectorInputPort("state", 2 * plant.num_positions(model))
        self.path_rate_input_port = self.DeclareVectorInputPort("path_rate", plant.num_velocities(model))
        self._kinematics = self.DeclareCacheEntry(
            "kinematics_scratch",
            ValueProducer(allocate=lambda: AbstractValue.Make(plant.CreateDefaultContext()),
                          calc=lambda context, value: None),
            prerequisites_of_calc={self.nothing_ticket()})
        self.separation_output_port = self.DeclareVectorOutputPort(
            "separation", len(SEPARATION_FIELDS) * self.num_people, self._calc_separation)

    @staticmethod
    def AddToBuilder(*, builder, query_object_output_port, state_output_port, path_rate_output_port,
                     name: str = "separation_monitor", **kwargs) -> "SeparationMonitor":
        """Adds a monitor named ``name`` fed by the three ports (``kwargs``: the
        constructor's)."""
        monitor = builder.AddNamedSystem(name, SeparationMonitor(**kwargs))
        builder.Connect(query_object_output_port, monitor.query_object_input_port)
        builder.Connect(state_output_port, monitor.state_input_port)
        builder.Connect(path_rate_output_port, monitor.path_rate_input_port)
        return monitor

    def _calc_separation(self, context, output):
        query = self.query_object_input_port.Eval(context)
        state = self.state_input_port.Eval(context)
        path_rate = np.asarray(self.path_rate_input_port.Eval(context))
        plant, model = self._plant, self._model
        n = plant.num_positions(model)
        kinematics = self._kinematics.Eval(context)
        plant.SetPositions(kinematics, model, state[:n])
        values = []
        for person_ids in self._people_ids:
            best = None
            for geometry_id, frame, X_FG in self._robot:
                for person_id in person_ids:
                    pair = query.ComputeSignedDistancePairClosestPoints(geometry_id, person_id)
                    if best is None or pair.distance < best[0].distance:
                        best = (pair, frame, X_FG)
            pair, frame, X_FG = best
            values.extend(self._measure(query, kinematics, pair, frame, X_FG, state[n:], path_rate))
        output.SetFromVector(np.array(values))

    def _measure(self, query, kinematics, pair, frame, X_FG, v, path_rate) -> list[float]:
        """The five numbers of one person from its closest pair (robot geometry A)."""
        plant = self._plant
        X_WA = query.GetPoseInWorld(pair.id_A)
        X_WB = query.GetPoseInWorld(pair.id_B)
        p_WCa = X_WA.multiply(pair.p_ACa)
        p_WCb = X_WB.multiply(pair.p_BCb)
        toward = p_WCb - p_WCa
        norm = np.linalg.norm(toward)
        if norm > 1e-9:
            toward = toward / norm * (1.0 if pair.distance >= 0.0 else -1.0)
        else:
            toward = -np.asarray(pair.nhat_BA_W)
            if not np.all(np.isfinite(toward)):
                toward = np.zeros(3)
        J = plant.CalcJacobianTranslationalVelocity(kinematics, JacobianWrtVariable.kV, frame,
                                                    X_FG.multiply(pair.p_ACa), plant.world_frame(),
                                                    plant.world_frame())
        v_r = float(toward @ (J @ v))
        full_speed = float(np.linalg.norm(J @ path_rate))
        distance = float(pair.distance)
        s_p = protective_separation_distance(v_r, self._parameters, self._stopping_time_s)
        return [distance, v_r, s_p, distance - s_p, full_speed]
