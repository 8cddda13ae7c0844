"""``drake-lfd record SCRIPT.yaml --out DEMO.csv``: a simulated kinesthetic demonstration.

Loads a guidance script (``kinesthetic.py`` documents the format), simulates the
free-driven UR5e guided by the virtual hand, and writes the measured joints as the
project's RTDE-style CSV (``timestamp, actual_q_0 .. actual_q_5``), atomically: a
temporary file beside ``DEMO.csv``, fsynced, then renamed over it. Progress goes to
stderr, the one-line summary to stdout.
"""

from __future__ import annotations

import math
import sys

from drake_lfd.cli.argument_checks import prepare_output
from drake_lfd.cli.startup import interrupts_deferred

__all__ = ['add_parser', 'run']


def add_parser(subparsers) -> None:
    parser = subparsers.add_parser(
        "record",
        help="simulate a kinesthetic demonstration on the UR5e and write its joint log (RTDE-style CSV)",
        description=(
            "Simulate a kinesthetic demonstration: a virtual hand guides the UR5e in free drive "
            "(gravity compensation and joint damping, no position control) along the waypoints of "
            "a guidance script, and the measured joints are logged at the script's rate "
            "(500 Hz, as the UR's RTDE interface) into an RTDE-style CSV."
        ),
    )
    parser.add_argument("script", metavar="SCRIPT.yaml", help="guidance script (YAML)")
    parser.add_argument("--out", required=True, metavar="DEMO.csv",
                        help="joint log to write (replaced atomically; missing folders are created)")
    parser.add_argument("--quiet", action="store_true", help="do not print progress")
    parser.set_defaults(func=run)


def run(args) -> int:
    with interrupts_deferred():
        from drake_lfd.diagrams.kinesthetic import record_demonstration
        from drake_lfd.io.demonstration_logs import write_rtde_csv
        from drake_lfd.io.guidance_scripts import load_guidance_script
    script = load_guidance_script(args.script)
    out = prepare_output(args.out, "--out")

    def progress(t, duration):
        print(f"  simulated {t:.1f} / {duration:.1f} s", file=sys.stderr, flush=True)

    if not args.quiet:
        print(
            f"recording {script.name}: {len(script.waypoints)} waypoints, {script.duration_s:.1f} s "
            f"at {script.sample_rate_hz:g} Hz (seed {script.seed})",
            file=sys.stderr,
            flush=True,
        )
    result = record_demonstration(script, progress=None if args.quiet else progress)
    write_rtde_csv(result.demonstration, out)
    demo = result.demonstration
    print(
        f"wrote {out}: {demo.num_samples} samples over {demo.duration_s:.2f} s; the tool stayed within "
        f"{1000 * result.max_position_error_m:.1f} mm / {math.degrees(result.max_rotation_error_rad):.1f} deg "
        f"of the hand and ended {1000 * result.final_position_error_m:.2f} mm / "
        f"{math.degrees(result.final_rotation_error_rad):.2f} deg from the last waypoint "
        f"({result.wall_time_s:.1f} s wall)"
    )
    return 0
