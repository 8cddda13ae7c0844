"""Time a closed-loop UR5e run of a 10 s plan with the shell monitor on.

Run: ``python benchmarks/bench_closed_loop.py [--time-step 0.005] [--controller compiled]
[--compare]`` (``--controller drake`` or ``pseudo_inverse``: the Python task-space
controller). Prints simulated time, wall time and their ratio (target: at least 10x
real time), the same by the process's CPU time, the tracking errors (along the path and
at the critical configurations), the closest approach to the safety shell, the largest
joint speed as a fraction of the UR5e's limit, and the per-call cost of the pieces of
the loop. ``--compare`` repeats
the run for plant steps of 1, 2 and 4 ms, so the accuracy cost of a larger step is
visible next to its speed.

Where the time went, and what was done (2-core machine, shared): a first measurement gave
3.3x with a 1 ms plant and a Python differential IK at 10 ms.

- The plant step with PD-controlled actuators costs 170-230 us whatever the step (SAP's
  fixed overhead; gains, rotor inertia, contact model, sampled ports changed nothing),
  so a 1 ms plant caps a run near 5x. The closed loop uses a 5 ms step: its accuracy
  stays far inside the 5 mm / 2 deg tolerances (see ``closed_loop.py``'s table).
- Drake's differential-IK QP cost 150-270 us per call from Python; for the UR5e's square
  Jacobian it has a closed form, now evaluated directly (same answer to 1e-13): the
  whole Python controller update is about 100 us. The C++
  ``DifferentialInverseKinematicsIntegrator`` neither takes the velocity feed-forward nor
  feeds back the measured pose the way this controller does (and
  ``DifferentialInverseKinematicsController`` runs open loop on its own command), so the
  default controller is built from pydrake primitives instead
  (``systems/joint_trajectory_controller.py``): the same law in joint space on the plan's
  joint path, no Python at 100 Hz. On this plan it tracks 0.72 mm at most along the
  path, 0.17 mm rms, 0.024 mm at the critical configurations, against 1.34 / 0.20 /
  0.086 mm for the Python controller (0.93 / 0.17 / 0.060 mm while its command was fed
  through to the drive and re-evaluated at every plant step; now the drive holds it
  between the 10 ms updates, with the feed-forward one period ahead).
- The monitor measures the joint log in batches (``systems/shell_monitor.py``); its
  figure below is one sample measured with every pair, for scale.
- The monitor loops over pairs in plain Python (numpy's per-call overhead cost more
  than the queries); pruning pairs by bounding spheres was slower (``GetPoseInWorld``
  costs as much as a distance query).
- The controller updates just before the drive samples its command, which also brought
  the 5 ms plant's path error down to the 1 ms plant's (rms 0.20 mm against 0.74 mm
  before; 0.16 mm at 1 ms).
"""

from __future__ import annotations

import argparse
import math
import timeit

import numpy as np
from pydrake.systems.analysis import Simulator

from drake_lfd.diagrams.closed_loop import plan_through_joint_configurations, run_closed_loop
from drake_lfd.io.simulation_config import CLOSED_LOOP_TIME_STEP_S, CONTROLLER_METHODS, PipelineConfig, StationConfig
from drake_lfd.diagrams.pipeline import build_pipeline
from drake_lfd.systems.differential_ik import pose_error
from drake_lfd.robot.kinematics import UR5eKinematics
from drake_lfd.robot.scene import min_signed_distances
from drake_lfd.diagrams.station import build_station
from drake_lfd.core.tasks import Box
from drake_lfd.core.timing import TimedPlan

PLAN_DURATION_S = 10.0
Q_HOME = np.array([0.0, -1.2, 1.6, -1.97, -math.pi / 2, 0.0])
Q_CRITICAL = np.array(
    [
        Q_HOME,
        Q_HOME + [0.6, 0.2, -0.3, 0.2, 0.3, 0.4],
        Q_HOME + [-0.5, -0.3, 0.2, 0.1, -0.2, -0.5],
        Q_HOME,
    ]
)
# The paper's transferring-task obstacle and shell (Table 7), moved beside this path.
OBSTACLES = [Box(name="cube", centre=[-0.3, 0.45, 0.2], size=[0.2, 0.2, 0.2])]
SAFETY_SHELLS = [Box(name="cube_shell", centre=[-0.3, 0.45, 0.2], size=[0.4, 0.4, 0.4])]


def benchmark_plan() -> TimedPlan:
    """Four critical configurations, stretched or squeezed to exactly 10 s."""
    plan = plan_through_joint_configurations(Q_CRITICAL)
    return TimedPlan(plan.times * (PLAN_DURATION_S / plan.duration), plan.poses, plan.critical_indices)


def path_tracking_errors(result, plan):
    """Max and rms position error (m) and max rotation error (rad) against the plan."""
    kinematics = UR5eKinematics()
    trajectory = plan.to_piecewise_pose()
    errors = np.array(
        [
            pose_error(
                trajectory.GetPose(min(max(t - result.plan_start_time_s, 0.0), plan.duration)),
                kinematics.X_WE(q),
            )
            for t, q in zip(result.t, result.q)
        ]
    )
    position = np.linalg.norm(errors[:, 3:], axis=1)
    rotation = np.linalg.norm(errors[:, :3], axis=1)
    return position.max(), math.sqrt(np.mean(position**2)), rotation.max()


def per_call_costs(plan, time_step, controller):
    """Median cost (us) of one controller update, one monitor update and one plant step."""
    config = PipelineConfig()
    config.station.time_step = time_step
    config.controller.method = controller
    loop = build_pipeline(plan=plan, obstacles=OBSTACLES, safety_shells=SAFETY_SHELLS, with_table=False,
                          config=config)
    context = loop.CreateDefaultContext()
    loop.station.set_initial_positions(context, Q_HOME)
    controller_context = loop.controller.GetMyContextFromRoot(context)
    monitor_context = loop.monitor.GetMyContextFromRoot(context)
    costs = {}
    clock = iter(np.arange(1, 10**6) * 1e-6)
    scene = loop.station.scene
    query_port = loop.monitor.query_object_input_port

    def controller_update():
        # A new time invalidates the cached update and everything upstream of it.
        context.SetTime(next(clock))
        loop.controller.EvalUniquePeriodicDiscreteUpdate(controller_context)

    def monitor_sample():
        context.SetTime(next(clock))
        min_signed_distances(
            query_port.Eval(monitor_context), scene.robot_geometry_ids, scene.keep_out_geometry_ids
        )

    for name, function in (
        ("differential IK update", controller_update),
        (f"shell monitor sample ({len(scene.keep_out_geometry_ids)} boxes)", monitor_sample),
    ):
        times = timeit.repeat(function, number=20, repeat=25)
        costs[name] = 1e6 * float(np.median(times)) / 20
    station = build_station(obstacles=OBSTACLES, safety_shells=SAFETY_SHELLS,
                            config=StationConfig(time_step=time_step))
    station_context = station.CreateDefaultContext()
    station.set_initial_positions(station_context, Q_HOME)
    station.GetInputPort("ur5e.position_command").FixValue(station_context, Q_HOME)
    simulator = Simulator(station, station_context)
    simulator.Initialize()
    steps = 500
    start = timeit.default_timer()
    simulator.AdvanceTo(steps * time_step)
    costs["station step (plant + drive)"] = 1e6 * (timeit.default_timer() - start) / steps
    return costs


def run_once(plan, time_step, controller):
    result = run_closed_loop(
        plan,
        q_initial=Q_HOME,
        obstacles=OBSTACLES,
        safety_shells=SAFETY_SHELLS,
        time_step=time_step,
        controller=controller,
    )
    path_max, path_rms, rotation_max = path_tracking_errors(result, plan)
    critical_position = max(e.position_m for e in result.critical_errors)
    critical_rotation = max(e.rotation_rad for e in result.critical_errors)
    print(
        f"plant step {1000 * time_step:.1f} ms, {controller}: sim {result.sim_time_s:.2f} s, wall "
        f"{result.wall_time_s:.2f} s, {result.realtime_factor:.1f}x real time (CPU {result.cpu_time_s:.2f} s, "
        f"{result.sim_time_s / result.cpu_time_s:.1f}x) | path error max "
        f"{1000 * path_max:.2f} mm, rms {1000 * path_rms:.2f} mm, {math.degrees(rotation_max):.2f} deg | "
        f"critical max {1000 * critical_position:.3f} mm, {math.degrees(critical_rotation):.3f} deg | "
        f"shell clearance {1000 * result.min_shell_distance_m:.0f} mm | max joint speed "
        f"{result.max_joint_speed_fraction:.2f} of limit"
    )
    return result


def main(argv=None):
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--time-step", type=float, default=CLOSED_LOOP_TIME_STEP_S, help="plant step, s")
    parser.add_argument("--controller", default="compiled", choices=list(CONTROLLER_METHODS),
                        help="compiled (the default: the plan's joint path in Drake's C++ systems), or the Python "
                             "task-space controller with Drake's law (drake) or the paper's (pseudo_inverse)")
    parser.add_argument("--compare", action="store_true", help="also run plant steps of 1, 2 and 4 ms")
    args = parser.parse_args(argv)

    plan = benchmark_plan()
    print(f"plan: {plan.duration:.1f} s, {len(plan.critical_indices)} critical configurations, monitor at 100 Hz")
    steps = [args.time_step]
    if args.compare:
        steps = sorted({1e-3, 2e-3, 4e-3, args.time_step})
    results = [run_once(plan, step, args.controller) for step in steps]
    for name, cost in per_call_costs(plan, args.time_step, args.controller).items():
        print(f"  {name}: {cost:.0f} us per call")
    return results


if __name__ == "__main__":
    main()
