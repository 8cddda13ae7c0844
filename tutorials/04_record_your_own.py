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
# # Tutorial 4: record your own demonstration, add it to a library, plan a new task
#
# Tutorial 3 ended with a demonstration request: with the paper's five demonstrations the
# assembling task cannot be planned, because nothing shows a 90 deg turn about the tool's
# x axis between con_2 and con_3. Here you answer that request yourself instead of using
# the bundled `span`:
#
# - turn the request (axis, angle, translation in con_2's frame) into a *guidance
#   script*: the waypoints a hand would lead the free-driven UR5e through (YAML, the same
#   format as `sims/demos/*.yaml`), with the library's tool frame `X_tool0_E`;
# - record the kinesthetic demonstration in simulation (a virtual hand pulls the
#   gravity-compensated arm; the joints are logged at the RTDE rate, 500 Hz) and save it
#   as an RTDE CSV, the file a real UR5e would give you;
# - build your own library: the five paper demonstrations plus yours;
# - plan the assembling task with it (your demonstration now covers con_2 -> con_3) and
#   run it closed loop.
#
# The command-line equivalent of the recording and library steps is:
#
#     drake-lfd record roll_carry.yaml --out roll_carry.csv
#     drake-lfd library copy paper5 my_library
#     drake-lfd library add my_library roll_carry.csv --name roll_carry
#
# The tutorial is a script, `04_record_your_own.py`, and the same cells as a notebook,
# `04_record_your_own.ipynb` (tutorials/README.md). Run the script from the repository's
# root (headless; everything it makes goes into `--out`):
#
#     python tutorials/04_record_your_own.py --out out/04_record_your_own           # also reruns tasks 1 and 2
#     python tutorials/04_record_your_own.py --out out/04_record_your_own --short   # assembling only

# %%
import argparse
import json
import shutil
import time
from pathlib import Path

import numpy as np
from pydrake.common.eigen_geometry import AngleAxis
from pydrake.math import RigidTransform, RollPitchYaw, RotationMatrix

from drake_lfd.core.resources import scenarios_directory
from drake_lfd.core.tasks import draw_trial, rigid_transform_from_euler_zyx
from drake_lfd.diagrams.kinesthetic import record_demonstration
from drake_lfd.diagrams.model_preview import write_configurations_html
from drake_lfd.experiments.figures import joint_trajectories_figure, plan_figure
from drake_lfd.experiments.notebooks import parse_tutorial_arguments, show
from drake_lfd.experiments.simulation import run_trials, trial_summary_line
from drake_lfd.io.demonstration_logs import read_rtde_csv, write_rtde_csv
from drake_lfd.io.guidance_scripts import load_guidance_script
from drake_lfd.io.library import Library, check_end_effector_frame, library_features
from drake_lfd.io.library_manifest import MANIFEST_NAME
from drake_lfd.io.plan_json import describe_uncovered
from drake_lfd.io.task_files import load_task
from drake_lfd.planning.options import PlanningOptions
from drake_lfd.planning.planner import plan_composition
from drake_lfd.robot.kinematics import UR5eKinematics
from drake_lfd.robot.scene import table_under_robot

NAME = "04_record_your_own"
DEMO_NAME = "roll_carry"

# The paper's scenarios: sims/ of a checkout, or inside the installed package.
SIMS = scenarios_directory()

# Where the demonstration starts: E at 0.15 m, 0.45 m, 0.35 m from the robot base, the
# cup-up orientation of the paper scenarios (E's x up, the flange pointing down). Any
# comfortable pose in reach will do, because a feature is the motion *relative to* the
# demonstration's own end (Eq. 12): where you show it does not matter, only how it moves.
START_P = (0.15, 0.45, 0.35)
START_EULER_ZYX = (0.0, -np.pi / 2, 0.0)
# How far the hand carries the tool: mapping scales a demonstration onto its span
# (Eq. 23), so a short, comfortable motion serves the task's 57 cm.
CARRY_LENGTH_M = 0.12


# %% [markdown]
# ## Settings
#
# A script takes them from its command line: `--out DIR` (default
# `tutorials_out/04_record_your_own` in the current directory) and `--short` (only the
# assembling task closed loop; the full run also reruns tutorials 1 and 2's tasks). A
# notebook has no command line: it uses the defaults (change the `default=` values below to change them), and the environment
# variable `DRAKE_LFD_TUTORIAL_SHORT=1` selects the short run for both.

# %%
parser = argparse.ArgumentParser(description="Tutorial 4: record your own demonstration")
parser.add_argument("--out", default=str(Path("tutorials_out") / NAME), metavar="DIR",
                    help="folder for the script, the recording, the library and the figures (created)")
parser.add_argument("--short", action="store_true",
                    help="only the assembling task closed loop (the full run also reruns tasks 1 and 2)")
args, short = parse_tutorial_arguments(parser)
out = Path(args.out)
out.mkdir(parents=True, exist_ok=True)
started = time.perf_counter()
print(f"{'short' if short else 'full'} run, outputs in {out}")

# %% [markdown]
# ## 1. The request

# %%
task = load_task(SIMS / "assembling.yaml")
concrete = draw_trial(task, 0)
table = table_under_robot(task.X_WB)
floor_z = float(table.centre[2] + table.size[2] / 2)
paper5 = Library.open("paper5")
# The paper's planning: Eq. 31's cost, in SE(3) alone (no joint-space check).
paper = PlanningOptions.paper_baseline()
request = plan_composition(concrete, library_features(paper5), paper, floor_z=floor_z)
print(f"assembling with {paper5.label}: {request.status}")
for line in describe_uncovered(request):
    print(f"  demonstration needed: {line}")
if request.planned or len(request.uncovered) != 1:
    raise SystemExit("expected exactly one uncovered segment (con_2 -> con_3) with paper5")
(segment,) = request.uncovered

# %% [markdown]
# ## 2. A guidance script for it
#
# The script says where the hand leads the tool: a start pose and an end pose 3 s later,
# joined by a screw motion with a minimum-jerk pace, plus the hand's wobble. We compute
# the end pose from the request, so the motion is exactly the one asked for; writing the
# numbers by hand works as well (see `sims/demos/span.yaml`). The demonstration must use
# the library's tool frame; it is checked before recording.

# %%
def euler_zyx_from_rotation(R: RotationMatrix) -> list[float]:
    """[yaw, pitch, roll] with R = Rz(yaw) Ry(pitch) Rx(roll), as task files write it."""
    rpy = RollPitchYaw(R)
    return [rpy.yaw_angle(), rpy.pitch_angle(), rpy.roll_angle()]


def numbers(values) -> str:
    return "[" + ", ".join(f"{float(v):.9g}" for v in values) + "]"


def guidance_script_text(request, X_WE_start: RigidTransform, length_m: float) -> str:
    """A guidance script showing the requested relative motion, scaled to ``length_m``.

    ``request`` is an uncovered segment: turn ``angle_rad`` about the body ``axis`` while
    translating ``translation_m``, both in con_from's frame, i.e. in the frame E starts
    in. So the end pose is the start pose composed with that relative motion.
    """
    direction = np.asarray(request.translation_m) / np.linalg.norm(request.translation_m)
    X_start_end = RigidTransform(RotationMatrix(AngleAxis(request.angle_rad, np.asarray(request.axis))),
                                 direction * length_m)
    X_WE_end = X_WE_start @ X_start_end
    start = (X_WE_start.translation(), euler_zyx_from_rotation(X_WE_start.rotation()))
    end = (X_WE_end.translation(), euler_zyx_from_rotation(X_WE_end.rotation()))
    return f"""\
# A demonstration for the assembling task's con_{request.con_from} -> con_{request.con_to}, written by
# tutorials/04_record_your_own.py from the demonstration request: turn
# {np.degrees(request.angle_rad):.0f} deg about the tool's body axis {numbers(np.round(request.axis, 3))} while carrying
# the tool {100 * length_m:.0f} cm along body direction {numbers(np.round(direction, 3))}.
name: {DEMO_NAME}
description: carry the screw {100 * length_m:.0f} cm sideways while rolling it +90 deg about the tool x axis
# The tool frame of the library this demonstration joins (paper5, and every paper
# scenario; see sims/transferring.yaml). A different X_tool0_E would make the feature
# describe a different frame's motion: the library refuses such a mix.
X_tool0_E: {{p: [0, 0, 0.2], euler_zyx: [0, pi/2, 0]}}
# Poses of E; the robot base is at the origin (X_WB defaults to identity). At pitch
# -90 deg Euler angles are in gimbal lock: yaw and roll are not unique there, and any
# pair giving the same rotation is the same pose.
waypoints:
  - {{t: 0.0, p: {numbers(start[0])}, euler_zyx: {numbers(start[1])}}}
  - {{t: 3.0, p: {numbers(end[0])}, euler_zyx: {numbers(end[1])}}}
hold_s: 0.5
# A human hand: about a millimetre and half a degree of wobble, +-5 % uneven pace.
hand_noise: {{position_m: 0.001, rotation_deg: 0.5, speed_variation: 0.05, frequency_hz: [0.2, 0.8]}}
seed: 11
sample_rate_hz: 500
"""


X_WE_start = rigid_transform_from_euler_zyx(np.array(START_P), np.array(START_EULER_ZYX))
script_path = out / f"{DEMO_NAME}.yaml"
script_path.write_text(guidance_script_text(segment, X_WE_start, CARRY_LENGTH_M))
script = load_guidance_script(script_path)
check_end_effector_frame(paper5, script.X_tool0_E, file=script_path)
print(f"wrote {script_path}: {len(script.waypoints)} waypoints, {script.duration_s:.1f} s")
print(script_path.read_text())

# %% [markdown]
# ## 3. Record it
#
# The arm starts at rest at the inverse-kinematics solution of the first waypoint; the
# virtual hand's spring pulls E along the guidance; nothing commands the joints. The
# recorder raises a clear error if the arm could not follow (out of reach, a joint limit
# or a singularity on the way): then move `START_P`.
#
# The RTDE CSV is what a real UR5e gives you (`timestamp`, `actual_q_0` .. `actual_q_5`).
# From here on we use the file, as you would with a real recording.

# %%
recorded = record_demonstration(script)
demonstration = recorded.demonstration
print(f"recorded {DEMO_NAME}: {demonstration.num_samples} samples over {demonstration.duration_s:.2f} s "
      f"(simulated in {recorded.wall_time_s:.1f} s); E within {1000 * recorded.max_position_error_m:.1f} mm / "
      f"{np.degrees(recorded.max_rotation_error_rad):.1f} deg of the hand, ended "
      f"{1000 * recorded.final_position_error_m:.2f} mm from the last waypoint")
csv_path = out / f"{DEMO_NAME}.csv"
write_rtde_csv(demonstration, csv_path)
from_file, warnings = read_rtde_csv(csv_path, name=DEMO_NAME, description=script.description)
for warning in warnings:
    print(f"  warning: {warning}")
print(f"wrote {csv_path}")

# %% [markdown]
# A look at the demonstration: its joints over time with each joint's position limits,
# and a 3D replay (30 frames/s) to open in a browser.

# %%
kinematics = UR5eKinematics(X_WB=script.X_WB, X_tool0_E=script.X_tool0_E)
lower, upper = kinematics.position_limits()
demo_joints_png = joint_trajectories_figure(
    out / f"{DEMO_NAME}_joints.png", from_file.timestamps, from_file.joint_positions, lower=lower,
    upper=upper, velocity_limit=kinematics.velocity_limits(), title=f"demonstration {DEMO_NAME}: joints",
)
frames = np.arange(0.0, from_file.duration_s, 1 / 30)
keyframes = np.array([np.interp(frames, from_file.timestamps, from_file.joint_positions[:, j])
                      for j in range(6)]).T
demo_html = write_configurations_html(out / f"{DEMO_NAME}_demonstration.html", keyframes,
                                      seconds_per_move=1 / 30, X_WB=script.X_WB)
print(f"wrote {demo_joints_png} and {demo_html}")
show(demo_joints_png)

# %% [markdown]
# ## 4. Your library
#
# Bundled libraries are read-only, so create one in the output folder with the same tool
# frame and copy paper5's demonstrations into it (their joint logs), then add yours.
# Features are computed when a demonstration is added and cached beside it. A previous
# run's library in the same folder is removed first, so the tutorial can run again.

# %%
library_path = out / "my_library"
if (library_path / MANIFEST_NAME).is_file():  # a previous run's library: start afresh
    shutil.rmtree(library_path)
library = Library.create(library_path, X_tool0_E=paper5.X_tool0_E)
for name in paper5.names:
    library.add(paper5.demonstration(name), name, paper5.entry(name).description)
library.add(from_file, DEMO_NAME, script.description)
print(f"created {library.label}: {', '.join(library.names)}")

# %% [markdown]
# ## 5. Plan the assembling task with it

# %%
check_end_effector_frame(library, task.X_tool0_E, file=task.file)
features = library_features(library)
result = plan_composition(concrete, features, paper, floor_z=floor_z)
print(f"assembling with your library: {result.status}")
if not result.planned:
    for line in describe_uncovered(result):
        print(f"  still uncovered: {line}")
    raise SystemExit("your demonstration did not cover the request; see above")
for step in result.composition:
    print(f"  {step.demo:10s} con_{step.con_from} -> con_{step.con_to}  cost {step.cost:.4f}")
print(f"  max correction {1000 * result.max_correction_position_m:.1f} mm, "
      f"{np.degrees(result.max_correction_rotation_rad):.2f} deg")
plan_png = plan_figure(out / "assembling_plan.png", result.timed.poses, result.timed.critical_indices,
                       title="assembling with " + "+".join(s.demo for s in result.composition))
print(f"wrote {plan_png}")
show(plan_png)

# %% [markdown]
# ## 6. Closed loop
#
# The assembling task has no variables and the simulation is deterministic, so one trial
# says it all. The full run also reruns tutorials 1 and 2's tasks with your library: a
# new demonstration adds options without taking any away.

# %%
task_names = ["assembling"] if short else ["assembling", "transferring", "filling_pouring"]
results = {}
recording = out / "assembling_trial1.html"
for name in task_names:
    scenario = task if name == "assembling" else load_task(SIMS / f"{name}.yaml")
    outcomes, wall = run_trials(scenario, features, trials=1, seed=0, options=PlanningOptions(cost="paper"),
                                record_html=recording if name == "assembling" else None)
    (outcome,) = outcomes
    print(f"{name}: {trial_summary_line(outcome)} ({wall:.1f} s)")
    for reason in outcome.failures:
        print(f"  {name} failed: {reason}")
    results[name] = {"success": outcome.success, "failures": outcome.failures,
                     "composition": outcome.composition_label}
print(f"wrote {recording}")

# %% [markdown]
# ## 7. Summary
#
# `summary.json` is what this tutorial found (the test suite checks it).

# %%
summary = {
    "tutorial": NAME,
    "short": short,
    "request": [(u.con_from, u.con_to) for u in request.uncovered],
    "demonstration": {"name": DEMO_NAME, "samples": demonstration.num_samples,
                      "max_position_error_m": recorded.max_position_error_m},
    "library": str(library.path),
    "library_demos": list(library.names),
    "plan_status": result.status,
    "composition": [(s.demo, s.con_from, s.con_to) for s in result.composition],
    "trials": results,
    "files": [str(p) for p in (script_path, csv_path, demo_joints_png, demo_html, plan_png, recording)],
    "wall_time_s": time.perf_counter() - started,
}
(out / "summary.json").write_text(json.dumps(summary, indent=1) + "\n")
print(f"done in {summary['wall_time_s']:.1f} s; outputs in {out}")
