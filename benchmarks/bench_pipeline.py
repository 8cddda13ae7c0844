"""Real-time factors of ``simulate``'s engine against the bare station, in one run.

Run: ``python benchmarks/bench_pipeline.py [--trials 10] [--controller compiled]``
(one process: ``--workers 1``, the only value). ``simulate``'s engine runs N trials of
``sims/transferring.yaml`` with ``paper5`` on one pipeline Diagram; after each trial the
bare station (the same UR5e plant and drive with the task's table, obstacle and shell,
5 ms step, a held position command, no controller, no monitor) simulates as long as that
trial did, so the machine's load falls on both alike. Prints:

- the bare station: simulated time / wall time;
- the closed loop alone (from the arm at rest at con_1 to the last critical
  configuration: controller, drive, plant, monitor, logger, and reading the run off the
  Context, where the monitor measures the logged samples), and its ratio to the bare
  station (target: at least 0.6);
- end to end (planning, placing the arm, the closed loop, judging), and its ratio
  (target: at least 0.3);
- each part's wall per trial: bare station, closed loop, placing the arm, planning,
  judging and the rest;
- for scale, the station driven along each trial's joint path by a TrajectorySource (no
  controller, no monitor): how much of the closed loop's cost is the moving arm's plant.

Not in any trial's figures: building the runner (the pipeline Diagram, and with it the
library prepared for the legal-action table: its stacks, its span index and that index's
one-time import of ``scipy.spatial``), printed on its own as "built once", as a
``simulate`` process pays it once before its first trial.

The ratios are printed by wall time (the measure) and by the process's CPU time, which
other processes on a shared machine do not inflate. Python's garbage is collected before
each timed part: the bare stations' Diagrams are reference cycles, and collecting them
(30-40 ms) inside the next trial's timing would charge the closed loop for the bench.
"""

from __future__ import annotations

import argparse
import dataclasses
import gc
import time

import numpy as np
from pydrake.systems.analysis import Simulator
from pydrake.systems.framework import DiagramBuilder
from pydrake.systems.primitives import ConstantVectorSource, TrajectorySource

from drake_lfd.core.resources import scenarios_directory
from drake_lfd.experiments import simulation
from drake_lfd.diagrams.judging import judge_run
from drake_lfd.io.simulation_config import CONTROLLER_METHODS, PipelineConfig
from drake_lfd.diagrams.station import build_station
from drake_lfd.experiments.simulation import TrialRunner
from drake_lfd.io.library import Library, library_features
from drake_lfd.io.task_files import load_task
from drake_lfd.planning.options import PlanningOptions
from drake_lfd.robot.scene import table_under_robot
from drake_lfd.systems.joint_trajectory_controller import joint_spline

Q_HOME = np.array([0.0, -1.2, 1.6, -1.97, -np.pi / 2, 0.0])


def bare_station_times_s(task, duration_s: float, outcome=None) -> tuple[float, float]:
    """Wall and CPU time of the bare station (the task's scene, the closed loop's plant
    step and drive) holding a position for ``duration_s`` simulated seconds; with a trial's
    ``outcome``, driven along its plan's joint path instead (a TrajectorySource on the
    position command: the moving arm's plant cost, without controller or monitor)."""
    config = PipelineConfig().checked().station
    builder = DiagramBuilder()
    station = builder.AddSystem(build_station(
        X_WB=task.X_WB, X_tool0_E=task.X_tool0_E, obstacles=task.obstacles, safety_shells=task.safety_shells,
        table=table_under_robot(task.X_WB), config=config))
    if outcome is None:
        q0, command = Q_HOME, ConstantVectorSource(Q_HOME)
    else:
        path = outcome.plan.joint_path
        q0 = path.q[0]
        command = TrajectorySource(joint_spline(outcome.run.plan_start_time_s + path.t, path.q))
    builder.Connect(builder.AddSystem(command).get_output_port(), station.GetInputPort("ur5e.position_command"))
    diagram = builder.Build()
    context = diagram.CreateDefaultContext()
    station.set_initial_positions(context, q0)
    simulator = Simulator(diagram, context)
    simulator.Initialize()
    gc.collect()  # the bench's own garbage (earlier Diagrams) is not this part's cost
    start, cpu_start = time.perf_counter(), time.process_time()
    simulator.AdvanceTo(duration_s)
    return time.perf_counter() - start, time.process_time() - cpu_start


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--trials", type=int, default=10)
    parser.add_argument("--workers", type=int, default=1, help="1: the measure is of one process")
    parser.add_argument("--controller", default=None, choices=list(CONTROLLER_METHODS),
                        help="default: the task's (compiled)")
    parser.add_argument("--controller-period", type=float, default=None, help="s (default: the task's)")
    parser.add_argument("--monitor-period", type=float, default=None, help="s (default: the task's)")
    args = parser.parse_args()
    if args.workers != 1:
        parser.error("--workers: the measure is of one process; only 1 is supported")
    task = load_task(scenarios_directory() / "transferring.yaml")
    features = library_features(Library.open("paper5"))
    config = task.simulation
    if args.controller is not None:
        config = dataclasses.replace(config, controller=dataclasses.replace(config.controller, method=args.controller))
    if args.controller_period is not None:
        config = dataclasses.replace(config, controller=dataclasses.replace(
            config.controller, time_step=args.controller_period)).checked()
    if args.monitor_period is not None:
        config = dataclasses.replace(config, monitor=dataclasses.replace(config.monitor, period=args.monitor_period))
    build_start, build_cpu_start = time.perf_counter(), time.process_time()
    runner = TrialRunner(task, features, config=config, options=PlanningOptions(cost="paper"))
    build = (time.perf_counter() - build_start, time.process_time() - build_cpu_start)
    walls = {"planning": [0.0, 0.0], "judging": [0.0, 0.0]}  # [wall, CPU]

    def timed(part, function):
        def wrapper(*a, **k):
            start, cpu_start = time.perf_counter(), time.process_time()
            try:
                return function(*a, **k)
            finally:
                walls[part][0] += time.perf_counter() - start
                walls[part][1] += time.process_time() - cpu_start
        return wrapper

    loop_runner = runner._runner
    loop_runner.plan = timed("planning", loop_runner.plan)
    simulation.judge_run = timed("judging", judge_run)
    outcomes = []
    wall, cpu, bare_wall, bare_cpu, moving_wall, moving_cpu = 0.0, 0.0, 0.0, 0.0, 0.0, 0.0
    for i in range(args.trials):
        # The Diagrams of the bare stations before, freed now rather than by a collection
        # inside the trial's timing (each part is timed without the others' garbage).
        gc.collect()
        start, cpu_start = time.perf_counter(), time.process_time()
        outcomes.append(runner.run(trial=i + 1, seed=i))
        wall += time.perf_counter() - start
        cpu += time.process_time() - cpu_start
        if outcomes[-1].run is not None:
            w, c = bare_station_times_s(task, outcomes[-1].run.sim_time_s)
            bare_wall, bare_cpu = bare_wall + w, bare_cpu + c
            w, c = bare_station_times_s(task, outcomes[-1].run.sim_time_s, outcomes[-1])
            moving_wall, moving_cpu = moving_wall + w, moving_cpu + c
    runs = [o.run for o in outcomes if o.run is not None]
    n, m = len(outcomes), len(runs)
    sim = sum(r.sim_time_s for r in runs)
    loop = [sum(r.wall_time_s for r in runs), sum(r.cpu_time_s for r in runs)]
    setup = sum(r.setup_wall_time_s for r in runs)
    print(f"{args.trials} transferring trials ({sum(o.success for o in outcomes)}/{n} succeeded), "
          f"{sim:.1f} s simulated, controller {loop_runner.pipeline.config.controller.method}, one process")
    for label, index, bare_time, moving_time, total in (("wall", 0, bare_wall, moving_wall, wall),
                                                         ("CPU", 1, bare_cpu, moving_cpu, cpu)):
        bare = sim / bare_time
        print(f"  by {label} time: bare station (plant + drive + scene, 5 ms step, held command) {bare:.1f}x real time; "
              f"closed loop alone {sim / loop[index]:.1f}x = {sim / loop[index] / bare:.2f} of it (target >= 0.6); "
              f"end to end {sim / total:.1f}x = {sim / total / bare:.2f} of it (target >= 0.3); "
              f"[the station driven along the plans' joint paths, no controller: {sim / moving_time:.1f}x = "
              f"{sim / moving_time / bare:.2f}]")
    other = wall - loop[0] - setup - walls["planning"][0] - walls["judging"][0]
    print(f"  wall per trial: bare station {bare_wall / m:.3f} s | closed loop {loop[0] / m:.3f} s, "
          f"placing the arm {setup / m:.3f} s, planning {walls['planning'][0] / n:.3f} s, "
          f"judging {walls['judging'][0] / n:.3f} s, the rest {other / n:.3f} s")
    print(f"  CPU per trial: bare station {bare_cpu / m:.3f} s | closed loop {loop[1] / m:.3f} s, "
          f"planning {walls['planning'][1] / n:.3f} s, judging {walls['judging'][1] / n:.3f} s, "
          f"trial in all {cpu / n:.3f} s")
    print(f"  built once, before the trials (Diagram, prepared library): {build[0]:.3f} s wall, {build[1]:.3f} s CPU")


if __name__ == "__main__":
    main()
