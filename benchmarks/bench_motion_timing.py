"""Executed duration against the time-optimal traversal of the same executed joint path.

Run: ``python benchmarks/bench_motion_timing.py [--trials 3] [--pick-and-place 10]``.

For the paper's three tasks (transferring and filling-and-pouring with ``paper5``,
assembling with ``paper6``; trials drawn as ``simulate`` draws them) and for the
pick-and-place benchmark tasks (``drake_lfd.experiments.pick_and_place``, one trial
each), runs the closed loop as ``simulate`` does and prints per task:

- **executed**: simulated time from the plan's start to its last critical configuration;
- **optimal**: the time-optimal traversal of the *logged* joint path (what the arm
  actually did) under the UR5e's full limits: joint speed pi rad/s, joint acceleration
  8 rad/s^2, tool speed 1.5 m/s, at rest at both ends. Computed here, independently of
  the planner's timing code: Drake's ``Toppra`` (grid: ``CalcGridPoints``'s defaults
  plus every knot) on several fits of the logged samples (stationary ones dropped): a
  shape-preserving cubic through all of them, and C2 cubic splines through knots 0.01,
  0.02 and 0.04 rad of joint travel apart. The servos' jitter makes the curvature of
  the raw samples noisy, which slows a time-optimal traversal; a fit smooths it. The
  optimum is the *fastest* of the fits that keep within 3 mm of the logged tool path, so
  the ratio is the hardest one to meet;
- the ratio (target <= 1.15), the largest measured joint speed over its limit, the
  largest critical-configuration error (target 5 mm / 2 deg) and the verdict.
"""

from __future__ import annotations

import argparse
import math
import tempfile
import time
from pathlib import Path

import numpy as np
from pydrake.multibody.optimization import CalcGridPointsOptions, Toppra
from pydrake.trajectories import PiecewisePolynomial

from drake_lfd.core.resources import scenarios_directory
from drake_lfd.experiments.pick_and_place import write_pick_and_place_tasks
from drake_lfd.experiments.simulation import TrialRunner
from drake_lfd.io.library import Library, library_features
from drake_lfd.io.task_files import load_task
from drake_lfd.planning.options import PlanningOptions
from drake_lfd.robot.kinematics import UR5eKinematics

JOINT_SPEED_RAD_S = math.pi
JOINT_ACCELERATION_RAD_S2 = 8.0
TOOL_SPEED_M_S = 1.5


def _toppra_duration(path: PiecewisePolynomial, kinematics: UR5eKinematics) -> float:
    grid = np.unique(np.concatenate([Toppra.CalcGridPoints(path, CalcGridPointsOptions()),
                                     np.asarray(path.get_segment_times())]))
    toppra = Toppra(path, kinematics.plant, grid)
    toppra.AddJointVelocityLimit(-JOINT_SPEED_RAD_S * np.ones(6), JOINT_SPEED_RAD_S * np.ones(6))
    toppra.AddJointAccelerationLimit(-JOINT_ACCELERATION_RAD_S2 * np.ones(6), JOINT_ACCELERATION_RAD_S2 * np.ones(6))
    toppra.AddFrameTranslationalSpeedLimit(kinematics.end_effector_frame, TOOL_SPEED_M_S)
    s_of_t = toppra.SolvePathParameterization()
    return math.nan if s_of_t is None else float(s_of_t.end_time())


def optimal_duration(q: np.ndarray, kinematics: UR5eKinematics) -> float:
    """Time-optimal traversal of the joint path ``q`` (m, 6), rest to rest (the fastest
    fit within 3 mm of it; module docstring)."""
    keep = [0]
    for k in range(1, len(q)):
        if np.linalg.norm(q[k] - q[keep[-1]]) > 1e-6:
            keep.append(k)
    q = q[keep]
    s = np.concatenate([[0.0], np.cumsum(np.linalg.norm(np.diff(q, axis=0), axis=1))])
    tool = kinematics.X_WE_batch(q)[:, :3, 3]
    fits = [PiecewisePolynomial.CubicShapePreserving(s, q.T, zero_end_point_derivatives=False)]
    for step in (0.01, 0.02, 0.04):
        knots = np.unique(np.concatenate([np.searchsorted(s, np.arange(0.0, s[-1], step)), [len(s) - 1]]))
        fit = PiecewisePolynomial.CubicWithContinuousSecondDerivatives(s[knots], q[knots].T, False)
        fitted = kinematics.X_WE_batch(np.array([fit.value(x)[:, 0] for x in s]))[:, :3, 3]
        if np.linalg.norm(fitted - tool, axis=1).max() <= 0.003:
            fits.append(fit)
    durations = [_toppra_duration(fit, kinematics) for fit in fits]
    return float(np.nanmin(durations)) if not np.all(np.isnan(durations)) else math.nan


def measure(task, features, seed: int) -> dict | None:
    runner = TrialRunner(task, features, options=PlanningOptions(cost="paper"))
    outcome = runner.run(trial=1, seed=seed)
    run = outcome.run
    if run is None:
        return None
    due = [c.time_s for c in run.critical_errors]
    start, end = run.plan_start_time_s, due[-1]
    inside = (run.t >= start - 1e-9) & (run.t <= end + 1e-9)
    kinematics = UR5eKinematics(X_WB=task.X_WB, X_tool0_E=task.X_tool0_E)
    optimal = optimal_duration(run.q[inside], kinematics)
    executed = end - start
    return {
        "executed": executed, "optimal": optimal, "ratio": executed / optimal,
        "speed": run.max_joint_speed_fraction,
        "mm": 1000 * max(c.position_m for c in run.critical_errors),
        "deg": math.degrees(max(c.rotation_rad for c in run.critical_errors)),
        "success": outcome.success, "failures": outcome.failures,
    }


def report(label: str, row: dict | None) -> None:
    if row is None:
        print(f"{label:32s} not planned")
        return
    verdict = "success" if row["success"] else "FAILED: " + "; ".join(row["failures"])[:80]
    print(f"{label:32s} executed {row['executed']:6.2f} s  optimal {row['optimal']:6.2f} s  "
          f"ratio {row['ratio']:5.2f}  speed {row['speed']:4.2f} of limit  "
          f"con error {row['mm']:4.2f} mm {row['deg']:4.2f} deg  {verdict}", flush=True)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--trials", type=int, default=3, help="trials per paper task")
    parser.add_argument("--pick-and-place", type=int, default=10, help="pick-and-place tasks")
    args = parser.parse_args()
    start = time.perf_counter()
    rows = []
    for name, library in (("transferring", "paper5"), ("filling_pouring", "paper5"), ("assembling", "paper6")):
        task = load_task(scenarios_directory() / f"{name}.yaml")
        features = library_features(Library.open(library))
        for seed in range(args.trials):
            row = measure(task, features, seed)
            report(f"{name} (seed {seed})", row)
            rows.append(row)
    features = library_features(Library.open("paper5"))
    with tempfile.TemporaryDirectory() as directory:
        for path in write_pick_and_place_tasks(Path(directory), args.pick_and_place):
            row = measure(load_task(path), features, 0)
            report(path.stem, row)
            rows.append(row)
    done = [r for r in rows if r is not None]
    ratios = [r["ratio"] for r in done]
    print(f"{len(done)} runs: executed / optimal median {np.median(ratios):.2f}, worst {max(ratios):.2f} "
          f"(target <= 1.15); fastest joint {max(r['speed'] for r in done):.2f} of its limit; "
          f"worst con error {max(r['mm'] for r in done):.2f} mm, {max(r['deg'] for r in done):.2f} deg; "
          f"{sum(r['success'] for r in done)}/{len(done)} succeeded; {time.perf_counter() - start:.0f} s")


if __name__ == "__main__":
    main()
