"""Real-time factor of ``simulate``'s engine against the bare station, in one run.

Run: ``python benchmarks/bench_pipeline.py [--trials 10]``. Prints:

- the bare station (the same UR5e plant and drive with the task's table, obstacle and
  shell, 5 ms step, a held position command, no controller, no monitor): simulated
  time / wall time;
- ``simulate``'s engine end to end on ``sims/transferring.yaml`` with ``paper5``: N
  trials on one pipeline Diagram (the library and planner systems plan each trial, then
  the closed loop runs it and it is judged), total simulated time / total wall time,
  planning, initial IK and judging included;
- their ratio (target: at least 0.5), and where the wall time went: the closed loop
  alone against the bare station, and each part's wall per trial against the budget a
  ratio of 0.5 leaves (twice the bare station's).

The machine is shared, so the two are interleaved: after each trial the bare station
simulates as long as that trial did, and the ratio is of the sums.
"""

from __future__ import annotations

import argparse
import dataclasses
import time

import numpy as np
from pydrake.systems.analysis import Simulator

from drake_lfd.core.resources import scenarios_directory
from drake_lfd.io.simulation_config import PipelineConfig
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
    parser.add_argument("--controller-period", type=float, default=None, help="s (default: the task's)")
    parser.add_argument("--monitor-period", type=float, default=None, help="s (default: the task's)")
    args = parser.parse_args()
    task = load_task(scenarios_directory() / "transferring.yaml")
    features = library_features(Library.open("paper5"))
    config = task.simulation
    if args.controller_period is not None:
        config = dataclasses.replace(config, controller=dataclasses.replace(
            config.controller, time_step=args.controller_period)).checked()
    if args.monitor_period is not None:
        config = dataclasses.replace(config, monitor=dataclasses.replace(config.monitor, period=args.monitor_period))
    runner = TrialRunner(task, features, config=config)
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
    print(f"bare station (plant + drive + scene, 5 ms step, held command): {bare:.1f}x real time")
    print(f"simulate engine (one pipeline Diagram), {args.trials} transferring trials end to end: {sim:.1f} s simulated in "
          f"{wall:.2f} s wall = {end_to_end:.1f}x real time "
          f"({sum(o.success for o in outcomes)}/{len(outcomes)} succeeded)")
    print(f"ratio end to end / bare station: {end_to_end / bare:.2f} (target >= 0.5)")
    other_wall = wall - loop_wall - setup_wall
    print(f"  closed-loop simulation {loop_wall:.2f} s ({sim / loop_wall:.1f}x), placing the arm "
          f"(initial IK) {setup_wall:.2f} s, planning + judging + pipeline build {other_wall:.2f} s")
    # What the target leaves: at a ratio of 0.5 a trial may take twice the bare station's wall.
    print(f"  closed loop alone / bare station: {sim / loop_wall / bare:.2f}; per trial: bare station "
          f"{bare_wall / len(runs):.3f} s, closed loop {loop_wall / len(runs):.3f} s, planning + judging "
          f"{other_wall / len(outcomes):.3f} s (a ratio of 0.5 allows {2 * bare_wall / len(runs):.3f} s in all)")


if __name__ == "__main__":
    main()
