"""``drake-lfd paper``: the paper's Section 6 end to end, with a report.

The output folder is checked for writability before any work; every closed-loop trial is
kept in ``DIR/trials.jsonl`` as it finishes (:mod:`drake_lfd.experiments.paper`).
"""

from __future__ import annotations

from drake_lfd.cli.argument_checks import prepare_output, require_at_least, require_seed
from drake_lfd.cli.shared_options import workers_of, workers_parent
from drake_lfd.cli.startup import interrupts_deferred

__all__ = ['add_parser', 'run']


def add_parser(subparsers) -> None:
    parser = subparsers.add_parser(
        "paper",
        parents=[workers_parent()],  # the closed-loop trials only; the training stays in this process
        help="reproduce the paper's Section 6 (training, three tasks, a request) with a report",
        description=(
            "Train on 20 random tasks, run the transferring, filling-and-pouring and assembling "
            "tasks closed loop (assembling first with 5 demonstrations, then with the sixth), and "
            "write results.json, report.md, figures and Meshcat recordings into DIR."
        ),
    )
    parser.add_argument("--out", default="paper_results", metavar="DIR",
                        help="output folder for report.md, results.json, trials.jsonl (each trial as it finishes), "
                             "figures and recordings (created if missing)")
    parser.add_argument("--trials", type=int, default=20, metavar="N", help="closed-loop trials per task, >= 1")
    parser.add_argument("--seed", type=int, default=0, metavar="S", help="seeds the training and the trials")
    parser.add_argument("--refine", action="store_true",
                        help="refine every closed-loop trial's plan by trajectory optimization "
                             "(docs/method.rst, Refinement by trajectory optimization) (default: off)")
    parser.set_defaults(func=run)


def run(args) -> int:
    import sys

    require_at_least(args.trials, 1, "--trials")
    require_seed(args.seed)
    workers = workers_of(args, args.trials)
    out = prepare_output(args.out, "--out", folder=True)
    with interrupts_deferred():
        from drake_lfd.experiments.paper import PAPER_OPTIONS, run_paper

    def log(line):
        print(line, file=sys.stderr, flush=True)

    where = {} if workers == 1 and args.scheduler is None else {"workers": workers, "scheduler": args.scheduler}
    options = PAPER_OPTIONS.replace(refine=args.refine)
    results = run_paper(out, trials=args.trials, seed=args.seed, log=log, options=options, **where)
    tasks = results["tasks"]
    print(f"transferring {tasks['transferring']['success_count']}/{args.trials}, filling and pouring "
          f"{tasks['filling_pouring']['success_count']}/{args.trials}, assembling: "
          f"{tasks['assembling']['initial_status']} with 5 demonstrations, then "
          f"{tasks['assembling']['after_new_demo']['success_count']}/{args.trials} with span; "
          f"{results['wall_time_s']:.0f} s. Report: {out / 'report.md'}")
    return 0
