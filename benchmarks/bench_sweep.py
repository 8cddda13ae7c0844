"""Speed-up of ``drake-lfd sweep`` on 2 worker processes over 1, and whether the rows agree.

Run: ``python benchmarks/bench_sweep.py [--trials 10] [--grid X0:X1:NX Y0:Y1:NY] [--rounds 2]``
(about 13 minutes). It runs the same sweep as a user would, each run a separate
``drake-lfd sweep`` process: the transferring task with ``paper5`` on a 2 x 2 grid of base
placements around the task file's base, 10 trials each (40 trials), with ``--workers 1``
(in one process, no cluster) and with ``--workers 2`` (a LocalCluster of two worker
processes; cluster start-up included). The machine is shared and its speed drifts by a
third over minutes (the same failing trial measured 7.3 s and 11.0 s on one day; one round
of this benchmark measured 2.06x, the next 1.70x), so the runs go in the order 1, 2, 2, 1
workers, twice by default (``--rounds``): a drift that is steady over a round weighs the
same on both, and a second round averages out more of the rest. Prints every wall time, the
speed-up (the 1-worker sum over the 2-worker sum; target: at least 1.7 on two cores)
overall and of each round, the load average before and after, and whether every
``sweep.jsonl`` table is the same row for row
(every field but wall-clock ones, rows matched by their inputs).

Not for: measuring a single trial (``bench_pipeline.py``).
"""

from __future__ import annotations

import argparse
import os
import subprocess
import sys
import tempfile
import time
from pathlib import Path

from drake_lfd.core.resources import scenarios_directory
from drake_lfd.experiments.sweep import row_key
from drake_lfd.io.json_lines import read_json_lines


def without_wall_times(value):
    """``value`` without wall-clock fields (they differ between runs)."""
    if isinstance(value, dict):
        return {k: without_wall_times(v) for k, v in value.items() if "wall" not in k}
    if isinstance(value, list):
        return [without_wall_times(v) for v in value]
    return value


def run_sweep(out: Path, workers: int, trials: int, grid: list[str]) -> float:
    """Wall time of one ``drake-lfd sweep`` process, start-up included."""
    command = [sys.executable, "-m", "drake_lfd", "sweep", str(scenarios_directory() / "transferring.yaml"),
               "--library", "paper5", "--trials", str(trials), "--base-grid", *grid,
               "--workers", str(workers), "--out", str(out)]
    start = time.perf_counter()
    subprocess.run(command, check=True, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
    return time.perf_counter() - start


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--trials", type=int, default=10, help="trials per base placement")
    parser.add_argument("--grid", nargs=2, default=["-0.3:-0.2:2", "0.6:0.7:2"], metavar="A0:A1:N",
                        help="the x and y axes of --base-grid")
    parser.add_argument("--rounds", type=int, default=2, help="rounds of runs in the order 1, 2, 2, 1 workers")
    args = parser.parse_args()
    placements = 1
    for axis in args.grid:
        placements *= int(axis.split(":")[2])
    total = placements * args.trials
    load_before = os.getloadavg()[0]
    order = [1, 2, 2, 1] * max(1, args.rounds)
    walls, tables = {1: [], 2: []}, []
    with tempfile.TemporaryDirectory() as scratch:
        for run, workers in enumerate(order):
            out = Path(scratch) / f"run{run}"
            walls[workers].append(run_sweep(out, workers, args.trials, args.grid))
            rows = read_json_lines(out / "sweep.jsonl")
            tables.append(sorted((without_wall_times(row) for row in rows), key=row_key))
            successes = sum(bool(row["success"]) for row in rows)
            print(f"--workers {workers}: {total} trials ({placements} placements x {args.trials}) in "
                  f"{walls[workers][-1]:.1f} s wall, {successes} succeeded", flush=True)
    load_after = os.getloadavg()[0]
    same = all(len(table) == total and table == tables[0] for table in tables)
    rounds = [f"{sum(walls[1][2 * r:2 * r + 2]) / sum(walls[2][2 * r:2 * r + 2]):.2f}x"
              for r in range(len(walls[2]) // 2)]
    print(f"speed-up of each round: {', '.join(rounds)}")
    print(f"speed-up on 2 workers: {sum(walls[1]):.1f} s / {sum(walls[2]):.1f} s = "
          f"{sum(walls[1]) / sum(walls[2]):.2f}x (target 1.7x); {os.cpu_count()} cores; "
          f"load average {load_before:.1f} before, {load_after:.1f} after")
    print(f"rows identical row for row (wall-clock fields aside): {'yes' if same else 'NO'}")


if __name__ == "__main__":
    main()
