"""People walking through the paper's cells: speed and separation monitoring against a
safety scanner's stop-only policy.

Run: ``python benchmarks/bench_collaboration.py [--trials-per-task 17] [--seed 0]``.
The paper's three tasks (``sims/transferring.yaml`` and ``sims/filling_pouring.yaml``
with ``paper5``, ``sims/assembling.yaml`` with ``paper6``, which holds the demonstration
that task asks for), each trial with one person on a seeded random path
(:func:`random_person`): from a far point in front of the cell (2.5-3.5 m out) the
person walks at 0.6-1.6 m/s (at most ISO 13855's 1.6 m/s) to a point 0.3-0.9 m in front
of the task's work area, stays there 0-2.5 s (or walks straight through, one trial in
four), and walks away to another far point. Every trial runs twice on the same plan and
the same person:

- ``speed_and_separation``: ISO/TS 15066 speed and separation monitoring with the
  documented defaults (``collaboration: {}``);
- ``stop_only``: stop whenever anyone is within a fixed radius, resume when clear. The
  radius is :func:`~drake_lfd.core.people.stop_only_radius_m`: the distance at which
  speed and separation monitoring starts to slow a robot point moving at the robot's top
  speed (1.5 m/s, UR's default tool speed limit), i.e. ``S_p`` at that speed plus the
  person's approach while the robot stops. Built from the same terms, it is as safe as
  speed and separation monitoring by construction, and the benchmark measures it too
  (violations must be 0 for both).

Prints, per policy: samples where the robot moved toward a person closer than ``S_p``
(violations; must be 0), trials with any, task success, the cycle time lost to people
(run time minus the plan's nominal time; total, mean, worst), time spent slowed and
protective stops; then whether speed and separation monitoring lost less cycle time.
With ``--json OUT`` the per-trial figures are written too.
"""

from __future__ import annotations

import argparse
import dataclasses
import json
import math
import time

import numpy as np

from drake_lfd.core.people import (
    STOP_ONLY_POLICY, CollaborationParameters, Person, ScriptedPath, Waypoint, stop_only_radius_m,
)
from drake_lfd.core.resources import scenarios_directory
from drake_lfd.core.tasks import draw_trial
from drake_lfd.core.timing import TimingLimits
from drake_lfd.experiments.simulation import TrialRunner
from drake_lfd.io.library import Library, library_features
from drake_lfd.io.task_files import load_task

TASKS = (("transferring", "paper5"), ("filling_pouring", "paper5"), ("assembling", "paper6"))
CONTROL_PERIOD_S = 0.01


def random_person(rng: np.random.Generator, work_xy: np.ndarray, front: np.ndarray, *, name: str = "walker") -> Person:
    """A person on a random path in front of the cell (module docstring): ``work_xy`` is
    the task's work area (the critical configurations' mean, W), ``front`` the unit floor
    direction from the robot's base toward it."""
    side = np.array([-front[1], front[0]])

    def far_point():
        return work_xy + front * rng.uniform(3.5, 4.5) + side * rng.uniform(-1.5, 1.5)

    start, near, end = far_point(), work_xy + front * rng.uniform(0.3, 0.9) + side * rng.uniform(-0.6, 0.6), far_point()
    speed = rng.uniform(0.6, 1.6)
    t0 = rng.uniform(0.0, 3.0)
    dwell = 0.0 if rng.uniform() < 0.25 else rng.uniform(0.0, 2.5)
    t1 = t0 + np.linalg.norm(near - start) / speed
    t2 = t1 + dwell
    t3 = t2 + np.linalg.norm(end - near) / speed
    points = [(0.0, start), (t0, start), (t1, near)] + ([(t2, near)] if dwell > 0.0 else []) + [(t3, end)]
    return Person(name, ScriptedPath(tuple(_increasing([Waypoint(t, xy) for t, xy in points]))))


def _increasing(waypoints):
    kept = []
    for waypoint in waypoints:
        if not kept or waypoint.t > kept[-1].t + 1e-9:
            kept.append(waypoint)
    return kept


def _work_area(task) -> tuple[np.ndarray, np.ndarray]:
    centre = np.mean([(np.asarray(c.p_lower) + np.asarray(c.p_upper))[:2] / 2 for c in task.critical_configurations],
                     axis=0)
    front = centre - task.X_WB.translation()[:2]
    return centre, front / max(np.linalg.norm(front), 1e-9)


def run(trials_per_task: int, seed: int, json_path: str | None) -> dict:
    policies = {"speed_and_separation": CollaborationParameters(),
                "stop_only": CollaborationParameters(policy=STOP_ONLY_POLICY)}
    timing = TimingLimits()
    stopping = CollaborationParameters().stopping_time(timing.joint_speed_rad_s, timing.joint_acceleration_rad_s2)
    radius = stop_only_radius_m(policies["stop_only"], stopping, CONTROL_PERIOD_S)
    print(f"stop-only radius {radius:.3f} m (S_p at 1.5 m/s plus the approach while stopping; T_s = {stopping:.3f} s)")
    rows = []
    wall = time.perf_counter()
    for task_name, library_name in TASKS:
        base_task = load_task(scenarios_directory() / f"{task_name}.yaml")
        features = library_features(Library.open(library_name))
        work_xy, front = _work_area(base_task)
        rng = np.random.default_rng(seed + sum(map(ord, task_name)))
        people = [random_person(rng, work_xy, front) for _ in range(trials_per_task)]
        for policy, parameters in policies.items():
            # One runner per person: the people are part of the scene the Diagram is built with.
            for index, person in enumerate(people):
                task = dataclasses.replace(base_task, people=(person,), collaboration=parameters)
                runner = TrialRunner(task, features)
                outcome = runner.run(trial=index + 1, seed=seed + index)
                record = outcome.run.collaboration if outcome.run is not None else None
                rows.append({
                    "task": task_name, "policy": policy, "trial": index + 1, "seed": seed + index,
                    "success": outcome.success, "ran": outcome.run is not None,
                    "violations": record.violation_count if record else 0,
                    "time_lost_s": record.time_lost_s if record else math.nan,
                    "time_scaled_s": record.time_scaled_s if record else math.nan,
                    "protective_stops": record.protective_stops if record else 0,
                    "min_separation_m": record.min_separation_m if record else math.nan,
                    "failures": outcome.failures,
                })
        done = [r for r in rows if r["task"] == task_name]
        print(f"{task_name}: {len(done)} runs, {time.perf_counter() - wall:.0f} s so far", flush=True)
    summary = {}
    for policy in policies:
        mine = [r for r in rows if r["policy"] == policy]
        ran = [r for r in mine if r["ran"]]
        lost = np.array([r["time_lost_s"] for r in ran])
        summary[policy] = {
            "trials": len(mine), "ran": len(ran), "success": sum(r["success"] for r in mine),
            "violation_samples": int(sum(r["violations"] for r in mine)),
            "trials_with_violations": sum(r["violations"] > 0 for r in mine),
            "time_lost_total_s": float(lost.sum()), "time_lost_mean_s": float(lost.mean()) if len(lost) else math.nan,
            "time_lost_max_s": float(lost.max()) if len(lost) else math.nan,
            "time_scaled_total_s": float(sum(r["time_scaled_s"] for r in ran)),
            "protective_stops": int(sum(r["protective_stops"] for r in ran)),
        }
    print()
    print(f"{'policy':22s} {'trials':>6s} {'success':>8s} {'violations':>10s} {'lost total':>11s} "
          f"{'lost mean':>10s} {'lost max':>9s} {'slowed':>8s} {'stops':>6s}")
    for policy, s in summary.items():
        print(f"{policy:22s} {s['trials']:6d} {s['success']:8d} {s['violation_samples']:10d} "
              f"{s['time_lost_total_s']:10.1f}s {s['time_lost_mean_s']:9.2f}s {s['time_lost_max_s']:8.2f}s "
              f"{s['time_scaled_total_s']:7.1f}s {s['protective_stops']:6d}")
    ssm, stop = summary["speed_and_separation"], summary["stop_only"]
    print()
    print(f"speed and separation monitoring: {ssm['violation_samples']} violations (must be 0); "
          f"stop-only: {stop['violation_samples']}")
    saved = stop["time_lost_total_s"] - ssm["time_lost_total_s"]
    print(f"cycle time lost: {ssm['time_lost_total_s']:.1f} s with speed and separation monitoring against "
          f"{stop['time_lost_total_s']:.1f} s stop-only at equal safety: "
          f"{'less' if saved > 0 else 'NOT less'} ({saved:.1f} s saved over {ssm['ran']} trials)")
    print(f"wall time {time.perf_counter() - wall:.0f} s")
    document = {"stop_only_radius_m": radius, "summary": summary, "trials": rows}
    if json_path:
        with open(json_path, "w", encoding="utf-8") as handle:
            json.dump(document, handle, indent=1, default=float)
    return document


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--trials-per-task", type=int, default=17, help="trials per task (3 tasks; default 17: 51)")
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--json", metavar="OUT", help="write the per-trial figures as JSON")
    args = parser.parse_args()
    run(args.trials_per_task, args.seed, args.json)


if __name__ == "__main__":
    main()
