"""Real-time factors of ``simulate``'s engine against the bare station, in one run.

Run: ``python benchmarks/bench_pipeline.py [--trials 10] [--controller compiled]``
(one process: ``--workers 1``, the only value). ``simulate``'s engine runs N trials of
``sims/transferring.yaml`` with ``paper5`` on one pipeline Diagram; after each trial the
bare station (the same UR5e plant and drive with the task's table, obstacle and shell,
5 ms step, a held position command, no controller, no monitor) simulates as long as that
trial did, so the machine's load falls on both alike. Prints:

- the bare station: simulated time / wall time;
- the closed loop alone (from the arm at rest at con_1 to the last critical
  configuration: controller, drive, plant, monitor, logger), and its ratio to the bare
  station (target: at least 0.6);
- end to end (planning, placing the arm, the closed loop, judging), and its ratio
  (target: at least 0.3);
- each part's wall per trial: bare station, closed loop, placing the arm, planning,
  judging and the rest.
"""

from __future__ import annotations

import argparse
import dataclasses
import time

import numpy as np
from pydrake.systems.analysis import Simulator

from drake_lfd.core.resources import scenarios_directory
from drake_lfd.experiments import simulation
from drake_lfd.experiments.judging import judge_run
from drake_lfd.io.simulation_config import CONTROLLER_METHODS, PipelineConfig
from drake_lfd.diagrams.station import build_station
from drake_lfd.experiments.simulation import TrialRunner
from drake_lfd.io.library import Library, library_features
from drake_lfd.io.task_files import load_task
from drake_lfd.robot.scene import table_under_robot

Q_HOME = np.array([0.0, -1.2, 1.6, -1.97, -np.pi / 2, 0.0])


def bare_station_wall_s(task, duration_s: float) -> float:
    """Wall time of the bare station (the task's scene, the closed loop's plant step and
    drive) holding a position for ``duration_s`` simulated seconds."""
    config = PipelineConfig().checked().station
    station = build_station(X_WB=task.X_WB, X_tool0_E=task.X_tool0_E, obstacles=task.obstacles,
                            safety_shells=task.safety_shells, table=table_under_robot(task.X_WB), config=config)
    context = station.CreateDefaultContext()
    station.set_initial_positions(context, Q_HOME)
    station.GetInputPort("ur5e.position_command").FixValue(context, Q_HOME)
    simulator = Simulator(station, context)
    simulator.Initialize()
    start = time.perf_counter()
    simulator.AdvanceTo(duration_s)
    return time.perf_counter() - start


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
    runner = TrialRunner(task, features, config=config)
    walls = {"planning": 0.0, "judging": 0.0}
    loop_runner = runner._runner
    plan = loop_runner.plan

    def timed_plan(*a, **k):
        start = time.perf_counter()
        try:
            return plan(*a, **k)
        finally:
            walls["planning"] += time.perf_counter() - start

    def timed_judge(*a, **k):
        start = time.perf_counter()
        try:
            return judge_run(*a, **k)
        finally:
            walls["judging"] += time.perf_counter() - start

    loop_runner.plan = timed_plan
    simulation.judge_run = timed_judge
    outcomes, wall, bare_wall = [], 0.0, 0.0
    for i in range(args.trials):
        start = time.perf_counter()
        outcomes.append(runner.run(trial=i + 1, seed=i))
        wall += time.perf_counter() - start
        if outcomes[-1].run is not None:
            bare_wall += bare_station_wall_s(task, outcomes[-1].run.sim_time_s)
    runs = [o.run for o in outcomes if o.run is not None]
    sim = sum(r.sim_time_s for r in runs)
    bare = sim / bare_wall
    loop_wall = sum(r.wall_time_s for r in runs)
    setup_wall = sum(r.setup_wall_time_s for r in runs)
    end_to_end = sim / wall
    n = len(outcomes)
    print(f"{args.trials} transferring trials ({sum(o.success for o in outcomes)}/{n} succeeded), "
          f"{sim:.1f} s simulated, controller {runner._runner.pipeline.config.controller.method}, one process")
    print(f"  bare station (plant + drive + scene, 5 ms step, held command): {bare:.1f}x real time")
    print(f"  closed loop alone: {sim / loop_wall:.1f}x real time = {sim / loop_wall / bare:.2f} of the bare station "
          f"(target >= 0.6)")
    print(f"  end to end (planning, placing the arm, closed loop, judging): {end_to_end:.1f}x real time = "
          f"{end_to_end / bare:.2f} of the bare station (target >= 0.3)")
    other = wall - loop_wall - setup_wall - walls["planning"] - walls["judging"]
    print(f"  wall per trial: bare station {bare_wall / len(runs):.3f} s | closed loop {loop_wall / len(runs):.3f} s, "
          f"placing the arm {setup_wall / len(runs):.3f} s, planning {walls['planning'] / n:.3f} s, "
          f"judging {walls['judging'] / n:.3f} s, the rest {other / n:.3f} s")


if __name__ == "__main__":
    main()
