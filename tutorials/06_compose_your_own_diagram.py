# ---
# jupyter:
#   jupytext:
#     formats: ipynb,py:percent
#   kernelspec:
#     display_name: Python 3 (ipykernel)
#     language: python
#     name: python3
# ---

# %% [markdown]
# # Tutorial 6: compose your own Diagram
#
# `drake-lfd simulate` runs one Drake Diagram, `drake_lfd.build_pipeline`'s. Here you
# build that Diagram yourself, stage by stage, from the package's systems, and put one
# system of your own between the controller and the robot:
#
# - the UR5e work cell (`Station`), the library (`FeatureLibrarySystem`), the planner
#   (`PlannerSystem`, planning as `drake-lfd plan` does), the trajectory source
#   (`JointPathSource`) and the compiled controller (`JointTrajectoryController`), the
#   safety-shell monitor (`ShellMonitor`), a joint logger (Drake's `LogVectorOutput`)
#   and `TrialEnd`, which ends the simulation once the plan has been executed; each is
#   added with its `AddToBuilder(builder=..., ...)`, keyword arguments only, which
#   connects its inputs;
# - your own LeafSystem, a *command watchdog*: it passes the joint command on unchanged
#   and keeps, in its Context, the largest step the command took in one period;
# - set a trial up in a Context, simulate it, read the run off the Context and judge it
#   with the criteria `simulate` uses.
#
# Everything a trial needs lives in the Context (task input, plan, joint path, arm state,
# log, monitor records), so the same Diagram can run any number of trials, in turn or in
# several Contexts at once. At the end the tutorial checks that your Diagram commanded
# exactly what `build_pipeline`'s does.
#
# The tutorial is a script, `06_compose_your_own_diagram.py`, and the same cells as a
# notebook (tutorials/README.md). Run the script from the repository's root:
#
#     python tutorials/06_compose_your_own_diagram.py --out out/06_compose_your_own_diagram

# %%
import argparse
import json
import time
from pathlib import Path

import numpy as np
from pydrake.systems.analysis import Simulator
from pydrake.systems.framework import DiagramBuilder, LeafSystem
from pydrake.systems.primitives import LogVectorOutput

import drake_lfd
from drake_lfd.core.resources import scenarios_directory
from drake_lfd.core.tasks import draw_trial
from drake_lfd.diagrams import Station, build_pipeline, joint_path_checker, judge_run
from drake_lfd.diagrams.trial_result import read_trial
from drake_lfd.experiments.notebooks import parse_tutorial_arguments, show
from drake_lfd.io.library import Library, library_features
from drake_lfd.planning.options import PlanningOptions
from drake_lfd.robot.kinematics import END_EFFECTOR_FRAME_NAME
from drake_lfd.robot.scene import KinematicScene
from drake_lfd.robot.workcell import Workcell
from drake_lfd.systems import (
    FeatureLibrarySystem, JointPathSource, JointTrajectoryController, PlannerSystem, ShellMonitor, TrialEnd,
)
from drake_lfd.systems.joint_trajectory_controller import law_for_plant

NAME = "06_compose_your_own_diagram"
SIMS = scenarios_directory()

# %% [markdown]
# ## Settings
#
# `--out DIR` (default `tutorials_out/06_compose_your_own_diagram`), `--seed S` (the
# trial). `--short` changes nothing here: the tutorial runs one trial either way. A
# notebook uses the defaults.

# %%
parser = argparse.ArgumentParser(description="Tutorial 6: compose your own Diagram")
parser.add_argument("--out", default=str(Path("tutorials_out") / NAME), metavar="DIR",
                    help="folder for the figure and the summary (created)")
parser.add_argument("--short", action="store_true", help="the same one trial")
parser.add_argument("--seed", type=int, default=0, metavar="S", help="the trial's seed")
args, short = parse_tutorial_arguments(parser)
out = Path(args.out)
out.mkdir(parents=True, exist_ok=True)
started = time.perf_counter()

# %% [markdown]
# ## 1. The task, its work cell and the library
#
# The work cell (`Workcell.of`) is the task's scene: robot base, table, obstacles,
# safety shells and tool. Its `planner_floor` is the table top the planner keeps the tool
# above. The simulation settings (plant step, controller period and gain, margins of the
# joint-space check) are the task's `simulation` block, a `PipelineConfig`.

# %%
task = drake_lfd.load_task(SIMS / "transferring.yaml")
workcell = Workcell.of(task)
config = task.simulation
library = Library.open("paper5")
features = library_features(library)
print(f"task {task.name}: {len(task)} critical configurations; library {library.label}: {library.names}")

# %% [markdown]
# ## 2. Your own system: a command watchdog
#
# A LeafSystem with one vector input and one vector output. Its state, in the Context,
# holds the previous command and the largest step between two commands; a discrete
# update once a controller period (when the controller's command changes) updates it.
# The output passes the command through unchanged, so the robot does exactly what the
# controller says. A real watchdog would stop the robot instead of only recording.

# %%
class CommandWatchdog(LeafSystem):
    """Passes a joint command through; records the largest per-period step of it."""

    def __init__(self, *, period: float, num_joints: int = 6):
        super().__init__()
        self._n = num_joints
        self.command_input_port = self.DeclareVectorInputPort("q_command_in", num_joints)
        # [previous command (n), largest step so far (1), samples seen (1)]
        self._state = self.DeclareDiscreteState(num_joints + 2)
        self.DeclarePeriodicDiscreteUpdateEvent(period, 0.0, self._watch)
        self.command_output_port = self.DeclareVectorOutputPort(
            "q_command_out", num_joints, lambda context, output: output.SetFromVector(
                self.command_input_port.Eval(context)))

    @staticmethod
    def AddToBuilder(*, builder, q_command_output_port, q_command_input_port, period: float,
                     name: str = "command_watchdog") -> "CommandWatchdog":
        watchdog = builder.AddNamedSystem(name, CommandWatchdog(period=period))
        builder.Connect(q_command_output_port, watchdog.command_input_port)
        builder.Connect(watchdog.command_output_port, q_command_input_port)
        return watchdog

    def _watch(self, context, discrete_state):
        q = self.command_input_port.Eval(context)
        state = context.get_discrete_state(self._state).value()
        previous, largest, seen = state[:self._n], state[self._n], state[self._n + 1]
        step = float(np.max(np.abs(q - previous))) if seen > 0 else 0.0
        discrete_state.set_value(self._state, np.concatenate([q, [max(largest, step), seen + 1]]))

    def largest_step(self, root_context) -> float:
        """The largest change of the command in one period so far, rad."""
        return float(self.GetMyContextFromRoot(root_context).get_discrete_state(self._state).value()[self._n])


# %% [markdown]
# ## 3. The Diagram, stage by stage
#
# Each stage's `AddToBuilder` adds it and connects its inputs; the arrows are the
# pipeline's. The controller's command goes to the watchdog instead of the station
# (`q_command_input_port` left out), and the watchdog's output drives the station.

# %%
builder = DiagramBuilder()
station = Station.AddToBuilder(builder=builder, workcell=workcell, config=config.station)
q_measured = station.GetOutputPort(station.port_name("position_measured"))
library_system = FeatureLibrarySystem.AddToBuilder(builder=builder, features=features,
                                                   X_tool0_E=workcell.X_tool0_E)
planner = PlannerSystem.AddToBuilder(
    builder=builder, library_output_port=library_system.library_output_port, options=PlanningOptions(),
    checker=joint_path_checker(workcell, config), floor_z=workcell.planner_floor,
    start_time_s=config.settle_s, check_period=None)
builder.ExportInput(planner.task_input_port, "task")
frame_E = station.controller_plant.GetFrameByName(END_EFFECTOR_FRAME_NAME)
law = law_for_plant(station.controller_plant, station.controller_model, frame_E, config.controller)
source = JointPathSource.AddToBuilder(builder=builder, plan_output_port=planner.plan_output_port,
                                      q_measured_output_port=q_measured, law=law)
controller = JointTrajectoryController.AddToBuilder(
    builder=builder, law=law, chunk_output_port=source.chunk_output_port, q_measured_output_port=q_measured)
watchdog = CommandWatchdog.AddToBuilder(
    builder=builder, q_command_output_port=controller.q_command_output_port,
    q_command_input_port=station.GetInputPort(station.port_name("position_command")),
    period=config.controller.time_step)
monitor = ShellMonitor.AddToBuilder(
    builder=builder, plant=station.plant, query_object_output_port=station.GetOutputPort("query_object"),
    robot_geometry_ids=station.scene.robot_geometry_ids, shell_geometry_ids=station.scene.keep_out_geometry_ids,
    robot_positions_output_port=q_measured, period=config.log_period, names=station.scene.names,
    kinds=station.scene.kinds, scene=KinematicScene(workcell))
logger = LogVectorOutput(station.GetOutputPort(station.port_name("state")), builder, config.log_period)
TrialEnd.AddToBuilder(builder=builder, plan_output_port=planner.plan_output_port)
diagram = builder.Build()
print("systems:", ", ".join(system.get_name() for system in diagram.GetSystems()))

# %% [markdown]
# ## 4. One trial in a Context
#
# The trial's task goes on the `task` input; `plan_now` plans it into the planner's
# state before the Simulator initializes, so the arm can be put at rest where the plan's
# checked joint path starts. `Initialize` hands the plan to the trajectory source, and
# `TrialEnd` stops the simulation once the plan has been executed: any final time at or
# beyond the trial's end works.

# %%
trial = draw_trial(task, args.seed)
simulator = Simulator(diagram)
context = simulator.get_mutable_context()
diagram.GetInputPort("task").FixValue(context, trial)
scheduled = planner.plan_now(context)
print(f"planned: {' + '.join(f'{s.demo} (con_{s.con_from}->con_{s.con_to})' for s in scheduled.result.composition)}, "
      f"{scheduled.timed.duration:.2f} s")
station.set_initial_positions(context, scheduled.result.joint_path.q[0])
simulator.Initialize()
status = simulator.AdvanceTo(60.0)
print(f"stopped at t = {context.get_time():.2f} s: {status.message()}")

# %% [markdown]
# ## 5. Read the run off the Context and judge it
#
# `read_trial` gathers the joint log, each critical configuration's error when it was
# due, the closest approach to every obstacle and shell, and the trial's path
# constraints; `judge_run` applies the success criteria of `drake-lfd simulate`.

# %%
plan = planner.plan_output_port.Eval(planner.GetMyContextFromRoot(context))
run = read_trial(context, plan=plan, logger=logger, monitor=monitor, station=station)
judgement = judge_run(run)
print(f"success: {judgement.success}; worst error at a critical configuration "
      f"{1e3 * max(e.position_m for e in run.critical_errors):.3f} mm; closest approach "
      f"{1e3 * run.min_shell_distance_m:.1f} mm; largest command step {watchdog.largest_step(context):.4f} rad")

# %% [markdown]
# The joints the arm took (the log) against the joint path the trajectory source handed
# the controller (from the source's own Context: `JointPathSource.joint_path`).

# %%
import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402

t_path, q_path = source.joint_path(context)
figure, axes = plt.subplots(figsize=(8, 4))
for j in range(6):
    line, = axes.plot(run.t, run.q[:, j], label=f"q{j + 1}")
    axes.plot(t_path, q_path[:, j], "--", color=line.get_color(), linewidth=0.8)
axes.set_xlabel("t (s)")
axes.set_ylabel("joint position (rad)")
axes.set_title("measured (solid) and desired joint path (dashed)")
axes.legend(ncol=6, fontsize=8)
figure.tight_layout()
joints_png = out / "compose_joints.png"
figure.savefig(joints_png, dpi=100)
plt.close(figure)
show(joints_png)

# %% [markdown]
# ## 6. The same run as `build_pipeline`'s Diagram
#
# The watchdog passes the command through, so the run must be the pipeline's own, to
# the bit: the same joint log.

# %%
pipeline = build_pipeline(task, library=library)
reference = Simulator(pipeline)
pipeline.prepare_trial(reference.get_mutable_context(), trial)
reference.Initialize()
reference.AdvanceTo(60.0)
reference_log = pipeline.logger.FindLog(reference.get_context())
same = bool(np.array_equal(reference_log.data(), logger.FindLog(context).data()))
print(f"the same joint log as build_pipeline's Diagram: {same}")

# %% [markdown]
# ## 7. A summary a script can read

# %%
summary = {
    "short": short,
    "task": task.name,
    "composition": [[s.demo, s.con_from, s.con_to] for s in scheduled.result.composition],
    "success": judgement.success,
    "failures": list(judgement.failures),
    "largest_command_step_rad": watchdog.largest_step(context),
    "log_samples": int(len(run.t)),
    "same_as_pipeline": same,
    "wall_time_s": time.perf_counter() - started,
}
(out / "summary.json").write_text(json.dumps(summary, indent=1) + "\n")
print(f"done in {summary['wall_time_s']:.1f} s; outputs in {out}")
