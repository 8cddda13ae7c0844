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
# # Tutorial 3: assembling, and what to do when the library cannot cover a task (Table 9)
#
# What you learn here:
#
# - what happens when no composition of the library's demonstrations covers a task: the
#   planner does not guess, it returns a *demonstration request* naming every uncovered
#   segment con_j -> con_(j+1) and the relative motion a new demonstration must show
#   (with `paper5`, the assembling task needs a 90 deg turn about the tool's x axis
#   between con_2 and con_3, which none of the five demonstrations has);
# - how a library with that demonstration (`paper6`: the five plus `span`, picking up a
#   spanner) plans the task, using `span` for con_2 -> con_3;
# - how to retrain the Q-policy after adding a demonstration, starting from the old table
#   (warm start) instead of from scratch, and how to read the training curve;
# - how the retrained policy's plans run closed loop on the UR5e.
#
# The tutorial is a script, `03_assembling.py`, and the same cells as a notebook,
# `03_assembling.ipynb` (tutorials/README.md). Run the script from the repository's root
# (headless; it writes PNG figures, a Meshcat HTML recording, the request and policies as
# JSON, and summaries):
#
#     python tutorials/03_assembling.py --out out/03_assembling           # 5 trials
#     python tutorials/03_assembling.py --out out/03_assembling --short   # 1 trial

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
from drake_lfd.io.plan_json import describe_uncovered, plan_json
from drake_lfd.io.policy_files import save_policy
from drake_lfd.io.task_files import load_task
from drake_lfd.planning.options import PlanningOptions
from drake_lfd.planning.planner import build_problem, plan_composition
from drake_lfd.planning.q_learning import episodes_to_steady
from drake_lfd.planning.training import train_on_random_tasks
from drake_lfd.robot.kinematics import UR5eKinematics
from drake_lfd.robot.scene import table_under_robot

NAME = "03_assembling"

# The paper's scenarios: sims/ of a checkout, or inside the installed package.
SIMS = scenarios_directory()


def label(result) -> str:
    return "+".join(step.demo for step in result.composition)


# %% [markdown]
# ## Settings
#
# A script takes them from its command line: `--out DIR` (default
# `tutorials_out/03_assembling` in the current directory), `--short` (one closed-loop
# trial instead of five), `--trials N`, `--seed S`. A notebook has no command line: it
# uses the defaults (change the `default=` values below to change them), and the environment variable
# `DRAKE_LFD_TUTORIAL_SHORT=1` selects the short run for both.
#
# The paper trains on 20 random tasks for 100 episodes. That takes well under a second
# here, so the short run keeps it (fewer episodes would leave the table half learned).

# %%
parser = argparse.ArgumentParser(description="Tutorial 3: assembling, and a demonstration request")
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
# ## 1. Plan with the five demonstrations
#
# The assembling task has no variables: every trial is the same four configurations.

# %%
task = load_task(SIMS / "assembling.yaml")
concrete = draw_trial(task, args.seed)
table = table_under_robot(task.X_WB)
floor_z = float(table.centre[2] + table.size[2] / 2)
paper5 = Library.open("paper5")
check_end_effector_frame(paper5, task.X_tool0_E, file=task.file)
features5 = library_features(paper5)
print(f"task {task.name}: {task.description}")
# The paper's planning: Eq. 31's cost, in SE(3) alone (no joint-space check).
paper = PlanningOptions.paper_baseline(planner="exact")
request = plan_composition(concrete, features5, paper, floor_z=floor_z)
print(f"with {paper5.label} ({', '.join(paper5.names)}): {request.status}")

# %% [markdown]
# ## 2. Read the demonstration request
#
# Each uncovered segment comes with the relative motion D_from* (x) D_to expressed in
# con_from's frame: the axis and angle of the turn and the translation. That is what the
# person at the robot must demonstrate (its size does not matter: mapping scales a
# demonstration onto its span, Eq. 23). `drake-lfd plan` prints the same and exits 3.
#
# The Q-planner reaches the same verdict: with no composition there is nothing to walk.

# %%
for line in describe_uncovered(request):
    print(f"  demonstration needed: {line}")
request_json = out / "assembling_request.json"
request_json.write_text(json.dumps(plan_json(request), indent=1) + "\n")
print(f"wrote {request_json}")

training5 = train_on_random_tasks(features5, num_tasks=num_tasks, episodes=episodes, seed=args.seed)
by_q5 = plan_composition(concrete, features5, paper.replace(planner="q"), policy=training5.policy, seed=args.seed,
                         floor_z=floor_z)
print(f"the Q-planner with a policy trained on paper5 ({num_tasks} random tasks x {episodes} episodes): "
      f"{by_q5.status}")

# %% [markdown]
# ## 3. Add the demonstration: paper6
#
# `paper6` is `paper5` plus `span`, a simulated kinesthetic demonstration of picking up a
# spanner: +90 deg about the tool's x axis while lifting it (`sims/demos/span.yaml`).
# Tutorial 4 records a demonstration like it yourself.

# %%
paper6 = Library.open("paper6")
check_end_effector_frame(paper6, task.X_tool0_E, file=task.file)
features6 = library_features(paper6)
new_demos = [name for name in paper6.names if name not in paper5.names]
for name in new_demos:
    print(f"{paper6.label} adds {name!r}: {paper6.entry(name).description}")

# %% [markdown]
# ## 4. Retrain, starting from the old table
#
# The table's keys do not depend on the library, so the old values are a fair start:
# `warm_start` copies them and Q-learning goes on with the new demonstration among the
# actions. The task that asked for the demonstration joins the random training tasks
# (`extra_problems`), so the table learns to complete it (the paper's Fig. 10c). For
# comparison, the same training from an empty table (cold start). The curve is the
# greedy policy's reward on the assembling task after each episode: it rises from the
# dead-end penalty to minus the composition's cost once the table has learned it.

# %%
extra = [build_problem(concrete, features6)]
warm = train_on_random_tasks(features6, num_tasks=num_tasks, episodes=episodes, seed=args.seed,
                             warm_start=training5.policy, extra_problems=extra)
cold = train_on_random_tasks(features6, num_tasks=num_tasks, episodes=episodes, seed=args.seed,
                             extra_problems=extra)
warm_curve, cold_curve = warm.greedy_rewards[:, -1], cold.greedy_rewards[:, -1]
steady_warm, steady_cold = episodes_to_steady(warm_curve), episodes_to_steady(cold_curve)
print(f"retrained on paper6 ({num_tasks} random tasks + assembling, {episodes} episodes) in "
      f"{warm.wall_time_s:.2f} s: the greedy reward on assembling is steady after {steady_warm} episodes "
      f"(warm start) vs {steady_cold} (cold start); final {warm_curve[-1]:.4f} (warm) / {cold_curve[-1]:.4f} (cold)")
policy_path = out / "policy_paper6.json"
save_policy(warm.policy, policy_path)
curve_png = training_curve_figure(out / "assembling_retraining.png", warm_curve, steady_episode=steady_warm,
                                  exploring=warm.rewards[:, -1],
                                  title="Assembling after the new demonstration (Fig. 10c)")
print(f"wrote {policy_path} and {curve_png}")
show(curve_png)

# %% [markdown]
# ## 5. Plan with paper6
#
# Both planners now find a composition; `span` covers con_2 -> con_3 and the screwing
# demonstrations take the screw out of hole 1 and fasten it in hole 2.

# %%
exact6 = plan_composition(concrete, features6, paper, floor_z=floor_z)
by_q6 = plan_composition(concrete, features6, paper.replace(planner="q"), policy=warm.policy, seed=args.seed,
                         floor_z=floor_z)
print(f"with {paper6.label}: exact {exact6.status} {label(exact6)} (cost {exact6.total_cost:.4f}); "
      f"q {by_q6.status} {label(by_q6)} (cost {by_q6.total_cost:.4f}, fallback {by_q6.fallback})")
if not by_q6.planned:
    raise SystemExit("the assembling task should plan with paper6")
for step in by_q6.composition:
    print(f"  {step.demo:10s} con_{step.con_from} -> con_{step.con_to}  cost {step.cost:.4f}")
print(f"  max correction {1000 * by_q6.max_correction_position_m:.1f} mm, "
      f"{np.degrees(by_q6.max_correction_rotation_rad):.2f} deg")
plan_png = plan_figure(out / "assembling_plan.png", by_q6.timed.poses, by_q6.timed.critical_indices,
                       title=f"assembling with paper6: {label(by_q6)}")
print(f"wrote {plan_png}")
show(plan_png)

# %% [markdown]
# ## 6. Closed-loop trials
#
# The assembling task has no variables, so every trial is the same task (the seeds only
# seed the Q-planner's refinement) and the simulation is deterministic: expect the same
# verdict every time. Tutorials 1 and 2 draw different positions per trial.

# %%
recording = out / "assembling_trial1.html"


def progress(done, total, outcome):
    print(f"  [{done}/{total}] {trial_summary_line(outcome)}")


print(f"running {num_trials} closed-loop trial(s) with paper6 and the retrained Q-policy ...")
outcomes, wall = run_trials(task, features6, trials=num_trials, seed=args.seed,
                            options=PlanningOptions(planner="q", cost="paper"),
                            policy=warm.policy, record_html=recording, progress=progress)
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
        out / "assembling_joints.png", ran.run.t, ran.run.q, lower=lower, upper=upper,
        velocity_limit=kinematics.velocity_limits(), title=f"assembling, trial {ran.trial}: measured joints",
    )
    print(f"wrote {joints_png}")
    show(joints_png)

# %% [markdown]
# ## 7. Summaries
#
# `assembling_trials.json` is the document `drake-lfd simulate --json` writes;
# `summary.json` is what this tutorial found (the test suite checks it).

# %%
document = simulate_json(task, outcomes, wall)
(out / "assembling_trials.json").write_text(json.dumps(document, indent=1) + "\n")
summary = {
    "tutorial": NAME,
    "short": short,
    "paper5_status": request.status,
    "uncovered": [(u.con_from, u.con_to, [float(a) for a in u.axis], float(u.angle_rad))
                  for u in request.uncovered],
    "paper5_q_status": by_q5.status,
    "retraining": {"tasks": num_tasks + len(extra), "episodes": episodes,
                   "episodes_to_steady_warm": steady_warm, "episodes_to_steady_cold": steady_cold,
                   "wall_time_s": warm.wall_time_s},
    "paper6_status": by_q6.status,
    "composition": [(s.demo, s.con_from, s.con_to) for s in by_q6.composition],
    "exact_composition": [(s.demo, s.con_from, s.con_to) for s in exact6.composition],
    "trials": num_trials,
    "success_count": successes,
    "successes": [o.success for o in outcomes],
    "failures": {o.trial: o.failures for o in outcomes if o.failures},
    "compositions": composition_counts(outcomes),
    "files": [str(p) for p in (request_json, policy_path, curve_png, plan_png, recording, joints_png,
                               out / "assembling_trials.json") if p],
    "wall_time_s": time.perf_counter() - started,
}
(out / "summary.json").write_text(json.dumps(summary, indent=1) + "\n")
print(f"done in {summary['wall_time_s']:.1f} s; outputs in {out}")
