"""The keep-out monitor: how close the robot came to each obstacle and safety shell.

Safety shells are filtered out of contact (``scene.py``), so SceneGraph's all-pairs
queries cannot see them. The monitor asks for each (robot geometry, box) pair with
``QueryObject.ComputeSignedDistancePairClosestPoints(id_A, id_B)``, which ignores
collision filters, at a fixed rate (100 Hz by default: every sample costs a query per
pair, so a 1 kHz monitor would add markedly to a run). Given the arm's joint positions, it
skips the pairs that provably cannot lower any record (see ``ShellMonitor``), so most
samples query two or three of the twenty pairs; the records are the same as querying
every pair, to the bit. Its state keeps, for every box, the
minimum signed distance seen so far, which robot geometry achieved it and when. It
samples the same states as a periodic publisher such as the joint-state logger (see
``ShellMonitor``), so the minimum can be recomputed exactly from a run's log. A
negative distance is a penetration; optionally the monitor then ends the simulation
(``EventStatus.ReachedTermination``: ``Simulator.AdvanceTo`` returns early, cleanly).

Because those are the logger's samples, the pipeline's monitor measures them from the
log (given a kinematic scene of the same work cell: ``clearances_with_log``, called
once when the run is read off its Context: one batch is cheaper than a batch at each
critical configuration), with no event of its own: a Python event every 10 ms and its
pairs loop cost about as much as the plant's step. A batch's joint travel and motion
bounds are computed at once, and the scene's arm is posed only at the samples where some
pair's bound has run out (on the transferring task about two samples in three, 2.5 pairs
each), about half the work of visiting every sample. The records are the same, to the bit (``tests/test_closed_loop_compiled.py``
compares them on the transferring task; 12 pick-and-place tasks, filling and pouring and
assembling agreed too). With ``stop_on_penetration`` the monitor samples itself, to end
the run at the penetration's sample.

Not for: registering the boxes (``scene.py``) or judging a run (``closed_loop.py``).
"""

from __future__ import annotations

import bisect
import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass

import numpy as np
from pydrake.common.value import AbstractValue
from pydrake.geometry import GeometryId, QueryObject
from pydrake.multibody.plant import MultibodyPlant
from pydrake.systems.framework import EventStatus, LeafSystem

from drake_lfd.io.simulation_config import DEFAULT_MONITOR_PERIOD_S
from drake_lfd.robot.motion_bounds import motion_bounds

__all__ = ['DEFAULT_MONITOR_PERIOD_S', 'BoxClearance', 'ShellMonitor']


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
        - robot_positions (optional)
        output_ports:
        - min_distance

    ``query_object``: SceneGraph's query port. ``robot_positions``: the plant's generalized
    positions, optional (the station's ``ur5e.position_measured``: its plant holds only
    the arm). ``min_distance``
    (1,): the minimum over all boxes and all samples so far, m (``inf`` before the first
    sample or with no boxes). Per-box records: :meth:`clearances`.

    Pruning, when ``robot_positions`` is connected: a revolute joint turning by ``dq``
    moves every point at most ``r |dq|`` away, ``r`` bounding the point's distance from
    the joint axis over all configurations (the joint-to-joint distances down the chain
    plus the geometry's bounding radius,
    :func:`drake_lfd.robot.motion_bounds.motion_bounds`), and a signed distance to
    a fixed box changes no more than its points move. The state keeps each joint's
    travel ``T_j`` (the sum of ``|dq_j|`` between samples), so a geometry has moved at
    most ``M = sum_j r_j T_j`` since the start. A pair measured at ``d`` when its
    geometry's bound was ``M0`` is at least ``d - (M - M0)`` away later; while that
    exceeds ``max(record, 0)`` (which only shrinks) the pair can neither lower the box's
    record nor be a penetration, and it is not queried. Geometries without a bounding
    radius here (meshes) are queried at every sample.

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
        scene=None,
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
        m = len(self._robot_ids)
        # Pairs in box-major order: pair k = (robot k % m, box k // m).
        self._num_pairs = num_pairs = n * m
        num_joints = plant.num_positions()
        self._num_joints = num_joints
        # State: [min distance per box (n), index of the closest robot geometry (n), time
        # of the minimum (n), the joint positions at the previous sample (J, nan before
        # the first), the joints' travel so far (J, sum of |dq| over samples), each pair's
        # wake-up travel (P, -inf: query at the next sample), the number of samples
        # measured (1)].
        initial = np.concatenate([np.full(n, np.inf), np.full(n, -1.0), np.full(n, np.nan),
                                  np.full(num_joints, np.nan), np.zeros(num_joints), np.full(num_pairs, -np.inf),
                                  [0.0]])
        self._state_index = self.DeclareDiscreteState(initial)
        self.query_object_input_port = self.DeclareAbstractInputPort(
            "query_object", AbstractValue.Make(QueryObject())
        )
        self.robot_positions_input_port = self.DeclareVectorInputPort("robot_positions", num_joints)
        self.min_distance_output_port = self.DeclareVectorOutputPort("min_distance", 1, self._calc_min_distance)
        # Per robot geometry, the motion bound of each joint (lists, set at the first
        # update), and whether it has one.
        self._radii: list[list[float]] = []
        self._bounded: list[bool] = []
        #: Distance queries made so far (a diagnostic, not part of the Context's state).
        self.num_pair_queries = 0
        self._prepared = False  # names are read from SceneGraph at the first update
        # Batches: given a kinematic scene of the same work cell (and no stop at a
        # penetration, which must end the run at its sample), the monitor has no event:
        # :meth:`clearances_with_log` measures the joint-state log's samples (the same states, see
        # above) on that scene, a batch at a time, and the Python work of an event every
        # period is saved.
        self._scene = scene if (scene is not None and not self._stop_on_penetration) else None
        if self._scene is not None:
            self._scene_plant_context = scene.plant.GetMyMutableContextFromRoot(scene.context)
            self._scene_graph_context = scene.scene_graph.GetMyContextFromRoot(scene.context)
            self._scene_robot_ids = list(scene.geometry.robot_geometry_ids)
            self._scene_box_ids = list(scene.geometry.keep_out_geometry_ids)
            if len(self._scene_robot_ids) != m or len(self._scene_box_ids) != n:
                raise ValueError("the monitor's scene has other geometries than the monitored one")
        elif n and self._robot_ids:
            # An unrestricted update, like the plant's own step: it samples the same state
            # as a periodic publisher (the joint-state logger) at the same instant, so the
            # minimum can be recomputed exactly from the logged joint positions. (A discrete
            # update would run after the plant's step and see the next state.)
            self.DeclarePeriodicUnrestrictedUpdateEvent(self._period, 0.0, self._update)

    @property
    def measures_log(self) -> bool:
        """Whether the monitor measures a joint-state log (:meth:`clearances_with_log`) instead of
        sampling with an event of its own."""
        return self._scene is not None

    @staticmethod
    def AddToBuilder(*, builder, plant: MultibodyPlant, query_object_output_port,
                     robot_geometry_ids: Sequence[GeometryId], shell_geometry_ids: Sequence[GeometryId],
                     robot_positions_output_port=None, name: str = "shell_monitor",
                     **kwargs) -> "ShellMonitor":
        """Adds a monitor named ``name`` fed by SceneGraph's ``query_object_output_port``
        (and the robot's joint positions, for pruning, when given); ``kwargs`` are the
        constructor's (``period``, ``names``, ``kinds``, ...)."""
        monitor = builder.AddNamedSystem(name, ShellMonitor(
            plant=plant, robot_geometry_ids=robot_geometry_ids, shell_geometry_ids=shell_geometry_ids, **kwargs))
        builder.Connect(query_object_output_port, monitor.query_object_input_port)
        if robot_positions_output_port is not None:
            builder.Connect(robot_positions_output_port, monitor.robot_positions_input_port)
        return monitor

    @property
    def period(self) -> float:
        return self._period

    def _update(self, context, new_state):
        """One sample, now (the monitor without a sample buffer)."""
        query_object = self.query_object_input_port.Eval(context)
        if not self._prepared:
            self._prepare(query_object)
        # Plain Python floats: a few dozen numbers, where numpy's per-call overhead would
        # cost more than the arithmetic.
        state = context.get_discrete_state(self._state_index).value().tolist()
        pruning = self.robot_positions_input_port.HasValue(context)
        q = self.robot_positions_input_port.Eval(context).tolist() if pruning else None
        penetration = self._sample(state, q, context.get_time(), query_object.ComputeSignedDistancePairClosestPoints,
                                   self._robot_ids, self._box_ids)
        state[-1] += 1.0
        new_state.get_mutable_discrete_state().get_mutable_vector(self._state_index).SetFromVector(state)
        if self._stop_on_penetration and penetration is not None:
            depth, i, j = penetration
            return EventStatus.ReachedTermination(
                self,
                f"{self._name_of(self._robot_ids[i])} penetrated {self._describe(self._box_ids[j])} "
                f"by {-depth:.4f} m at t = {context.get_time():.3f} s",
            )
        return EventStatus.Succeeded()

    def _sample(self, state: list, q: list | None, time_s: float, signed_distance, robot_ids, box_ids):
        """Updates ``state`` (the discrete state as a list) with the sample of joint
        positions ``q`` (None: no pruning) at ``time_s``, measuring with
        ``signed_distance(robot_id, box_id)``; returns the deepest penetration
        ``(depth, robot index, box index)`` of the sample, or None."""
        n, num_joints = len(self._box_ids), self._num_joints
        m = len(robot_ids)
        records, wake = state[:n], state[3 * n + 2 * num_joints:3 * n + 2 * num_joints + self._num_pairs]
        pruning = q is not None
        if pruning:
            q_previous = state[3 * n:3 * n + num_joints]
            travel = state[3 * n + num_joints:3 * n + 2 * num_joints]
            if q_previous[0] == q_previous[0]:  # not nan: there was a previous sample
                travel = [t + abs(a - b) for t, a, b in zip(travel, q, q_previous)]
            state[3 * n:3 * n + 2 * num_joints] = q + travel
            # How far each robot geometry may have moved since the start, as a bound.
            moved = [_motion_bound(radii, travel) if bounded else math.inf
                     for radii, bounded in zip(self._radii, self._bounded)]
        best = [math.inf] * n  # per box: the smallest distance measured now, and by whom
        best_index = [-1] * n
        measured = []
        for k in range(self._num_pairs):
            j, i = divmod(k, m)
            if pruning and moved[i] < wake[k]:
                continue  # provably farther than the record and than zero: skip
            distance = signed_distance(robot_ids[i], box_ids[j]).distance
            measured.append((k, distance))
            if distance < best[j]:
                best[j], best_index[j] = distance, i
        self.num_pair_queries += len(measured)
        penetration = None
        for j in range(n):
            if best[j] < records[j]:
                records[j] = state[j] = best[j]
                state[n + j], state[2 * n + j] = best_index[j], time_s
            if best[j] < 0.0 and (penetration is None or best[j] < penetration[0]):
                penetration = (best[j], best_index[j], j)
        if pruning:
            # A pair measured at d now stays beyond max(record, 0), which can only
            # shrink, until its geometry has moved d - max(record, 0) further.
            offset = 3 * n + 2 * num_joints
            for k, distance in measured:
                j, i = divmod(k, m)
                state[offset + k] = moved[i] + distance - max(records[j], 0.0)
        return penetration

    # -- batches of logged samples ------------------------------------------------------------
    def clearances_with_log(self, root_context, t: np.ndarray, q: np.ndarray) -> list[BoxClearance]:
        """:meth:`clearances` as they are once the samples of a joint-state log not
        measured yet are measured too; the Context is left as it is.

        ``t`` (m,) and ``q`` (m, J) are the log of the run so far, sampled every monitor
        period from the start (the pipeline's joint-state logger). Only samples before the
        Context's time count: a sample at that very time is the one an event-driven
        monitor would take at the start of the next step. A monitor that samples itself
        returns its records as they are.
        """
        context = self.GetMyContextFromRoot(root_context)
        state = self._state_with_log(context, t, q) if self._scene is not None else None
        return self._records(context.get_discrete_state(self._state_index).value() if state is None else state)

    def _state_with_log(self, context, t: np.ndarray, q: np.ndarray) -> np.ndarray | None:
        """The state once the log's samples not measured yet are (None: none to measure)."""
        if not self._prepared:
            self._prepare(self.query_object_input_port.Eval(context))
        state = context.get_discrete_state(self._state_index).value().copy()
        done = int(state[-1])
        end = int(np.searchsorted(t, context.get_time(), side="left"))
        if end <= done:
            return None
        signed_distance = self._scene.scene_graph.get_query_output_port().Eval(
            self._scene_graph_context).ComputeSignedDistancePairClosestPoints
        self._measure_batch(state, np.asarray(t[done:end], dtype=float), np.asarray(q[done:end], dtype=float),
                            signed_distance)
        state[-1] = float(end)
        return state

    def _measure_batch(self, state: np.ndarray, t: np.ndarray, q: np.ndarray, signed_distance) -> None:
        """Updates ``state`` as :meth:`_sample` would for each of the samples ``q`` (K, J)
        at times ``t`` (K,) in turn, with the same arithmetic in the same order.

        The joints' travel and each geometry's motion bound are computed for the whole
        batch at once (cumulative sums, nondecreasing), so the samples at which every
        pair is pruned are found without visiting them: the scene's arm is posed, and
        pairs queried, only at the samples where some pair's bound has run out.
        """
        n, num_joints, m = len(self._box_ids), self._num_joints, len(self._scene_robot_ids)
        offset = 3 * n + 2 * num_joints
        q_previous = state[3 * n:3 * n + num_joints]
        steps = np.abs(np.diff(q, axis=0, prepend=q_previous[None, :] if q_previous[0] == q_previous[0]
                               else q[:1]))
        # travel_k = travel_(k-1) + |q_k - q_(k-1)|, summed in sample order (add.accumulate).
        travel = np.cumsum(np.vstack([state[3 * n + num_joints:offset], steps]), axis=0)[1:]
        moved = _motion_bounds(self._radii, self._bounded, travel)  # (K, m)
        state[3 * n:offset] = np.concatenate([q[-1], travel[-1]])
        # Plain Python from here (a few numbers per sample, as in :meth:`_sample`). Each
        # geometry's bound is nondecreasing along the batch (rounding is monotone), so the
        # first sample at which a pair is due (not ``moved < wake``) is a binary search.
        moved_by_robot = moved.T.tolist()  # m lists of K
        values = state.tolist()
        records, wake = values[:n], values[offset:offset + self._num_pairs]
        due_at = [bisect.bisect_left(moved_by_robot[pair % m], wake[pair]) for pair in range(self._num_pairs)]
        plant, plant_context = self._scene.plant, self._scene_plant_context
        robot_ids, box_ids = self._scene_robot_ids, self._scene_box_ids
        num_samples = len(t)
        while (k := min(due_at, default=num_samples)) < num_samples:
            plant.SetPositions(plant_context, q[k])
            best = [math.inf] * n
            best_index = [-1] * n
            measured = []
            for pair, due in enumerate(due_at):
                if due != k:
                    continue
                j, i = divmod(pair, m)
                distance = signed_distance(robot_ids[i], box_ids[j]).distance
                measured.append((pair, distance))
                if distance < best[j]:
                    best[j], best_index[j] = distance, i
            self.num_pair_queries += len(measured)
            for j in range(n):
                if best[j] < records[j]:
                    records[j] = values[j] = best[j]
                    values[n + j], values[2 * n + j] = best_index[j], float(t[k])
            for pair, distance in measured:
                j, i = divmod(pair, m)
                bound = moved_by_robot[i]
                wake[pair] = bound[k] + distance - max(records[j], 0.0)
                due_at[pair] = bisect.bisect_left(bound, wake[pair], k + 1)
        state[:3 * n] = values[:3 * n]
        state[offset:offset + self._num_pairs] = wake

    def _prepare(self, query_object):
        """Names read once from SceneGraph (for geometries not named by the caller), and
        each pair's motion bounds."""
        for geometry_id in self._robot_ids + self._box_ids:
            self._name_of(geometry_id, query_object)
        for geometry_id in self._robot_ids:
            bounds = motion_bounds(self._plant, query_object.inspector(), geometry_id)
            self._bounded.append(bool(np.all(np.isfinite(bounds))))
            self._radii.append(np.where(np.isfinite(bounds), bounds, 0.0).tolist())
        self._prepared = True

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
        return self._records(context.get_discrete_state(self._state_index).value())

    def _records(self, state) -> list[BoxClearance]:
        n = len(self._box_ids)
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


def _motion_bound(radii: Sequence[float], travel: Sequence[float]) -> float:
    """``sum_j r_j T_j``, summed in joint order (as :func:`_motion_bounds` does)."""
    moved = 0.0
    for r, t in zip(radii, travel):
        moved += r * t
    return moved


def _motion_bounds(radii: Sequence[Sequence[float]], bounded: Sequence[bool], travel: np.ndarray) -> np.ndarray:
    """:func:`_motion_bound` of every robot geometry (``radii`` (m, J), inf where not
    ``bounded``) at every sample's joint travel ``travel`` (K, J): (K, m), the same
    floating-point operations in the same order."""
    products = travel[:, None, :] * np.asarray(radii, dtype=float).reshape(len(radii), travel.shape[1])  # (K, m, J)
    moved = np.zeros(products.shape[:2])
    for j in range(products.shape[2]):
        moved += products[:, :, j]
    moved[:, ~np.asarray(bounded, dtype=bool)] = np.inf
    return moved
