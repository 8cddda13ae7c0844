"""``drake-lfd train``: Q-learning of a general policy on random tasks (Algorithm 1).

A thin front end (docs/cli.rst): it loads the library, refreshes its feature caches,
trains and writes the policy and its curve. Not for: the learning itself
(:mod:`drake_lfd.planning.training`, :mod:`drake_lfd.planning.q_learning`).
"""

from __future__ import annotations

from pathlib import Path

from drake_lfd.cli.argument_checks import library_help, prepare_output, require_at_least, require_seed
from drake_lfd.cli.startup import interrupts_deferred
from drake_lfd.core.errors import InputError
from drake_lfd.core.option_values import DEFAULT_CHAINED_TASKS


__all__ = ["add_parser", "curve_figure_path", "run", "training_title"]


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
    parser.add_argument("--library", required=True, metavar="LIB", help=library_help() + ", with demonstrations")
    parser.add_argument("--random-tasks", type=int, default=20, metavar="N",
                        help="the paper's Section 6.2 random training tasks, >= 0")
    parser.add_argument(
        "--chained-tasks", type=int, default=DEFAULT_CHAINED_TASKS, metavar="M",
        help="also train on M tasks chained from the library's demonstrations (0: the paper's "
             "random tasks only, which a small library rarely covers); N + M >= 1",
    )
    parser.add_argument("--episodes", type=int, default=100, metavar="E", help="episodes per training task, >= 1")
    parser.add_argument("--seed", type=int, default=0, metavar="S",
                        help="seeds the tasks and the exploration (the same seed gives the same policy)")
    parser.add_argument("--out", required=True, metavar="POLICY",
                        help="policy file to write (JSON; missing folders are created), "
                             "with its curve beside it as POLICY-stem.curve.png")
    parser.add_argument("--warm-start", metavar="POLICY", help="start from this saved policy's table")
    parser.add_argument("--json", metavar="OUT",
                        help="write the training summary as JSON (missing folders are created)")
    parser.set_defaults(func=run)


def curve_figure_path(policy_path: Path) -> Path:
    return policy_path.with_name(policy_path.stem + ".curve.png")


def training_title(random_tasks: int, chained_tasks: int, library: str, *, warm_start: bool = False) -> str:
    """The title of a user's training curve, describing the run: ``"Q-learning on 20 random
    + 5 chained tasks, library mylib, warm start"`` (the paper's Fig. 7 is
    ``drake-lfd paper``'s figure, not this one)."""
    parts = [f"{random_tasks} random"] if random_tasks else []
    if chained_tasks:
        parts.append(f"{chained_tasks} chained")
    tasks = " + ".join(parts) + (" task" if random_tasks + chained_tasks == 1 else " tasks")
    return f"Q-learning on {tasks}, library {library}" + (", warm start" if warm_start else "")


def run(args) -> int:
    chained = DEFAULT_CHAINED_TASKS if args.chained_tasks is None else args.chained_tasks
    require_at_least(args.random_tasks, 0, "--random-tasks")
    require_at_least(args.episodes, 1, "--episodes")
    require_at_least(chained, 0, "--chained-tasks")
    if args.random_tasks + chained == 0:
        raise InputError("needs at least one training task", field="--random-tasks")
    require_seed(args.seed)
    out = prepare_output(args.out, "--out")
    prepare_output(args.json, "--json")
    with interrupts_deferred():
        import numpy as np

        from drake_lfd.experiments.figures import training_curve_figure
        from drake_lfd.io.library import Library, library_features
        from drake_lfd.cli.progress import ProgressBar
        from drake_lfd.io.policy_files import load_policy, save_policy
        from drake_lfd.io.strict_json import write_json
        from drake_lfd.planning.q_learning import episodes_to_steady, never_steady
        from drake_lfd.planning.training import train_on_random_tasks
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
    # None when the greedy curve never settles (planning.q_learning.never_steady).
    steady = None if never_steady(result.greedy_curve) else episodes_to_steady(result.greedy_curve)
    save_policy(result.policy, out)
    figure = training_curve_figure(curve_figure_path(out), result.greedy_curve, steady_episode=steady,
                                   exploring=result.curve,
                                   title=training_title(args.random_tasks, chained, Path(args.library).name,
                                                        warm_start=warm is not None))
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
        write_json(Path(args.json), summary)
    if steady is None:
        spread = float(np.ptp(result.greedy_curve[-10:]))
        steadiness = (f"not steady within {args.episodes} episodes: the greedy reward still changed by "
                      f"{spread:.2g} over the last {min(10, args.episodes)}")
    else:
        steadiness = f"steady after {steady} episodes"
    print(f"trained on {args.random_tasks} random + {chained} chained tasks x {args.episodes} episodes in "
          f"{result.wall_time_s:.2f} s ({steadiness}); wrote {out} and {figure}")
    return 0
