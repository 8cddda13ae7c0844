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
# # Tutorial 5: from a real UR5e's log to a program the real UR5e runs
#
# An integrator's round trip, without ROS installed and without a robot:
#
# - a demonstration recorded on ROS: the UR driver publishes `/joint_states`
#   (`sensor_msgs/JointState`, the arm's joints by name, in any order, beside a gripper's)
#   and `ros2 bag record` stores them; here the tutorial writes such a bag itself, from
#   the bundled `span` demonstration's joint log, with joint names prefixed `ur5e_` and a
#   gripper joint mixed in;
# - add it to a copy of the paper's five-demonstration library (`drake-lfd library add`
#   reads ROS 1 and ROS 2 bags with the pure-Python `rosbags` library);
# - plan the assembling task with that library: the plan's joint trajectory is checked at
#   plan time (limits, singularities, clearances), so it is one the arm can run;
# - export it as a URScript program (`movej` to the start, then `servoj` at the
#   e-Series' 500 Hz), a joint-trajectory CSV and a ROS 2 `JointTrajectory`.
#
# The command-line equivalent:
#
#     drake-lfd library copy paper5 my_library
#     drake-lfd library add my_library span_bag --name span_from_bag
#     drake-lfd plan sims/assembling.yaml --library my_library --json plan.json
#     drake-lfd export plan.json --slow-down S --urscript plan.script --csv plan.csv --ros2 plan.yaml
#
# Run the script from the repository's root (headless; everything goes into `--out`):
#
#     python tutorials/05_real_robot.py --out out/05_real_robot

# %%
import argparse
import json
import shutil
import time
from pathlib import Path

import numpy as np
from rosbags.rosbag2 import StoragePlugin, Writer
from rosbags.typesys import Stores, get_typestore

import drake_lfd.cli as cli
from drake_lfd.core.resources import scenarios_directory
from drake_lfd.experiments.figures import joint_trajectories_figure
from drake_lfd.experiments.notebooks import parse_tutorial_arguments, show
from drake_lfd.io.demonstration_logs import read_rtde_csv
from drake_lfd.io.library import Library
from drake_lfd.io.trajectory_export import least_slow_down, load_plan_trajectory
from drake_lfd.robot.kinematics import UR5E_JOINT_NAMES, UR5eKinematics

NAME = "05_real_robot"
SIMS = scenarios_directory()

# %% [markdown]
# ## Settings
#
# `--out DIR` (default `tutorials_out/05_real_robot`); `--short` changes nothing here (the
# tutorial plans once and runs no closed loop), it is accepted like the other tutorials'.

# %%
parser = argparse.ArgumentParser(description="Tutorial 5: from a real UR5e's log to a program it runs")
parser.add_argument("--out", default=str(Path("tutorials_out") / NAME), metavar="DIR",
                    help="folder for the bag, the library, the plan and the exported files (created)")
parser.add_argument("--short", action="store_true", help="accepted for symmetry with the other tutorials")
args, short = parse_tutorial_arguments(parser)
out = Path(args.out)
out.mkdir(parents=True, exist_ok=True)
started = time.perf_counter()

# %% [markdown]
# ## 1. A ROS 2 bag of `/joint_states`, as a UR driver records it
#
# Each message carries the six UR joints with the driver's prefix and a gripper's joint,
# shuffled differently in every message; the stamps are the robot's clock. Nothing of
# this is special to the tutorial: a bag from `ros2 bag record /joint_states` on a real
# cell looks the same.

# %%
demo = read_rtde_csv(SIMS / "demos" / "span.csv").demonstration
typestore = get_typestore(Stores.ROS2_HUMBLE)
JointState = typestore.types["sensor_msgs/msg/JointState"]
Header = typestore.types["std_msgs/msg/Header"]
Time = typestore.types["builtin_interfaces/msg/Time"]
names = [f"ur5e_{name}" for name in UR5E_JOINT_NAMES] + ["gripper_finger_joint"]
rng = np.random.default_rng(0)
bag = out / "span_bag"
if bag.exists():
    shutil.rmtree(bag)
epoch_ns = 1_700_000_000_000_000_000
with Writer(bag, version=9, storage_plugin=StoragePlugin.MCAP) as writer:
    connection = writer.add_connection("/joint_states", "sensor_msgs/msg/JointState", typestore=typestore)
    for t, q in zip(demo.timestamps, demo.joint_positions):
        ns = epoch_ns + int(round(float(t) * 1e9))
        order = rng.permutation(len(names))
        position = np.append(q, 0.02)[order]
        message = JointState(header=Header(stamp=Time(sec=ns // 10**9, nanosec=ns % 10**9), frame_id=""),
                             name=[names[i] for i in order], position=position,
                             velocity=np.zeros(len(names)), effort=np.zeros(len(names)))
        writer.write(connection, ns, typestore.serialize_cdr(message, JointState.__msgtype__))
print(f"wrote {bag}: {len(demo.timestamps)} /joint_states messages over "
      f"{demo.timestamps[-1] - demo.timestamps[0]:.2f} s")

# %% [markdown]
# ## 2. Add it to a library
#
# `library add` finds the six UR joints by name (with or without a prefix), ignores the
# gripper, checks the log as it checks an RTDE CSV (timestamps, speeds, a motion at all)
# and stores it as the library's own joint log. `--topic` chooses another topic,
# `--start`/`--end` cut a time window.

# %%
library_dir = out / "my_library"
if library_dir.exists():
    shutil.rmtree(library_dir)
assert cli.main(["library", "copy", "paper5", str(library_dir)]) == 0
assert cli.main(["library", "add", str(library_dir), str(bag), "--name", "span_from_bag"]) == 0
library = Library.open(library_dir)
print("library:", ", ".join(library.names))

# %% [markdown]
# ## 3. Plan the assembling task
#
# With the five paper demonstrations this task asks for a demonstration (tutorial 3);
# with the bag's it plans. The plan's `joint_trajectory` is the joint path the
# controller's law produces from the chosen start, checked before it was promised.

# %%
plan_path = out / "plan.json"
code = cli.main(["plan", str(SIMS / "assembling.yaml"), "--library", str(library_dir), "--json", str(plan_path)])
plan = json.loads(plan_path.read_text())
print(f"plan exit {code}, status {plan['status']}:",
      " + ".join(f"{c['demo']} (con_{c['from']}->con_{c['to']})" for c in plan["composition"]))

# %% [markdown]
# ## 4. Export it for the robot
#
# The export checks joint positions, speeds (180 deg/s) and accelerations against the
# UR5e's limits before it writes anything. The plan is timed within those limits
# already, so the least slow-down factor that fits is 1: it runs at its own pace.

# %%
slow_down = least_slow_down(load_plan_trajectory(plan_path))
script, csv_path, ros2 = out / "plan.script", out / "plan.csv", out / "plan.yaml"
assert cli.main(["export", str(plan_path), "--slow-down", f"{slow_down:g}", "--urscript", str(script),
                 "--csv", str(csv_path), "--ros2", str(ros2)]) == 0
servoj = sum(1 for line in script.read_text().splitlines() if line.strip().startswith("servoj("))
print(f"slow-down {slow_down:g}: {script.name} with {servoj} servoj targets "
      f"({servoj * 0.002:.1f} s at 500 Hz), {csv_path.name}, {ros2.name}")
# The exported trajectory (read back from the CSV) against the joint limits.
exported = read_rtde_csv(csv_path).demonstration
kinematics = UR5eKinematics()
lower, upper = kinematics.position_limits()
joints_png = joint_trajectories_figure(out / "exported_joints.png", exported.timestamps, exported.joint_positions,
                                       lower=lower, upper=upper, velocity_limit=kinematics.velocity_limits(),
                                       title=f"Exported trajectory, slowed down {slow_down:g}x")
show(joints_png)

# %% [markdown]
# ## 5. Running it on a real UR5e, safely
#
# - Try the program in URSim (UR's offline simulator) first, with the same installation
#   (TCP, payload, mounting) as the robot.
# - On the robot, start with the speed slider of the teach pendant at 10-25 %, keep a
#   hand on the emergency stop and the cell clear; the first `movej` goes to the start
#   configuration at 0.35 rad/s: check it is the configuration you expect before the
#   `servoj` stream begins.
# - The plan was checked against the obstacles and shells of the task file, not against
#   anything else in your cell: compare the task file with the real cell.
# - A protective stop (the robot detects a collision or a limit) halts the program: find
#   why before running it again; freedrive (the teach pendant's button) moves the arm by
#   hand out of where it stopped.
# - The CSV is the same trajectory in the RTDE column layout (for your own tooling, or to
#   add it back to a library); the YAML is a `trajectory_msgs/JointTrajectory` for
#   `ur_robot_driver`'s joint trajectory controller.

# %% [markdown]
# ## 6. Summary
#
# `summary.json` is what this tutorial found (the test suite checks it).

# %%
summary = {
    "tutorial": NAME,
    "short": short,
    "messages": int(len(demo.timestamps)),
    "library": list(library.names),
    "plan_status": plan["status"],
    "composition": [[c["demo"], c["from"], c["to"]] for c in plan["composition"]],
    "slow_down": slow_down,
    "servoj_targets": servoj,
    "files": [str(p) for p in (bag, plan_path, script, csv_path, ros2, joints_png)],
    "wall_time_s": time.perf_counter() - started,
}
(out / "summary.json").write_text(json.dumps(summary, indent=1) + "\n")
print(f"done in {summary['wall_time_s']:.1f} s; outputs in {out}")
