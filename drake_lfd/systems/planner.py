"""The planner as a Drake system: task and library in, a scheduled plan out.

:class:`PlannerSystem` runs :func:`drake_lfd.planning.planner.plan_composition` (the
exact shortest-path planner or the Q-policy's greedy walk, as its
:class:`~drake_lfd.planning.options.PlanningOptions` say) inside a Diagram. It plans at
initialization, and every ``check_period`` s it compares its inputs with what its plan
was made for: when the task (or the library) has changed, it plans again from where the
robot is on the current plan, following the paper's MDP (the state is the current
configuration and the critical configurations still ahead; see
:mod:`drake_lfd.planning.replanning` for where the new motion joins the old one). The
plan lives in the system's abstract state, so it is part of the Context: one Diagram
runs many trials by changing the task input.

Not for: the planning itself (``planning/``) or following the plan
(``plan_trajectory_source.py``).
"""

from __future__ import annotations

import dataclasses
import types

import numpy as np
from pydrake.common.value import AbstractValue
from pydrake.systems.framework import Context, DiagramBuilder, EventStatus, LeafSystem, OutputPort

from drake_lfd.core.tasks import ConcreteTask
from drake_lfd.io.simulation_config import DEFAULT_CHECK_PERIOD_S
from drake_lfd.robot.joint_path import JointPathChecker
from drake_lfd.planning.options import PlanningOptions
from drake_lfd.planning.planner import PlanResult, plan_composition
from drake_lfd.planning.q_learning import QPolicy
from drake_lfd.planning.replanning import ScheduledPlan, replan, task_fingerprint
from drake_lfd.systems.feature_library import LibraryFeatures

__all__ = ["GivenPlan", "NO_PLAN", "PlannerSystem"]

#: The ``plan`` a :class:`PlannerSystem` puts out before its first plan (a Context not
#: initialized yet): a :class:`~drake_lfd.planning.replanning.ScheduledPlan`, so the
#: port is typed ``ScheduledPlan`` throughout, whose result (status ``"no_plan"``, for
#: an empty task) has no motion. :meth:`PlannerSystem.scheduled_plan` reads it as None.
NO_PLAN = ScheduledPlan(PlanResult(status="no_plan", planner="none", task=ConcreteTask("", ()),
                                   euler_zyx=np.zeros((0, 3))))
# The model values of the typed input ports (never put out).
_TASK_MODEL = ConcreteTask("", ())
_LIBRARY_MODEL = LibraryFeatures(types.MappingProxyType({}))


class PlannerSystem(LeafSystem):
    """Plans the task on its input with the library on its input.

    .. pydrake_system::

        name: PlannerSystem
        input_ports:
        - task
        - library
        output_ports:
        - plan

    ``task`` is an abstract :class:`~drake_lfd.core.tasks.ConcreteTask`; ``library`` an
    abstract :class:`~drake_lfd.systems.feature_library.LibraryFeatures`; ``plan`` an
    abstract :class:`~drake_lfd.planning.replanning.ScheduledPlan` (:data:`NO_PLAN`
    before the first plan). A task's ``seed`` (when set) seeds the Q-planner's refinement.

    With ``options.refine`` each executable plan is refined by demonstration-guided
    trajectory optimization (:func:`drake_lfd.planning.refinement.refine_plan`); a plan
    the refinement cannot improve stands, with the reason in its ``refinement``.

    Parameters
    ----------
    options : PlanningOptions
        How to plan: planner, cost, refinement, tolerances, ... (default: those of
        ``drake-lfd plan``). ``options.refine`` needs ``checker``; ``options.joint_check``
        is the builder's to honour (it decides whether to give a ``checker``).
    policy : QPolicy, optional
        Needed by the ``q`` planner.
    start_time_s : float
        Simulation time at which the first plan's motion starts (the settling time).
    floor_z : float, optional
        Height of the table top the tool path must stay above.
    checker : JointPathChecker, optional
        The plan-time joint-space check of the scene (:mod:`drake_lfd.robot.joint_path`):
        with it, only executable compositions are planned.
    check_period : float or None
        How often the inputs are compared with the plan's, s; None: only at
        initialization (a Diagram whose plan cannot change during a run, such as the
        compiled closed loop's, then pays no periodic Python event).
    """

    def __init__(
        self,
        *,
        options: PlanningOptions = PlanningOptions(),
        policy: QPolicy | None = None,
        start_time_s: float = 0.0,
        floor_z: float | None = None,
        checker: JointPathChecker | None = None,
        check_period: float | None = DEFAULT_CHECK_PERIOD_S,
    ):
        super().__init__()
        if not isinstance(options, PlanningOptions):
            raise TypeError(f"options must be PlanningOptions, got {type(options).__name__}")
        if options.refine and checker is None:
            raise ValueError("refine needs a checker (the plan-time joint-space check)")
        if options.planner == "q" and policy is None:
            raise ValueError("the q planner needs a policy")
        self._options = options
        self._refinement_scene = None  # built on the first refinement, kept for the work cell
        self._policy = policy
        self._start_time_s = float(start_time_s)
        self._floor_z = floor_z
        self._checker = checker
        self._last_plan: tuple | None = None  # (inputs' key, PlanResult) of the last first plan
        self.task_input_port = self.DeclareAbstractInputPort("task", AbstractValue.Make(_TASK_MODEL))
        self.library_input_port = self.DeclareAbstractInputPort("library", AbstractValue.Make(_LIBRARY_MODEL))
        self._state_index = self.DeclareAbstractState(AbstractValue.Make(NO_PLAN))
        self.plan_output_port = self.DeclareStateOutputPort("plan", self._state_index)
        self.DeclareInitializationUnrestrictedUpdateEvent(self._update)
        if check_period is not None:
            self.DeclarePeriodicUnrestrictedUpdateEvent(check_period, 0.0, self._update)

    @staticmethod
    def AddToBuilder(*, builder: DiagramBuilder, library_output_port: OutputPort,
                     task_output_port: OutputPort | None = None, name: str = "planner",
                     **kwargs) -> "PlannerSystem":
        """Adds a planner named ``name`` fed by the library (and the task, when given;
        otherwise export or fix its ``task`` input)."""
        planner = builder.AddNamedSystem(name, PlannerSystem(**kwargs))
        builder.Connect(library_output_port, planner.library_input_port)
        if task_output_port is not None:
            builder.Connect(task_output_port, planner.task_input_port)
        return planner

    @property
    def options(self) -> PlanningOptions:
        """How this system plans."""
        return self._options

    @property
    def planner(self) -> str:
        return self._options.planner

    @property
    def cost(self) -> str:
        return self._options.cost

    def plan(self, task: ConcreteTask, library: LibraryFeatures) -> PlanResult:
        """One plan of ``task`` with this system's settings (no state involved)."""
        result = plan_composition(task, library.features, self._options, policy=self._policy,
                                  seed=0 if task.seed is None else int(task.seed), floor_z=self._floor_z,
                                  checker=self._checker)
        if not (self._options.refine and result.planned):
            return result
        from drake_lfd.planning.refinement import refine_plan
        from drake_lfd.robot.optimization_scene import OptimizationScene

        if self._refinement_scene is None:
            self._refinement_scene = OptimizationScene(self._checker.scene.workcell)
        return refine_plan(result, self._checker, scene=self._refinement_scene)

    def scheduled_plan(self, context: Context) -> ScheduledPlan | None:
        """The plan in ``context`` (this system's), or None before the first."""
        value = context.get_abstract_state(self._state_index).get_value()
        return None if value is NO_PLAN else value

    def next_plan(self, context: Context) -> ScheduledPlan | None:
        """The plan for the inputs in ``context``: the current one when nothing changed,
        a first plan, or a replan from the current configuration."""
        task = self.task_input_port.Eval(context)
        library = self.library_input_port.Eval(context)
        if not isinstance(task, ConcreteTask) or not isinstance(library, LibraryFeatures):
            return self.scheduled_plan(context)
        current = self.scheduled_plan(context)
        if current is not None and len(current.inputs) == 2 and current.inputs[0] is task \
                and current.inputs[1] is library:
            return current  # the very objects it was planned for: nothing to compare
        digest = task_fingerprint(task)
        inputs = (task, library)
        if current is None:
            return ScheduledPlan(self._first_plan(task, library, digest), self._start_time_s, digest,
                                 library.revision, inputs=inputs)
        if current.task_fingerprint == digest and _library_digest(current) == library.digest:
            return dataclasses.replace(current, inputs=inputs)
        scheduled = replan(current, task, library.features, context.get_time(),
                           lambda sub_task: self.plan(sub_task, library),
                           task_digest=digest, library_revision=library.revision)
        return dataclasses.replace(scheduled, inputs=inputs)

    def _first_plan(self, task: ConcreteTask, library: LibraryFeatures, digest: bytes) -> PlanResult:
        """:meth:`plan`, remembering the last result: planning is deterministic, so a
        Context reset to its defaults after a plan (``SetRandomContext`` in Drake's
        ``RandomSimulation``) plans the same task again at initialization for free."""
        key = (digest, task.seed, repr(task.timing), repr(task.path_constraints), library.digest)
        if self._last_plan is None or self._last_plan[0] != key:
            self._last_plan = (key, self.plan(task, library))
        return self._last_plan[1]

    def plan_now(self, root_context: Context) -> ScheduledPlan | None:
        """Plans into the state right away (before a Simulator initializes, for example
        to place the robot at the plan's start); initialization then keeps it."""
        context = self.GetMyMutableContextFromRoot(root_context)
        plan = self.next_plan(context)
        context.get_mutable_abstract_state(self._state_index).set_value(NO_PLAN if plan is None else plan)
        return plan

    def _update(self, context, state):
        plan = self.next_plan(context)
        if plan is self.scheduled_plan(context):
            return EventStatus.DidNothing()  # the Simulator then leaves the state alone
        state.get_mutable_abstract_state(self._state_index).set_value(plan)
        return EventStatus.Succeeded()


def _library_digest(plan: ScheduledPlan) -> bytes:
    """The digest of the library ``plan`` was made with (empty when unknown)."""
    return plan.inputs[1].digest if len(plan.inputs) == 2 else b""


class GivenPlan(LeafSystem):
    """A fixed plan, put out as the planner system puts out its own: for trying the
    closed loop on a given motion without a library or a planner.

    .. pydrake_system::

        name: GivenPlan
        output_ports:
        - plan

    The plan lives in the system's abstract state (default: ``plan``), so its output
    changes only when a Context's state is set, and the joint-path source's cache of the
    run's path stays valid for the whole run.
    """

    def __init__(self, plan: ScheduledPlan):
        super().__init__()
        self._state_index = self.DeclareAbstractState(AbstractValue.Make(plan))
        self.plan_output_port = self.DeclareStateOutputPort("plan", self._state_index)

    @staticmethod
    def AddToBuilder(*, builder: DiagramBuilder, plan: ScheduledPlan, name: str = "given_plan") -> "GivenPlan":
        """Adds a GivenPlan of ``plan`` named ``name``."""
        return builder.AddNamedSystem(name, GivenPlan(plan))

