"""The compiled closed loop: the plan's joint path tracked by Drake's own C++ systems.

At run time a checked plan is already a timed joint path (``PlanResult.joint_path``, the
one the differential-IK law commands, sampled every controller period), and its SE(3)
path is that path's forward kinematics. :class:`JointTrajectoryController` tracks it
with no Python in the 100 Hz loop: a subsystem Diagram of pydrake primitives::

    chunk -> sample of the clock's instant (w_k: the path's feed-forward step and
             dt K q_d, per period) ------------------\
                                                      Multiplexer -> MatrixGain (dt v) -> Saturation
    q_measured --------------------------------------/                     (joint speed limits)
        -> LinearSystem (discrete, period dt, no feed-through: the command integrator, from 0)
        -> Adder (+ q_0, the run's initial positions) -> Saturation (position limits) -> q_command

with the same law as the Python controller (``differential_ik.py``), written in joint space::

    dt v_k = (q_d(t_k + 2 dt) - q_d(t_k + dt)) + dt K (q_d(t_k) - q_measured(t_k)),
             |v_k,j| <= fraction * vmax_j
    q_command,k+1 = q_command,k + dt v_k     (Eq. 37-38's Euler step)

For small errors ``J^-1 (X_WE_desired [-] X_WE(q_measured)) = q_d - q_measured`` to first
order, so this is the task-space law's feedback (gain K = 20 /s, integrated on the
command side: integral action on the tracking error) with the feed-forward of a path that
already is the law's, as the path's own step over a period (so open loop the command is
the path, sample for sample). Everything but the measurement is known before the run, so
``w_k`` is computed then, one value per controller instant, and travels to the
controller in chunks: :class:`~drake_lfd.systems.joint_path_source.JointPathSource`
reads the plan on its input port at the run's start, keeps the run's ``w_k`` in its
Context (a cache entry of the plan and the arm's initial positions) and, once every
``M`` periods (a Python event at 4 Hz, outside the 100 Hz loop), puts out the next ``M``
samples as one vector; the controller picks the sample of its clock's instant with Drake
primitives (see :class:`JointTrajectoryController`). One Diagram therefore runs many
trials in many Contexts, and Drake's tools for many runs (``MonteCarloSimulation``) work
on it.

The integrator is a discrete ``LinearSystem`` (``x <- x + dt v`` at the instants the drive
samples the command) whose output is its state, so the drive holds the command between
updates and the controller's systems are evaluated once a period, at the update, not at
every plant step. With the output fed through, ``y = x + dt v``, as before, every 5 ms
plant step evaluated the whole chain again with that step's measurement, for a command
that moved between the drive's samples, and the closed loop cost well above the station
driven along the same joint path; now it costs about the same. The instructions executed
barely changed (callgrind), so the saving is in the memory system, not in arithmetic. The update at
``t_k`` sees the positions of ``t_k`` (the station's plant steps as a discrete update,
simultaneous with this one) and its command takes effect from the next plant step, so
the feed-forward is the path's step one period ahead, as the Python controller targets
the pose due one period later. On the 10 s benchmark plan (``benchmarks/bench_closed_loop.py``)
the lead of the feed-forward step, in periods, gives (path max / rms, at the critical
configurations, mm)::

    lead       0           0.25        0.5         0.75        1           1.5
    tracking   1.46/0.27   1.24/0.24   1.03/0.21   0.84/0.18   0.72/0.17   0.69/0.17
    at cons    0.082       0.073       0.062       0.041       0.024       0.160

against 0.93 / 0.17 / 0.060 with the fed-through output. The feedback compares the path
at the measurement's own time: a quarter period either way leaves 0.42-0.45 mm rms.
(With Drake's sampled output ports the plant's step is an unrestricted update, applied
before the discrete updates of the same instant: the integrator then sees the positions
of ``t_k + h``, ``h`` the plant step, and the feedback compares them with the path at
``t_k + h``, ``lead_s``.) Limits: the commanded joint speeds are clipped per joint to
``velocity_limit_fraction`` of the UR5e's limits and the command to the joint position
limits (the Python law scales the whole motion instead; plans are timed within 0.9 of
the limits, so on the paper's tasks neither binds).

The desired joint path of a run is given as samples at the controller instants:
:func:`joint_path_of_plan` gives them, the plan's checked joint path, or (a plan made
without the check, or given as an SE(3) motion) the path the controller's law takes
following the plan kinematically. Only those samples are read, so no spline is built for
a run; :func:`joint_trajectory_of_plan` is the path as a cubic Hermite spline, for
plotting or driving a bare station.

Not for: the task-space Python controller (``differential_ik.py``, the paper's
baseline), the drive (``diagrams/station.py``).
"""

from __future__ import annotations

import math

import numpy as np
import scipy.sparse
from pydrake.systems.framework import Context, Diagram, DiagramBuilder
from pydrake.systems.primitives import (
    Adder, AffineSystem, Demultiplexer, LinearSystem, MatrixGain, Multiplexer, Saturation, SparseMatrixGain,
)
from pydrake.trajectories import PiecewisePolynomial

from drake_lfd.planning.replanning import ScheduledPlan
from drake_lfd.robot.differential_ik_law import DEFAULT_POSITION_GAIN, DEFAULT_TIME_STEP_S, DifferentialIKLaw

__all__ = ["JointTrajectoryController", "joint_path_of_plan", "joint_trajectory_of_plan", "joint_spline",
           "law_for_plant", "JOINT_PATH_AGREEMENT_M", "CHUNK_SAMPLES", "chunk_size", "feed_forward_samples"]

# A plan's joint path is used as it is when its forward kinematics meets the plan's
# critical configurations this closely (a path that no longer belongs to the plan, for
# example after a splice, is re-derived instead).
JOINT_PATH_AGREEMENT_M = 1e-3

# Controller instants per chunk of the path (the source's Python event runs once a chunk:
# every 0.25 s at the 10 ms period, outside the 100 Hz loop; a Python event costs about
# as much as the whole selection's update, and the selection's vectors grow with M).
CHUNK_SAMPLES = 25

# |w| bound of the chunk's gate (module docstring): w_k is about dt K |q| < 1 rad.
_GATE_BOUND = 1.0e3


def joint_spline(t: np.ndarray, q: np.ndarray) -> PiecewisePolynomial:
    """Cubic Hermite spline through samples ``q`` (m, n) at times ``t`` (m,), with
    central-difference velocities (zero at both ends: plans start and end at rest)."""
    t = np.asarray(t, dtype=float)
    q = np.asarray(q, dtype=float)
    if len(t) < 2:
        t, q = np.array([t[0], t[0] + 1.0]), np.vstack([q[0], q[0]])
    qdot = np.gradient(q, t, axis=0)
    qdot[0] = qdot[-1] = 0.0
    return PiecewisePolynomial.CubicHermite(t, q.T, qdot.T)


def _follow(scheduled: ScheduledPlan, q_initial: np.ndarray, law: DifferentialIKLaw,
            corrections: int = 2) -> tuple[np.ndarray, np.ndarray]:
    """The joint path of ``scheduled`` from ``q_initial``, one sample per period from the
    plan's start: t (m,), q (m, 6).

    Each sample is the law's Euler step from the previous one (measured = commanded,
    as the plan-time check follows a plan), then ``corrections`` Newton steps of the
    law's feedback onto the plan's pose at that time, so the path's forward kinematics
    is the plan (without them the kinematic follow lags it by up to 0.8 mm).
    """
    dt = law.time_step
    duration = scheduled.timed.duration
    steps = int(math.ceil(duration / dt - 1e-9)) + 1
    q = np.array(q_initial, dtype=float)
    path = [q]
    zero = np.zeros(6)
    for k in range(steps):
        t = scheduled.start_time_s + k * dt
        q = q + dt * law.joint_velocity(q, q, scheduled.X_WE_desired(t), scheduled.V_WE_desired(t))
        if law.position_gain > 0.0:
            X_next = scheduled.X_WE_desired(t + dt)
            for _ in range(corrections):
                # v = K J^-1 (X_next [-] X(q)): v / K is a Newton step toward X_next.
                q = q + law.joint_velocity(q, q, X_next, zero) / law.position_gain
        path.append(q)
    return scheduled.start_time_s + dt * np.arange(len(path)), np.array(path)


def _path_matches_plan(scheduled: ScheduledPlan, q_initial: np.ndarray, law: DifferentialIKLaw) -> bool:
    """Whether the plan's joint path starts at ``q_initial`` and meets each critical
    configuration, at the sample nearest its time, within :data:`JOINT_PATH_AGREEMENT_M`
    plus half a period at 1 m/s (a path spliced from another plan does not)."""
    path = scheduled.result.joint_path
    if path is None or len(path.q) < 2 or not np.array_equal(path.q[0], q_initial):
        return False
    timed = scheduled.timed
    tolerance = JOINT_PATH_AGREEMENT_M + 0.5 * law.time_step * 1.0
    for i, X_plan in zip(timed.critical_indices, timed.X_WE_critical()):
        k = int(round(timed.times[i] / law.time_step))
        if k >= len(path.q):
            return False
        if np.linalg.norm(law.X_WE(path.q[k]).translation() - X_plan.translation()) > tolerance:
            return False
    return True


def joint_path_of_plan(scheduled: ScheduledPlan, q_initial: np.ndarray,
                       law: DifferentialIKLaw) -> tuple[np.ndarray, np.ndarray]:
    """The desired joint path of a run, one sample per controller period: simulation
    times t (m,) and positions q (m, 6).

    The plan's checked joint path when it starts at ``q_initial`` and still belongs to
    the plan (its forward kinematics meets the critical configurations); otherwise the
    path the law takes following the SE(3) plan from ``q_initial`` (``law``: the
    controller's period, gain and limits, on any plant of the arm).
    """
    q_initial = np.asarray(q_initial, dtype=float)
    if _path_matches_plan(scheduled, q_initial, law):
        path = scheduled.result.joint_path
        return scheduled.start_time_s + np.asarray(path.t, dtype=float), np.asarray(path.q, dtype=float)
    return _follow(scheduled, q_initial, law)


def joint_trajectory_of_plan(scheduled: ScheduledPlan, q_initial: np.ndarray,
                             law: DifferentialIKLaw) -> PiecewisePolynomial:
    """:func:`joint_path_of_plan` as a :func:`joint_spline` (the desired joint trajectory
    of a run between the samples too, for plotting or driving a station)."""
    return joint_spline(*joint_path_of_plan(scheduled, q_initial, law))


def chunk_size(num_joints: int, samples: int = CHUNK_SAMPLES) -> int:
    """Length of a chunk vector: ``[q_0 (n), w_0 .. w_(M-1) (n each)]``."""
    return num_joints + num_joints * samples


def feed_forward_samples(t, q, time_step: float, position_gain: float, lead_s: float, first: int,
                         count: int) -> np.ndarray:
    """``w_k`` of the joint path ``q`` (m, n) at times ``t`` (m,) for controller instants
    ``k = first .. first + count - 1``: (count, n) (module docstring; the path linear
    between its samples, held before the first and after the last)."""
    dt = time_step
    grid = dt * (first + np.arange(count))
    t = np.asarray(t, dtype=float)
    q = np.asarray(q, dtype=float)
    at = lambda times: np.column_stack([np.interp(times, t, q[:, j]) for j in range(q.shape[1])])
    return at(grid + 2.0 * dt) - at(grid + dt) + dt * position_gain * at(grid + lead_s)


class JointTrajectoryController(Diagram):
    """Joint position command tracking a desired joint trajectory, in compiled systems.

    .. pydrake_system::

        name: JointTrajectoryController
        input_ports:
        - chunk
        - q_measured
        output_ports:
        - q_command

    ``q_measured`` and ``q_command`` are (6,) joint positions in UR joint order.
    ``chunk`` is the path's next samples, :func:`chunk_size` long: ``[q_0, w_0 ..
    w_(M-1)]``, ``w_i`` the feed-forward and feedback term (module docstring) of the
    chunk's i-th controller instant and ``q_0`` the run's initial command (the arm's
    positions at its start), as :class:`~drake_lfd.systems.joint_path_source.JointPathSource`
    puts it out. At each update the controller picks the sample of its instant with Drake
    primitives alone: a one-hot ``h`` of the instant's place in its chunk (a permutation
    state that turns once a period, from the run's start at t = 0), and a gate
    ``relu(w + B (h - 1)) - relu(-w + B (h - 1))`` that passes ``w`` exactly when ``h = 1``
    and gives exactly 0 when ``h = 0``. So the 100 Hz loop evaluates only C++ systems, and
    the command is the same to the bit as from a table of all samples.

    Parameters
    ----------
    position_lower, position_upper : array (6,)
        Joint position limits, rad.
    velocity_limits : array (6,)
        Joint speeds commanded at most, rad/s (already scaled by the speed fraction).
    time_step : float
        Update period, s (the drive's command period).
    position_gain : float
        K, 1/s.
    lead_s : float
        How much later than the update's instant the feedback reads the path (module
        docstring); used by the source that fills the chunks.
    chunk_samples : int
        M, the controller instants in one chunk.
    """

    def __init__(self, *, position_lower, position_upper, velocity_limits,
                 time_step: float = DEFAULT_TIME_STEP_S, position_gain: float = DEFAULT_POSITION_GAIN,
                 lead_s: float = 0.0, chunk_samples: int = CHUNK_SAMPLES):
        super().__init__()
        self.lead_s = float(lead_s)
        n = len(position_lower)
        M = int(chunk_samples)
        self.num_joints, self.chunk_samples = n, M
        self.time_step = float(time_step)
        self.position_gain = float(position_gain)
        dt, K = self.time_step, self.position_gain
        builder = DiagramBuilder()
        add = builder.AddNamedSystem
        identity = np.eye(n)
        stack = np.kron(np.ones((1, M)), identity)  # (n, nM): the sum over a chunk's samples
        split = add("chunk_split", Demultiplexer([n, n * M]))
        # The instant's place in its chunk as a one-hot h (exactly 0 or 1), put out as
        # h - 1: a permutation state that turns once a period. y = x + e_0 - 1 with
        # x <- P x + (P e_0 - e_0), x = 0 at the run's start (every Context's default):
        # y_k = e_(k mod M) - 1, in exact arithmetic (every value is 0 or +-1).
        rotate = np.roll(np.eye(M), 1, axis=0)  # e_i -> e_(i+1 mod M)
        first = np.eye(M)[:, 0]
        instant = add("instant_in_chunk", AffineSystem(
            A=rotate, B=np.zeros((M, 0)), f0=rotate @ first - first, C=np.eye(M), D=np.zeros((M, 0)),
            y0=first - 1.0, time_period=dt))
        instant_and_samples = add("instant_and_samples", Multiplexer([M, n * M]))
        # The gate: [w_i + B (h_i - 1); -w_i + B (h_i - 1)] per sample and joint: +-w_i
        # exactly for the instant's sample (its level is 0), below -B + |w| < 0 for the
        # others.
        per_sample = np.kron(np.eye(M), np.ones((n, 1)))  # (nM, M)
        level = _GATE_BOUND * per_sample
        gate = add("gate", SparseMatrixGain(scipy.sparse.csc_matrix(np.vstack([
            np.hstack([level, np.eye(n * M)]), np.hstack([level, -np.eye(n * M)])]))))
        relu = add("relu", Saturation(np.zeros(2 * n * M), np.full(2 * n * M, np.inf)))
        gated_and_measured = add("gated_and_measured", Multiplexer([2 * n * M, n]))
        # dt * v = w_k - dt K q_measured, w_k = sum_i relu(w_i + level_i) - relu(-w_i + level_i):
        # one step of the command.
        step = add("feed_forward_and_feedback", MatrixGain(np.hstack([stack, -stack, -dt * K * identity])))
        speed_limit = add("joint_speed_limits", Saturation(
            -dt * np.asarray(velocity_limits, dtype=float), dt * np.asarray(velocity_limits, dtype=float)))
        # The command integrator: x <- x + dt v every period, from 0 at the run's start;
        # the command is q_0 + x (no feed-through from the measurement or the clock: the
        # drive holds it until the next update, and nothing upstream is evaluated between
        # updates).
        self._command = add("command_integrator", LinearSystem(
            A=identity, B=identity, C=identity, D=np.zeros((n, n)), time_period=dt))
        initial_plus = add("initial_plus_integral", Adder(2, n))
        position_limit = add("joint_position_limits", Saturation(
            np.asarray(position_lower, dtype=float), np.asarray(position_upper, dtype=float)))
        builder.ExportInput(split.get_input_port(), "chunk")
        builder.Connect(instant.get_output_port(), instant_and_samples.get_input_port(0))
        builder.Connect(split.get_output_port(1), instant_and_samples.get_input_port(1))
        builder.Connect(instant_and_samples.get_output_port(), gate.get_input_port())
        builder.Connect(gate.get_output_port(), relu.get_input_port())
        builder.Connect(relu.get_output_port(), gated_and_measured.get_input_port(0))
        builder.ExportInput(gated_and_measured.get_input_port(1), "q_measured")
        builder.Connect(gated_and_measured.get_output_port(), step.get_input_port())
        builder.Connect(step.get_output_port(), speed_limit.get_input_port())
        builder.Connect(speed_limit.get_output_port(), self._command.get_input_port())
        builder.Connect(split.get_output_port(0), initial_plus.get_input_port(0))
        builder.Connect(self._command.get_output_port(), initial_plus.get_input_port(1))
        builder.Connect(initial_plus.get_output_port(), position_limit.get_input_port())
        builder.ExportOutput(position_limit.get_output_port(), "q_command")
        self._relu = relu
        self._stack = stack
        builder.BuildInto(self)
        self.set_name("joint_trajectory_controller")
        self.chunk_input_port = self.GetInputPort("chunk")
        self.q_measured_input_port = self.GetInputPort("q_measured")
        self.q_command_output_port = self.GetOutputPort("q_command")

    @staticmethod
    def AddToBuilder(*, builder: DiagramBuilder, law: DifferentialIKLaw, chunk_output_port, q_measured_output_port,
                     q_command_input_port=None, name: str = "differential_ik",
                     **kwargs) -> "JointTrajectoryController":
        """Adds a controller with ``law``'s limits, period and gain, named ``name``, fed by
        the joint-path source's chunks and the measured positions, and (when given)
        commanding ``q_command_input_port`` (``kwargs``: ``lead_s``, ``chunk_samples``)."""
        controller = builder.AddNamedSystem(name, JointTrajectoryController.for_law(law, **kwargs))
        builder.Connect(chunk_output_port, controller.chunk_input_port)
        builder.Connect(q_measured_output_port, controller.q_measured_input_port)
        if q_command_input_port is not None:
            builder.Connect(controller.q_command_output_port, q_command_input_port)
        return controller

    @classmethod
    def for_law(cls, law: DifferentialIKLaw, **kwargs) -> "JointTrajectoryController":
        """A controller with ``law``'s limits, period and gain (``kwargs``: ``lead_s``,
        ``chunk_samples``)."""
        return cls(position_lower=law.position_lower, position_upper=law.position_upper,
                   velocity_limits=law.velocity_limits, time_step=law.time_step, position_gain=law.position_gain,
                   **kwargs)

    def feed_forward(self, root_context: Context) -> np.ndarray:
        """The ``w`` the controller reads at the clock's instant in ``root_context``, (6,)."""
        gated = self._relu.get_output_port().Eval(self._relu.GetMyContextFromRoot(root_context))
        half = len(gated) // 2
        return self._stack @ gated[:half] - self._stack @ gated[half:]


def law_for_plant(plant, model, frame_E, config) -> DifferentialIKLaw:
    """The controller's law (period, gain, speed fraction of a ``ControllerConfig``)."""
    return DifferentialIKLaw(plant=plant, model=model, frame_E=frame_E, time_step=config.time_step,
                             position_gain=config.position_gain,
                             velocity_limit_fraction=config.velocity_limit_fraction)

