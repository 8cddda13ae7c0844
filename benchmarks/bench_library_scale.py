"""Planning against large libraries: time, memory and what the index discards.

Run: ``python benchmarks/bench_library_scale.py`` (all sections, about 10 minutes), or
one section: ``--section scale`` / ``issue`` / ``q``.

* ``scale``: generated libraries of 10, 100, 1,000 and 10,000 demonstrations with their
  own random motions (``core/synthetic_library.random_features``), chained tasks of 4,
  10, 25 and 50 configurations made from pieces of the library's own demonstrations
  (perturbed by up to 15 deg and 2 cm). The library is prepared first (stacks, KD-tree,
  demo terms: once per library in a process, timed apart). For each cell, the exact
  planner (legal-action table and solve, default ``fidelity`` cost), wall and CPU
  seconds: one task's first plan (it also computes the suffix excursions of the
  demonstrations it reaches for the first time), its repeated plan (a new problem, the
  prepared library reused: what every later plan of that size costs), and a second task
  of the same size planned once (its pieces from other demonstrations, so its work
  differs); the largest of the three plans' peak memory (the resident memory at its
  highest during the plan above what the process held before: numpy's buffers,
  Python's objects and the allocator's slack); the first task's fractions of
  (demonstration, span) pairs the index discarded, the sweep never reached (no shorter
  allocation) and the exact test ran on. After each size, the process's peak resident
  memory so far (VmHWM, what ru_maxrss reports: the generated features, the prepared
  library and the plans) and the load average. Then, when ``benchmarks/library_ops.py``
  is present, the on-disk library's operation times.
* ``issue``: the table of the issue: the paper's six demonstrations copied and rigidly
  turned to h = 6, 25, 100, chained tasks of n = 10, 25, 50, exact planner.
* ``q``: the Q-learner against libraries of 6 to 1,000 demonstrations (each size in its
  own process, for its peak memory): training on 20 random tasks x 100 episodes (the
  ``train`` defaults), the tables' sizes, and a plan with the Q planner against the
  exact one on a 10-configuration chained task.

Acceptance (issue 26): h = 1,000, n = 10 at most 1 s; h = 10,000, n = 10 at most 5 s;
h = 100, n = 50 at most 1 s; peak memory at most 1 GB everywhere.
"""

from __future__ import annotations

import argparse
import importlib.util
import json
import os
import pathlib
import resource
import subprocess
import sys
import tempfile
import time

import numpy as np

from drake_lfd.core.dual_quaternion import dual_quaternion_from_translation_rotation, dual_quaternion_multiply
from drake_lfd.core.quaternion import quaternion_from_axis_angle
from drake_lfd.core.errors import InputError
from drake_lfd.core.features import Feature
from drake_lfd.core.similarity import Tolerances
from drake_lfd.core.synthetic_library import PAPER6, random_features, synthetic_demo_poses
from drake_lfd.planning.exact_planner import plan_exact
from drake_lfd.planning.planner import build_problem
from drake_lfd.planning.random_tasks import chained_task
from drake_lfd.planning.span_index import prepared_library

__all__ = ["main", "turned_copies", "plan_once"]

SIZES = (10, 100, 1000, 10000)
TASK_LENGTHS = (4, 10, 25, 50)
ISSUE_SIZES = (6, 25, 100)
ISSUE_LENGTHS = (10, 25, 50)
Q_SIZES = (6, 30, 100, 300, 1000)
HERE = pathlib.Path(__file__).resolve().parent


def turned_copies(count: int, seed: int = 0) -> dict[str, Feature]:
    """``count`` copies of the paper's six demonstrations, each turned and moved rigidly."""
    rng = np.random.default_rng(seed)
    copies = {}
    for i in range(count):
        name = PAPER6[i % len(PAPER6)]
        axis = rng.normal(size=3)
        turn = dual_quaternion_from_translation_rotation(
            rng.uniform(-0.2, 0.2, 3), quaternion_from_axis_angle(axis / np.linalg.norm(axis), rng.uniform(0, np.pi)))
        copies[f"{name}_{i}"] = Feature.from_poses(dual_quaternion_multiply(turn, synthetic_demo_poses(name)))
    return copies


def plan_once(task, library, cost="fidelity"):
    """Builds the problem and plans exactly: (seconds, peak MB, problem, steps, CPU
    seconds of this process: on a loaded machine the wall time counts the waits). The
    peak is the process's resident memory at its highest during the plan above what it
    held before (``/proc/self/status`` VmHWM after resetting it, where Linux allows)."""
    rss = _reset_peak()
    start, start_cpu = time.perf_counter(), time.process_time()
    problem = build_problem(task, library, cost=cost)
    steps = plan_exact(problem)
    seconds, cpu = time.perf_counter() - start, time.process_time() - start_cpu
    return seconds, _status_mb("VmHWM") - rss, problem, steps, cpu


_process_peak_mb = 0.0


def _status_mb(field: str) -> float:
    """A memory field of ``/proc/self/status`` in MB (``VmRSS``, ``VmHWM``); without
    it (not Linux), the process's ru_maxrss for both."""
    try:
        with open("/proc/self/status") as status:
            for line in status:
                if line.startswith(field + ":"):
                    return int(line.split()[1]) / 1024
    except OSError:
        pass
    return resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024


def _reset_peak() -> float:
    """Folds the peak so far into :func:`_peak_rss_mb`'s and resets the kernel's, so the
    next VmHWM is the peak of what follows; returns the resident memory now (MB)."""
    global _process_peak_mb
    _process_peak_mb = max(_process_peak_mb, _status_mb("VmHWM"))
    try:
        with open("/proc/self/clear_refs", "w") as clear:
            clear.write("5")  # resets VmHWM (and ru_maxrss) to the current resident memory
    except OSError:  # not Linux: the peaks are then the process's since it started
        pass
    return _status_mb("VmRSS")


def _task(library, n, seed):
    return chained_task(np.random.default_rng(seed), library, num_cons=n, perturbation_deg=15,
                        perturbation_m=0.02, name=f"chained_{n}")[0]


def _seconds(function):
    """``function()``'s result with its wall and CPU seconds (this process's)."""
    start, start_cpu = time.perf_counter(), time.process_time()
    result = function()
    return result, time.perf_counter() - start, time.process_time() - start_cpu


def _peak_rss_mb() -> float:
    """The process's peak resident memory so far (VmHWM, ru_maxrss's figure, over every reset)."""
    return max(_process_peak_mb, _status_mb("VmHWM"))


def scale_section(sizes, lengths, cost):
    print(f"## planning (exact planner, {cost} cost; wall s with CPU s in brackets)")
    print("| h | n | first plan | repeated plan | another task | plan peak MB | discarded by index | not reached "
          "| tested | planned |")
    print("|---|---|---|---|---|---|---|---|---|---|")
    for h in sizes:
        library, made, _ = _seconds(lambda: random_features(np.random.default_rng(h), h))
        _, prepared, prepared_cpu = _seconds(lambda: prepared_library(list(library.values()), Tolerances()))
        for n in lengths:
            task = _task(library, n, 2 * n)
            try:
                first = plan_once(task, library, cost)
            except InputError as error:  # check_problem_size's refusal, before anything is allocated
                print(f"| {h:,} | {n} | refused by the size check: {str(error).split(': the task ')[-1].split(':')[0]} "
                      "|", flush=True)
                continue
            first = first[0], first[4], first[1]  # the problem is dropped: one table alive at a time
            seconds, peak, problem, steps, cpu = plan_once(task, library, cost)
            s, planned = problem.stats, steps is not None
            del problem, steps
            other = plan_once(_task(library, n, 2 * n + 1), library, cost)
            other = other[0], other[4], other[1], other[3] is not None
            print(f"| {h:,} | {n} | {first[0]:.2f} ({first[1]:.2f}) | {seconds:.2f} ({cpu:.2f}) | "
                  f"{other[0]:.2f} ({other[1]:.2f}){'' if other[3] else ' no plan'} | "
                  f"{max(peak, first[2], other[2]):.0f} | "
                  f"{s.discarded_by_index / s.pairs:.2f} | {s.dropped_earlier / s.pairs:.2f} | "
                  f"{s.tested / s.pairs:.2f} | {'yes' if planned else 'no'} |", flush=True)
        print(f"(h = {h:,}: library generated in {made:.1f} s, prepared (stacks, index, demo terms) in {prepared:.2f} s "
              f"({prepared_cpu:.2f} CPU), neither counted; process peak so far {_peak_rss_mb():.0f} MB; "
              f"load average {os.getloadavg()[0]:.1f})", flush=True)
        del library
    print(f"process peak resident memory: {_peak_rss_mb():.0f} MB")
    library_operations(sizes)


def library_operations(sizes):
    sys.path.insert(0, str(HERE))
    if importlib.util.find_spec("library_ops") is None:
        print("library operations: benchmarks/library_ops.py not present")
        return
    from library_ops import measure_library_operations  # the on-disk library's benchmark

    print("## library operations (s)")
    print("| h | open | show | add one | remove one |")
    print("|---|---|---|---|---|")
    for h in sizes:
        with tempfile.TemporaryDirectory() as folder:
            t = measure_library_operations(h, pathlib.Path(folder))
        print(f"| {h:,} | {t['open_s']:.3f} | {t['show_s']:.3f} | {t['add_s']:.3f} | {t['remove_s']:.3f} |",
              flush=True)


def issue_section():
    print("## the issue's table (turned copies of the six demonstrations, exact planner, fidelity cost)")
    print("| n cons | " + " | ".join(f"h = {h}" for h in ISSUE_SIZES) + " |")
    print("|---|" + "---|" * len(ISSUE_SIZES))
    six = {name: Feature.from_poses(synthetic_demo_poses(name)) for name in PAPER6}
    for n in ISSUE_LENGTHS:
        task = _task(six, n, n)
        cells = []
        for h in ISSUE_SIZES:
            seconds, _, _, steps, _ = plan_once(task, turned_copies(h))  # fresh copies: prepared in the plan
            cells.append(f"{seconds:.2f} s" + ("" if steps else " (no plan)"))
        print(f"| {n} | " + " | ".join(cells) + " |", flush=True)


def q_one(h: int) -> dict:
    """The Q-learner against a library of h demonstrations (PAPER6 and random ones)."""
    from drake_lfd.planning.q_learning import plan_q
    from drake_lfd.planning.training import train_on_random_tasks

    six = {name: Feature.from_poses(synthetic_demo_poses(name)) for name in PAPER6}
    library = {**six, **random_features(np.random.default_rng(h), max(0, h - len(six)))}
    start = time.perf_counter()
    result = train_on_random_tasks(library, num_tasks=20, episodes=100, seed=0)
    trained = time.perf_counter() - start
    policy = result.policy
    task = _task(six, 10, 1)
    exact_s, _, problem, exact, _ = plan_once(task, library)
    start = time.perf_counter()
    q = plan_q(build_problem(task, library, cost="fidelity"), policy)
    q_s = time.perf_counter() - start
    return {"h": h, "train_s": trained, "values": len(policy.values), "illegal_values": len(policy.illegal_values),
            "policy_json_mb": len(json.dumps(policy.illegal_values)) / 2**20 + len(json.dumps(policy.values)) / 2**20,
            "peak_mb": resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024, "plan_q_s": q_s,
            "plan_exact_s": exact_s,
            "q_cost_over_exact": (sum(s.cost for s in q.steps) / sum(s.cost for s in exact)) if q.steps and exact
            else None}


def q_section():
    print("## Q-learner (20 random tasks x 100 episodes; plan: 10-configuration chained task)")
    print("| h | training s | afterstate values | illegal-action values | policy JSON MB | process peak MB | "
          "plan --planner q s | exact s | Q cost / exact |")
    print("|---|---|---|---|---|---|---|---|---|")
    for h in Q_SIZES:
        out = subprocess.run([sys.executable, __file__, "--q-one", str(h)], capture_output=True, text=True,
                             check=True).stdout
        r = json.loads(out.strip().splitlines()[-1])
        ratio = "-" if r["q_cost_over_exact"] is None else f"{r['q_cost_over_exact']:.3f}"
        print(f"| {h:,} | {r['train_s']:.1f} | {r['values']:,} | {r['illegal_values']:,} | {r['policy_json_mb']:.1f} | "
              f"{r['peak_mb']:.0f} | {r['plan_q_s']:.2f} | {r['plan_exact_s']:.2f} | {ratio} |", flush=True)


def main(argv=None):
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--section", choices=("all", "scale", "issue", "q"), default="all")
    parser.add_argument("--sizes", type=int, nargs="+", default=SIZES, help="library sizes of the scale section")
    parser.add_argument("--lengths", type=int, nargs="+", default=TASK_LENGTHS, help="task lengths (configurations)")
    parser.add_argument("--cost", choices=("fidelity", "paper"), default="fidelity",
                        help="cost mode of the scale section")
    parser.add_argument("--q-one", type=int, help=argparse.SUPPRESS)
    args = parser.parse_args(argv)
    if args.q_one is not None:
        print(json.dumps(q_one(args.q_one)))
        return
    if args.section in ("all", "scale"):
        scale_section(args.sizes, args.lengths, args.cost)
    if args.section in ("all", "issue"):
        issue_section()
    if args.section in ("all", "q"):
        q_section()


if __name__ == "__main__":
    main()
