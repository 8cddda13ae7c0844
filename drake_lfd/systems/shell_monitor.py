"""The keep-out monitor: how close the robot came to each obstacle and safety shell.

Safety shells are filtered out of contact (``scene.py``), so SceneGraph's all-pairs
queries cannot see them. The monitor asks for each (robot geometry, box) pair with
``QueryObject.ComputeSignedDistancePairClosestPoints(id_A, id_B)``, which ignores
collision filters, at a fixed rate (100 Hz by default: about 7 us per pair, so a 1 kHz
monitor would add ~40 % to a run, as measured). Its state keeps, for every box, the
minimum signed distance seen so far, which robot geometry achieved it and when. It
samples the same states as a periodic publisher such as the joint-state logger (see
``ShellMonitor``), so the minimum can be recomputed exactly from a run's log. A
negative distance is a penetration; optionally the monitor then ends the simulation
(``EventStatus.ReachedTermination``: ``Simulator.AdvanceTo`` returns early, cleanly).

Not for: registering the boxes (``scene.py``) or judging a run (``closed_loop.py``).
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass

import numpy as np
from pydrake.common.value import AbstractValue
from pydrake.geometry import GeometryId, QueryObject
from pydrake.multibody.plant import MultibodyPlant
from pydrake.systems.framework import EventStatus, LeafSystem

__all__ = ['DEFAULT_MONITOR_PERIOD_S', 'BoxClearance', 'ShellMonitor']

DEFAULT_MONITOR_PERIOD_S = 0.01


@dataclass(frozen=True)
class BoxClearance:
    """The closest approach of the robot to one box during a run.

    Attributes
    ----------
    box : str
        The box's name.
    distance_m : float
        Minimum signed distance (negative: penetration depth); ``inf`` before the first
        sample.
    robot_geometry : str or None
        The robot geometry that came closest (``<link>/<geometry>``).
    time_s : float
        When (nan before the first sample).
    kind : str
        ``"safety shell"``, ``"obstacle"`` or empty when unknown to the monitor.
    """

    box: str
    distance_m: float
    robot_geometry: str | None
    time_s: float
    kind: str = ""

    def describe(self) -> str:
        """``safety shell 'shell_1'`` (or just the name when the kind is unknown)."""
        return f"{self.kind} '{self.box}'" if self.kind else f"'{self.box}'"


class ShellMonitor(LeafSystem):
    """Minimum signed distance between the robot and every obstacle / safety shell.

    .. pydrake_system::

        name: ShellMonitor
        input_ports:
        - query_object
        output_ports:
        - min_distance

    ``query_object``: SceneGraph's query port. ``min_distance`` (1,): the minimum over all
    boxes and all samples so far, m (``inf`` before the first sample or with no boxes).
    Per-box records: :meth:`clearances`.

    Parameters
    ----------
    plant : MultibodyPlant
        The plant that registered the geometries (names robot geometries by link).
    robot_geometry_ids : sequence of GeometryId
    shell_geometry_ids : sequence of GeometryId
        The boxes to watch: safety shells and obstacles.
    period : float
        Sampling period, s.
    stop_on_penetration : bool
        End the simulation at the first sample with a negative distance.
    names : mapping GeometryId -> str, optional
        Names to report (for example ``SceneGeometry.names``); SceneGraph's names
        otherwise.
    kinds : mapping GeometryId -> str, optional
        ``"safety shell"`` / ``"obstacle"`` of each box (``SceneGeometry.kinds``).
    """

    def __init__(
        self,
        *,
        plant: MultibodyPlant,
        robot_geometry_ids: Sequence[GeometryId],
        shell_geometry_ids: Sequence[GeometryId],
        period: float = DEFAULT_MONITOR_PERIOD_S,
        stop_on_penetration: bool = False,
        names: Mapping | None = None,
        kinds: Mapping | None = None,
    ):
        super().__init__()
        self._plant = plant
        self._robot_ids = list(robot_geometry_ids)
        self._box_ids = list(shell_geometry_ids)
        self._stop_on_penetration = bool(stop_on_penetration)
        self._names = dict(names or {})
        self._kinds = dict(kinds or {})
        self._period = float(period)
        n = len(self._box_ids)
        # State: [min distance per box (n), index of the closest robot geometry (n),
        # time of the minimum (n)].
        initial = np.concatenate([np.full(n, np.inf), np.full(n, -1.0), np.full(n, np.nan)])
        self._state_index = self.DeclareDiscreteState(initial)
        self.query_object_input_port = self.DeclareAbstractInputPort(
            "query_object", AbstractValue.Make(QueryObject())
        )
        self.min_distance_output_port = self.DeclareVectorOutputPort("min_distance", 1, self._calc_min_distance)
        self._prepared = False  # names are read from SceneGraph at the first update
        if n and self._robot_ids:
            # An unrestricted update, like the plant's own step: it samples the same state
            # as a periodic publisher (the joint-state logger) at the same instant, so the
            # minimum can be recomputed exactly from the logged joint positions. (A discrete
            # update would run after the plant's step and see the next state.)
            self.DeclarePeriodicUnrestrictedUpdateEvent(self._period, 0.0, self._update)

    @staticmethod
    def AddToBuilder(*, builder, plant: MultibodyPlant, query_object_output_port,
                     robot_geometry_ids: Sequence[GeometryId], shell_geometry_ids: Sequence[GeometryId],
                     name: str = "shell_monitor", **kwargs) -> "ShellMonitor":
        """Adds a monitor named ``name`` fed by SceneGraph's ``query_object_output_port``;
        ``kwargs`` are the constructor's (``period``, ``names``, ``kinds``, ...)."""
        monitor = builder.AddNamedSystem(name, ShellMonitor(
            plant=plant, robot_geometry_ids=robot_geometry_ids, shell_geometry_ids=shell_geometry_ids, **kwargs))
        builder.Connect(query_object_output_port, monitor.query_object_input_port)
        return monitor

    @property
    def period(self) -> float:
        return self._period

    def _update(self, context, new_state):
        query_object = self.query_object_input_port.Eval(context)
        if not self._prepared:
            self._prepare(query_object)
        n = len(self._box_ids)
        state = new_state.get_mutable_discrete_state().get_mutable_vector(self._state_index)
        penetration = None
        for j, box_id in enumerate(self._box_ids):
            best, best_index = self._closest_robot_geometry(query_object, box_id)
            if best < state.GetAtIndex(j):
                state.SetAtIndex(j, best)
                state.SetAtIndex(n + j, best_index)
                state.SetAtIndex(2 * n + j, context.get_time())
            if best < 0.0 and (penetration is None or best < penetration[0]):
                penetration = (best, best_index, j)
        if self._stop_on_penetration and penetration is not None:
            depth, i, j = penetration
            return EventStatus.ReachedTermination(
                self,
                f"{self._name_of(self._robot_ids[i])} penetrated {self._describe(self._box_ids[j])} "
                f"by {-depth:.4f} m at t = {context.get_time():.3f} s",
            )
        return EventStatus.Succeeded()

    def _prepare(self, query_object):
        """Names read once from SceneGraph (for geometries not named by the caller)."""
        for geometry_id in self._robot_ids + self._box_ids:
            self._name_of(geometry_id, query_object)
        self._prepared = True

    def _closest_robot_geometry(self, query_object, box_id):
        """Minimum signed distance to ``box_id`` over robot geometries, and which one.

        Every pair is queried: plain Python over a handful of pairs, since numpy's
        per-call overhead, or pruning by bounding spheres (``GetPoseInWorld`` costs about
        as much as a distance query), would cost more than it saves.
        """
        signed_distance = query_object.ComputeSignedDistancePairClosestPoints
        best, best_index = math.inf, -1
        for i, robot_id in enumerate(self._robot_ids):
            distance = signed_distance(robot_id, box_id).distance
            if distance < best:
                best, best_index = distance, i
        return best, best_index

    def _describe(self, box_id) -> str:
        kind = self._kinds.get(box_id)
        return f"{kind} '{self._name_of(box_id)}'" if kind else f"'{self._name_of(box_id)}'"

    def _calc_min_distance(self, context, output):
        n = len(self._box_ids)
        values = context.get_discrete_state(self._state_index).value()[:n]
        output.SetAtIndex(0, float(np.min(values)) if n else np.inf)

    def _name_of(self, geometry_id, query_object=None) -> str:
        if geometry_id not in self._names and query_object is not None:
            # Not given a name: remember SceneGraph's, robot geometries by their link.
            inspector = query_object.inspector()
            name = inspector.GetName(geometry_id).split("::")[-1]
            body = self._plant.GetBodyFromFrameId(inspector.GetFrameId(geometry_id))
            if body is not None and body.index() != self._plant.world_body().index():
                name = f"{body.name()}/{name}"
            self._names[geometry_id] = name
        return self._names.get(geometry_id, str(geometry_id))

    def clearances(self, context) -> list[BoxClearance]:
        """The record of each box, in the order of ``shell_geometry_ids``."""
        n = len(self._box_ids)
        state = context.get_discrete_state(self._state_index).value()
        records = []
        for j, box_id in enumerate(self._box_ids):
            index = int(state[n + j])
            records.append(
                BoxClearance(
                    box=self._name_of(box_id),
                    distance_m=float(state[j]),
                    robot_geometry=None if index < 0 else self._name_of(self._robot_ids[index]),
                    time_s=float(state[2 * n + j]),
                    kind=self._kinds.get(box_id, ""),
                )
            )
        return records
