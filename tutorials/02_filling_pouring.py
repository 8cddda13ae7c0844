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
# # Tutorial 2: fill a cup, carry it upright, pour it out (Yu & Chang, Table 8)
#
# What you learn here:
#
# - how a task leaves an angle free: the roll gamma of con_2 .. con_4 may be anything in
#   [-pi, pi], and the planner picks it (on a 15 deg grid) together with the composition;
# - how the composition strings different demonstrations together (filling, then
#   stacking for the carrying, then a screwing motion that turns the cup over to pour);
# - how to train a Q-policy on random tasks (Algorithm 1, Section 6.2) and plan with it
#   (`planner="q"`, Algorithm 2), and how its plans compare with the exact planner's;
# - how to run closed-loop trials with the Q-planner.
#
# The tutorial is a script, `02_filling_pouring.py`, and the same cells as a notebook,
# `02_filling_pouring.ipynb` (tutorials/README.md). Run the script from the repository's
# root (headless; it writes PNG figures, a Meshcat HTML recording, the policy and JSON
# summaries):
#
#     python tutorials/02_filling_pouring.py --out out/02_filling_pouring           # 5 trials
#     python tutorials/02_filling_pouring.py --out out/02_filling_pouring --short   # 1 trial

# %%
import argparse
import json
import time
from pathlib import Path

import numpy as np

from drake_lfd.core.resources import scenarios_directory
from drake_lfd.core.tasks import draw_trial
from drake_lfd.experiments.figures import joint_trajectories_figure, plan_figure, training_curve_figure
from drake_lfd.experiments.notebooks import parse_tutorial_arguments, show
from drake_lfd.experiments.simulation import composition_counts, run_trials, simulate_json, trial_summary_line
from drake_lfd.io.library import Library, check_end_effector_frame, library_features
from drake_lfd.io.policy_files import save_policy
from drake_lfd.io.task_files import load_task
from drake_lfd.planning.options import PlanningOptions
from drake_lfd.planning.planner import plan_composition
from drake_lfd.planning.q_learning import episodes_to_steady
from drake_lfd.planning.training import train_on_random_tasks
from drake_lfd.robot.kinematics import UR5eKinematics
from drake_lfd.robot.scene import table_under_robot

NAME = "02_filling_pouring"

# The paper's scenarios: sims/ of a checkout, or inside the installed package.
SIMS = scenarios_directory()


# %% [markdown]
# ## Settings
#
# A script takes them from its command line: `--out DIR` (default
# `tutorials_out/02_filling_pouring` in the current directory), `--short` (one
# closed-loop trial instead of five), `--trials N`, `--seed S`. A notebook has no command
# line: it uses the defaults (change the `default=` values below to change them), and the environment variable
# `DRAKE_LFD_TUTORIAL_SHORT=1` selects the short run for both.
#
# The paper trains on 20 random tasks for 100 episodes. That takes well under a second
# here, so the short run keeps it (fewer episodes would leave the table half learned).

# %%
parser = argparse.ArgumentParser(description="Tutorial 2: fill a cup, carry it upright, pour it out")
parser.add_argument("--out", default=str(Path("tutorials_out") / NAME), metavar="DIR",
                    help="folder for the figures, the recording and the summary (created)")
parser.add_argument("--short", action="store_true", help="one closed-loop trial instead of five")
parser.add_argument("--trials", type=int, default=None, metavar="N", help="override the number of trials")
parser.add_argument("--seed", type=int, default=0, metavar="S", help="trial i uses seed S + i - 1")
args, short = parse_tutorial_arguments(parser)
out = Path(args.out)
out.mkdir(parents=True, exist_ok=True)
num_trials = args.trials or (1 if short else 5)
num_tasks, episodes = 20, 100
started = time.perf_counter()
print(f"{'short' if short else 'full'} run: {num_trials} closed-loop trial(s), seed {args.seed}, outputs in {out}")

# %% [markdown]
# ## 1. Task and library
#
# Cup 2's position (x, y) is drawn per trial; con_2 .. con_4 keep the cup upright
# (pitch -pi/2) but leave the roll gamma free: `euler_zyx: [0, -pi/2, [-pi, pi]]`.

# %%
task = load_task(SIMS / "filling_pouring.yaml")
library = Library.open("paper5")
check_end_effector_frame(library, task.X_tool0_E, file=task.file)
features = library_features(library)
print(f"task {task.name}: {task.description}")
print(f"library {library.label}: {', '.join(library.names)}")

# %% [markdown]
# ## 2. Plan one trial exactly, and look at the free angle
#
# The exact planner is a backward dynamic programme over (configuration, angle values):
# it returns the cheapest composition and the gamma values that go with it. We plan with
# the table top as the floor, as the closed-loop trials below do.

# %%
concrete = draw_trial(task, args.seed)
table = table_under_robot(task.X_WB)
floor_z = float(table.centre[2] + table.size[2] / 2)
# The paper's planning: Eq. 31's cost, in SE(3) alone (no joint-space check).
paper = PlanningOptions.paper_baseline(planner="exact")
exact = plan_composition(concrete, features, paper, seed=args.seed, floor_z=floor_z)
print(f"trial seed {args.seed}: cup 2 at x = {concrete.variable_values['x']:.3f}, "
      f"y = {concrete.variable_values['y']:.3f} m -> {exact.status}")
if not exact.planned:
    raise SystemExit("the filling/pouring task should plan with paper5")
gammas = np.degrees(exact.euler_zyx[1:4, 2])
print("  chosen gamma (roll) of con_2, con_3, con_4: " + ", ".join(f"{g:.0f} deg" for g in gammas))
for step in exact.composition:
    print(f"  {step.demo:10s} con_{step.con_from} -> con_{step.con_to}  cost {step.cost:.4f}")
print(f"  total cost {exact.total_cost:.4f}; max correction {1000 * exact.max_correction_position_m:.1f} mm, "
      f"{np.degrees(exact.max_correction_rotation_rad):.2f} deg")
plan_png = plan_figure(
    out / "filling_pouring_plan.png", exact.timed.poses, exact.timed.critical_indices,
    title=f"filling/pouring, seed {args.seed}: " + "+".join(s.demo for s in exact.composition),
)
print(f"wrote {plan_png}")
show(plan_png)

# %% [markdown]
# ## 3. Train a Q-policy
#
# Algorithm 1 learns on random tasks (Section 6.2), not on this one, so the same table
# plans tasks it has never seen: its states are task-independent keys (segments left,
# the relative rotation and direction to the next configuration). The learning curve
# (the paper's Fig. 7) is the greedy policy's accumulated reward after each episode,
# averaged over the training tasks; the grey line is the exploring episodes themselves.
# The paper's random tasks are rarely covered by five demonstrations, so most of what
# the table learns from them is which actions lead to a dead end (the penalty, -10
# scaled by the part of the task left).

# %%
training = train_on_random_tasks(features, num_tasks=num_tasks, episodes=episodes, seed=args.seed)
steady = episodes_to_steady(training.greedy_curve)
print(f"trained on {num_tasks} random tasks x {episodes} episodes in {training.wall_time_s:.2f} s; "
      f"greedy reward steady after {steady} episodes (last 10: {training.greedy_curve[-10:].mean():.2f}); "
      f"{len(training.policy.values)} table entries")
policy_path = out / "policy.json"
save_policy(training.policy, policy_path)
curve_png = training_curve_figure(out / "filling_pouring_training.png", training.greedy_curve,
                                  steady_episode=steady, exploring=training.curve,
                                  title=f"Q-learning on {num_tasks} random tasks (Fig. 7)")
print(f"wrote {policy_path} and {curve_png}")
show(curve_png)

# %% [markdown]
# ## 4. Plan with the policy, compare with the exact planner
#
# The Q-planner first refines the table on the task's own states (`refine_episodes`,
# 100 by default), then walks greedily (Algorithm 2). If the walk dead-ends while a
# composition exists it falls back on the exact planner and says so (`fallback`). The
# exact planner's cost is the optimum, so the ratio says how good the walk was.

# %%
comparison = []
for seed in range(args.seed, args.seed + max(num_trials, 2)):
    trial = draw_trial(task, seed)
    by_q = plan_composition(trial, features, paper.replace(planner="q"), policy=training.policy, seed=seed,
                            floor_z=floor_z)
    by_exact = plan_composition(trial, features, paper, seed=seed, floor_z=floor_z)
    label_q = "+".join(s.demo for s in by_q.composition)
    excess = 100.0 * (by_q.total_cost / by_exact.total_cost - 1.0)
    print(f"  seed {seed}: q {label_q} cost {by_q.total_cost:.4f} (greedy completed: "
          f"{by_q.greedy_completed}, fallback: {by_q.fallback}); exact cost {by_exact.total_cost:.4f} "
          f"-> q is {excess:+.1f} % of the optimum")
    comparison.append({"seed": seed, "q_composition": label_q, "q_cost": by_q.total_cost,
                       "exact_composition": "+".join(s.demo for s in by_exact.composition),
                       "exact_cost": by_exact.total_cost, "q_excess_percent": excess,
                       "fallback": by_q.fallback})

# %% [markdown]
# ## 5. Closed-loop trials with the Q-planner
#
# Judged as in tutorial 1: every con within 5 mm / 2 deg, joints within limits, and no
# contact with the table. The first trial is recorded; its joints are plotted with each
# joint's position limits.

# %%
recording = out / "filling_pouring_trial1.html"


def progress(done, total, outcome):
    print(f"  [{done}/{total}] {trial_summary_line(outcome)}")


print(f"running {num_trials} closed-loop trial(s) with the Q-planner ...")
outcomes, wall = run_trials(task, features, trials=num_trials, seed=args.seed,
                            options=PlanningOptions(planner="q", cost="paper"),
                            policy=training.policy, record_html=recording, progress=progress)
successes = sum(o.success for o in outcomes)
print(f"{successes}/{num_trials} trials succeeded in {wall:.1f} s; compositions {composition_counts(outcomes)}")
for outcome in outcomes:
    for reason in outcome.failures:
        print(f"  trial {outcome.trial} failed: {reason}")
print(f"wrote {recording}")

ran = next((o for o in outcomes if o.run is not None), None)
joints_png = None
if ran is not None:
    kinematics = UR5eKinematics(X_WB=task.X_WB, X_tool0_E=task.X_tool0_E)
    lower, upper = kinematics.position_limits()
    joints_png = joint_trajectories_figure(
        out / "filling_pouring_joints.png", ran.run.t, ran.run.q, lower=lower, upper=upper,
        velocity_limit=kinematics.velocity_limits(), title=f"filling/pouring, trial {ran.trial}: measured joints",
    )
    print(f"wrote {joints_png}")
    show(joints_png)

# %% [markdown]
# ## 6. Summaries
#
# `filling_pouring_trials.json` is the document `drake-lfd simulate --json` writes;
# `summary.json` is what this tutorial found (the test suite checks it).

# %%
document = simulate_json(task, outcomes, wall)
(out / "filling_pouring_trials.json").write_text(json.dumps(document, indent=1) + "\n")
summary = {
    "tutorial": NAME,
    "short": short,
    "plan_status": exact.status,
    "composition": [(s.demo, s.con_from, s.con_to) for s in exact.composition],
    "gamma_deg": [float(g) for g in gammas],
    "training": {"tasks": num_tasks, "episodes": episodes,
                 "episodes_to_steady": steady, "wall_time_s": training.wall_time_s},
    "q_vs_exact": comparison,
    "trials": num_trials,
    "success_count": successes,
    "successes": [o.success for o in outcomes],
    "failures": {o.trial: o.failures for o in outcomes if o.failures},
    "compositions": composition_counts(outcomes),
    "files": [str(p) for p in (plan_png, curve_png, policy_path, recording, joints_png,
                               out / "filling_pouring_trials.json") if p],
    "wall_time_s": time.perf_counter() - started,
}
(out / "summary.json").write_text(json.dumps(summary, indent=1) + "\n")
print(f"done in {summary['wall_time_s']:.1f} s; outputs in {out}")
