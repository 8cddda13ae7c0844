"""``drake-lfd train``: Q-learning of a general policy on random tasks (Algorithm 1).

A thin front end (docs/cli.rst): it loads the library, refreshes its feature caches,
trains and writes the policy and its curve. Not for: the learning itself
(:mod:`drake_lfd.planning.training`, :mod:`drake_lfd.planning.q_learning`).
"""

from __future__ import annotations

from pathlib import Path

from drake_lfd.cli.argument_checks import require_at_least, require_folder_of, require_seed
from drake_lfd.io.atomic_files import atomic_write_json
from drake_lfd.core.errors import InputError


__all__ = ["add_parser", "curve_figure_path", "run"]


def add_parser(subparsers) -> None:
    parser = subparsers.add_parser(
        "train",
        help="Q-learning of a general composition policy on random tasks",
        description=(
            "Train a policy on N random tasks drawn as in the paper's Section 6.2 (4 critical "
            "configurations, positions in a 50 cm cube, Euler angles from multiples of pi/2), "
            "E episodes each. Writes POLICY and a training-curve figure beside it."
        ),
    )
    parser.add_argument("--library", required=True, metavar="LIB")
    parser.add_argument("--random-tasks", type=int, default=20, metavar="N")
    parser.add_argument(
        "--chained-tasks", type=int, default=None, metavar="M",
        help="also train on M tasks chained from the library's demonstrations (default 0: the paper's "
             "random tasks only, which a small library rarely covers)",
    )
    parser.add_argument("--episodes", type=int, default=100, metavar="E")
    parser.add_argument("--seed", type=int, default=0, metavar="S")
    parser.add_argument("--out", required=True, metavar="POLICY", help="policy file to write (JSON)")
    parser.add_argument("--warm-start", metavar="POLICY", help="start from this saved policy")
    parser.add_argument("--json", metavar="OUT", help="write the training summary as JSON")
    parser.set_defaults(func=run)


def curve_figure_path(policy_path: Path) -> Path:
    return policy_path.with_name(policy_path.stem + ".curve.png")


def run(args) -> int:
    from drake_lfd.experiments.figures import training_curve_figure
    from drake_lfd.io.library import Library, library_features
    from drake_lfd.cli.progress import ProgressBar
    from drake_lfd.io.policy_files import load_policy, save_policy
    from drake_lfd.planning.q_learning import episodes_to_steady
    from drake_lfd.planning.training import train_on_random_tasks

    from drake_lfd.planning.training import DEFAULT_CHAINED_TASKS

    chained = DEFAULT_CHAINED_TASKS if args.chained_tasks is None else args.chained_tasks
    require_at_least(args.random_tasks, 0, "--random-tasks")
    require_at_least(args.episodes, 1, "--episodes")
    require_at_least(chained, 0, "--chained-tasks")
    if args.random_tasks + chained == 0:
        raise InputError("needs at least one training task", field="--random-tasks")
    require_seed(args.seed)
    require_folder_of(args.out, "--out")
    out = Path(args.out)
    library = Library.open(args.library)
    if len(library) == 0:
        raise InputError("the library has no demonstrations", file=library.label)
    warm = load_policy(args.warm_start) if args.warm_start else None
    library.write_feature_caches()
    features = library_features(library)
    bar = ProgressBar("training", args.episodes)
    result = train_on_random_tasks(
        features, num_tasks=args.random_tasks, num_chained_tasks=chained, episodes=args.episodes, seed=args.seed,
        warm_start=warm, progress=lambda done, total: bar.update(done),
    )
    bar.close()
    steady = episodes_to_steady(result.greedy_curve)
    save_policy(result.policy, out)
    figure = training_curve_figure(curve_figure_path(out), result.greedy_curve, steady_episode=steady,
                                   exploring=result.curve)
    summary = {
        "library": library.label,
        "tasks": args.random_tasks,
        "chained_tasks": chained,
        "episodes": args.episodes,
        "seed": args.seed,
        "warm_start": args.warm_start,
        "wall_time_s": result.wall_time_s,
        "episodes_to_steady": steady,
        "final_average_reward": float(result.greedy_curve[-10:].mean()),
        "curve": [float(v) for v in result.greedy_curve],
        "exploring_curve": [float(v) for v in result.curve],
        "policy": str(out.resolve()),
        "figure": str(figure.resolve()),
        "table_entries": len(result.policy.values),
    }
    if args.json:
        atomic_write_json(Path(args.json), summary)
    print(f"trained on {args.random_tasks} random + {chained} chained tasks x {args.episodes} episodes in "
          f"{result.wall_time_s:.2f} s (steady after {steady} episodes); wrote {out} and {figure}")
    return 0
