"""Shape fidelity: do plans recover the demonstrations a task was cut from? Printed, never asserted.

Run: ``python benchmarks/bench_fidelity.py [--tasks 60] [--seed 0] [--library paper5]``.

Each task (:mod:`drake_lfd.experiments.fidelity_tasks`) is two or three pieces of
distinct library demonstrations, each cut at two random points along it (poses
interpolated between resampling samples), placed end to end under a random rigid
placement; its critical configurations (fixed Euler angles) are the cut points and the
joins. Each task is planned with the exact planner in SE(3) (no joint-space check) with
``--cost paper`` (Eq. 31) and ``--cost fidelity`` (docs/method.rst, Shape fidelity).
A plan passes when it uses the constructing composition (the same demonstrations over
the same spans) or its tool path stays within 2 cm of the constructing demonstrations'
shape: the symmetric distance, the largest distance of a sample of either path from the
other path's polyline (:func:`~drake_lfd.experiments.fidelity_tasks.path_distance`).

Prints one line per task (pieces; per cost mode: pass, constructing composition found,
path distance) and the pass rates side by side. Seeded and deterministic.
"""

from __future__ import annotations

import argparse
import time

import numpy as np

from drake_lfd.core.fidelity import COST_MODES
from drake_lfd.experiments.fidelity_tasks import SUCCESS_TOLERANCE_M, evaluate, fidelity_task
from drake_lfd.io.library import Library, library_features


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--tasks", type=int, default=60)
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--library", default="paper5")
    args = parser.parse_args()

    features = library_features(Library.open(args.library))
    rng = np.random.default_rng(args.seed)
    start = time.perf_counter()
    header = f"{'task':>4}  {'pieces (demo[con_from-con_to])':<48}" + "".join(
        f"  {cost + ': pass constr dist':<28}" for cost in COST_MODES)
    print(header)
    results = {cost: [] for cost in COST_MODES}
    for number in range(args.tasks):
        case = fidelity_task(rng, features, name=f"fidelity_{number}")
        pieces = " ".join(f"{p.demo}[{p.con_from}-{p.con_to}]" for p in case.pieces)
        line = f"{number:>4}  {pieces:<48}"
        for cost in COST_MODES:
            evaluation = evaluate(case, features, cost)
            results[cost].append(evaluation)
            distance = "-" if not np.isfinite(evaluation.distance_m) else f"{evaluation.distance_m * 100:.1f} cm"
            line += (f"  {'pass' if evaluation.success else 'FAIL':<10} {'yes' if evaluation.constructing else 'no':<6}"
                     f" {distance:>9}  ")
        print(line)
    wall = time.perf_counter() - start

    print()
    print(f"{args.tasks} tasks, library {args.library}, seed {args.seed}, pass: constructing composition or "
          f"path within {SUCCESS_TOLERANCE_M * 100:.0f} cm; {wall:.1f} s")
    print(f"{'':<34}" + "".join(f"{cost:>12}" for cost in COST_MODES))
    rows = [
        ("pass", lambda e: e.success),
        ("constructing composition", lambda e: e.constructing),
        ("planned", lambda e: e.status == "planned"),
    ]
    for label, test in rows:
        cells = []
        for cost in COST_MODES:
            count = sum(bool(test(e)) for e in results[cost])
            cells.append(f"{count:>4} ({100 * count / args.tasks:3.0f} %)")
        print(f"{label:<34}" + "".join(f"{c:>12}" for c in cells))
    for label, function in (("median path distance (cm)", np.median), ("max path distance (cm)", np.max)):
        cells = []
        for cost in COST_MODES:
            distances = np.array([e.distance_m for e in results[cost] if np.isfinite(e.distance_m)])
            cells.append(f"{100 * function(distances):.1f}" if len(distances) else "-")
        print(f"{label:<34}" + "".join(f"{c:>12}" for c in cells))


if __name__ == "__main__":
    main()
