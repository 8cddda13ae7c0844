"""``drake-lfd show-model``: write a Meshcat HTML animation of the shipped UR5e."""

from __future__ import annotations

from drake_lfd.cli.argument_checks import prepare_output, require_meshcat
from drake_lfd.cli.startup import interrupts_deferred
from drake_lfd.core.errors import InputError

__all__ = ['add_parser', 'run']


def add_parser(subparsers) -> None:
    parser = subparsers.add_parser(
        "show-model",
        help="write a standalone Meshcat HTML of the UR5e moving through configurations",
        description="Write a self-contained Meshcat HTML animation of drake-lfd's UR5e model.",
    )
    parser.add_argument("--out", default="ur5e.html", metavar="OUT",
                        help="output HTML file (missing folders are created)")
    parser.add_argument(
        "--q", nargs=6, type=float, action="append", metavar="Q",
        help="a joint configuration in radians (repeat for keyframes); without it, a showcase",
    )
    parser.set_defaults(func=run)


def run(args) -> int:
    with interrupts_deferred():
        import numpy as np

        from drake_lfd.diagrams.model_preview import SHOWCASE_CONFIGURATIONS, write_configurations_html

    q_keyframes = SHOWCASE_CONFIGURATIONS if not args.q else np.array(args.q)
    if not np.all(np.isfinite(q_keyframes)):
        raise InputError("joint angles must be finite numbers", field="--q")
    require_meshcat("show-model", optional=False)
    out = prepare_output(args.out, "--out")
    write_configurations_html(out, q_keyframes)
    print(f"wrote {out} ({out.stat().st_size / 1e6:.1f} MB); open it in a browser")
    return 0
