"""Measure where the robot base should stand in each paper scenario: a ``drake-lfd sweep`` each.

    python sims/base_placement_sweeps.py [--trials 8] [--step 0.1] [--out base_placement_sweeps]
                                         [--tasks NAME ...] [--workers N | --scheduler ADDRESS]

For each paper scenario (``sims/transferring.yaml``, ``sims/filling_pouring.yaml``,
``sims/assembling.yaml``) this runs ``drake-lfd sweep`` on a 5 x 5 grid of base
placements centred on the scenario's current base (x and y +-2 steps, z and yaw kept),
N trials each, with the exact planner and the paper's action cost (``--cost paper``;
transferring and filling-and-pouring with ``paper5``, assembling with ``paper6``, which
has the demonstration it needs); ``--tasks`` runs only some of them. Each sweep's rows
and summary stay in ``OUT/<task>/`` (``--resume``: an interrupted run continues). It
copies each success map to ``docs/_static/base_placement_<task>.png`` and writes the
table of the current and the best placements, with their success rates, of every
scenario with a summary in ``OUT`` to ``docs/_static/base_placements.md`` (and prints
it). It changes no scenario file: choosing a new base is a decision for the
scenario's author (the files explain their choices).

Not for: running one sweep (``drake-lfd sweep``).
"""

from __future__ import annotations

import argparse
import json
import shutil
from pathlib import Path

from drake_lfd import cli
from drake_lfd.core.resources import scenarios_directory
from drake_lfd.experiments.parallel_trials import BasePlacement
from drake_lfd.io.task_files import load_task

REPOSITORY = Path(__file__).resolve().parent.parent
STATIC = REPOSITORY / "docs" / "_static"
SCENARIOS = (("transferring", "paper5"), ("filling_pouring", "paper5"), ("assembling", "paper6"))


def grid_around(base: BasePlacement, step: float) -> list[str]:
    """``--base-grid`` axes: x and y from 2 steps below to 2 steps above the base, 5 each."""
    return [f"{base.x - 2 * step:.6g}:{base.x + 2 * step:.6g}:5", f"{base.y - 2 * step:.6g}:{base.y + 2 * step:.6g}:5"]


def _placement_text(entry: dict) -> str:
    return f"({entry['base_x']:.2f}, {entry['base_y']:.2f}, {entry['base_z']:.2f})"


def _rate_text(entry: dict) -> str:
    return f"{entry['successes']}/{entry['trials']}"


def table_markdown(summaries: dict[str, dict], *, step: float) -> str:
    """The current and the best placements of each scenario, with their success rates."""
    lines = [
        f"Base placements measured by `python sims/base_placement_sweeps.py` (5 x 5 grid, step {step:g} m "
        "around the scenario's base, exact planner, `--cost paper`).",
        "",
        "| scenario | library | trials per placement | current base (x, y, z) m | its success | best placements "
        "| their success | grid total |",
        "|---|---|---|---|---|---|---|---|",
    ]
    for name, summary in summaries.items():
        own = summary["task_base"]
        current = next(e for e in summary["by_base"] if all(
            abs(e[k] - own[k]) < 1e-9 for k in ("base_x", "base_y", "base_z", "base_yaw_deg")))
        best = summary["best"]
        lines.append(
            f"| {name} | {summary['library']} | {summary['trials_per_base']} | {_placement_text(current)} | "
            f"{_rate_text(current)} | "
            f"{', '.join(_placement_text(e) for e in best[:6])}{' ...' if len(best) > 6 else ''} "
            f"({len(best)}) | {_rate_text(best[0])} | {summary['success_count']}/{summary['rows']} |")
    return "\n".join(lines) + "\n"


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--trials", type=int, default=8, help="trials per base placement")
    parser.add_argument("--step", type=float, default=0.1, help="grid spacing in metres")
    parser.add_argument("--out", default="base_placement_sweeps", help="folder of the sweeps' results")
    parser.add_argument("--tasks", nargs="+", choices=[name for name, _ in SCENARIOS],
                        default=[name for name, _ in SCENARIOS], help="the scenarios to sweep")
    group = parser.add_mutually_exclusive_group()
    group.add_argument("--workers", type=int, help="worker processes (default: every core)")
    group.add_argument("--scheduler", help="a running dask scheduler's address")
    args = parser.parse_args()
    where = (["--workers", str(args.workers)] if args.workers else []) + (
        ["--scheduler", args.scheduler] if args.scheduler else [])
    STATIC.mkdir(parents=True, exist_ok=True)
    for name, library in SCENARIOS:
        if name not in args.tasks:
            continue
        task_file = scenarios_directory() / f"{name}.yaml"
        base = BasePlacement.of(load_task(task_file).X_WB)
        out = Path(args.out) / name
        status = cli.main(["sweep", str(task_file), "--library", library, "--planner", "exact", "--cost", "paper",
                           "--trials", str(args.trials), "--base-grid", *grid_around(base, args.step),
                           "--out", str(out), "--resume", *where])
        if status != 0:
            raise SystemExit(f"{name}: drake-lfd sweep ended with status {status}")
        shutil.copyfile(out / "success_by_base.png", STATIC / f"base_placement_{name}.png")
    summaries = {name: json.loads((Path(args.out) / name / "summary.json").read_text())
                 for name, _ in SCENARIOS if (Path(args.out) / name / "summary.json").is_file()}
    table = table_markdown(summaries, step=args.step)
    (STATIC / "base_placements.md").write_text(table)
    print(table)


if __name__ == "__main__":
    main()
