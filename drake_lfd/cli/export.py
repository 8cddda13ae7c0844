"""``drake-lfd export``: a planned joint trajectory as files a real UR5e can run.

A thin front end (docs/cli.rst): reads a ``plan --json`` document, resamples and checks
its joint trajectory (:mod:`drake_lfd.io.trajectory_export`) and only then writes, each
file atomically, the URScript program (:mod:`drake_lfd.io.urscript`), the RTDE-layout
CSV and the ROS 2 JointTrajectory YAML asked for.
"""

from __future__ import annotations

import math

from drake_lfd.cli.argument_checks import prepare_output
from drake_lfd.core.errors import InputError

__all__ = ["add_parser", "run"]


def _positive_number(text: str) -> float:
    import argparse

    try:
        value = float(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"{text!r} is not a number") from None
    if not math.isfinite(value):
        raise argparse.ArgumentTypeError(f"{text!r} is not a finite number")
    return value


def add_parser(subparsers) -> None:
    from drake_lfd.io.urscript import DEFAULT_GAIN, DEFAULT_LOOKAHEAD_TIME_S

    parser = subparsers.add_parser(
        "export",
        help="write a planned joint trajectory as URScript, RTDE CSV or ROS 2 YAML for a real UR5e",
        description=(
            "Export the joint trajectory of a plan --json document for a real UR5e, resampled to the "
            "e-Series controller period (2 ms). Speeds, accelerations and the start configuration are "
            "checked against the UR5e's limits before anything is written; a violation is refused "
            "(exit 2). Without an output option only the check runs. Run the program in URSim first "
            "(docs/cli.rst: running it on a real UR5e)."
        ),
    )
    parser.add_argument("plan", metavar="PLAN.json", help="a plan --json document with status 'planned'")
    parser.add_argument("--urscript", metavar="OUT.script",
                        help="write a URScript program: movej to the start, servoj every 2 ms, stopj "
                             "(default: not written)")
    parser.add_argument("--csv", metavar="OUT.csv",
                        help="write the 2 ms targets as an RTDE-layout CSV (timestamp, target_q_0..5, "
                             "actual_q_0..5) (default: not written)")
    parser.add_argument("--ros2", metavar="OUT.yaml",
                        help="write a ROS 2 trajectory_msgs/JointTrajectory YAML for ur_robot_driver's "
                             "joint trajectory controller (default: not written)")
    parser.add_argument("--joint-prefix", default="", metavar="PREFIX",
                        help="put PREFIX before the ROS 2 joint names (ur_ gives ur_shoulder_pan_joint) "
                             "(default: none)")
    parser.add_argument("--slow-down", type=_positive_number, default=1.0, metavar="S",
                        help="run the plan S times slower (S >= 1; a refusal names the least S that fits)")
    parser.add_argument("--lookahead-time", type=_positive_number, default=DEFAULT_LOOKAHEAD_TIME_S,
                        metavar="SECONDS", help="servoj lookahead_time, 0.03-0.2 s")
    parser.add_argument("--gain", type=_positive_number, default=DEFAULT_GAIN, metavar="G",
                        help="servoj gain, 100-2000")
    parser.set_defaults(func=run)


def run(args) -> int:
    from drake_lfd.io.atomic_files import atomic_write_bytes
    from drake_lfd.io.trajectory_export import (
        check_limits,
        load_plan_trajectory,
        resample,
        ros2_joint_names,
        ros2_trajectory_yaml,
        rtde_csv_text,
    )
    from drake_lfd.io.urscript import check_servoj_parameters, urscript_program

    check_servoj_parameters(args.lookahead_time, args.gain)
    ros2_joint_names(args.joint_prefix)
    if args.slow_down < 1.0:
        raise InputError(f"must be >= 1 (a plan is never sped up), not {args.slow_down:g}", field="--slow-down")
    for option in ("--urscript", "--csv", "--ros2"):
        if getattr(args, option.lstrip("-")) == "-":
            raise InputError("give a file name (not -)", field=option)
    outputs = {option: prepare_output(getattr(args, option.lstrip("-")), option)
               for option in ("--urscript", "--csv", "--ros2")}
    plan = load_plan_trajectory(args.plan)
    trajectory = resample(plan, args.slow_down)
    fractions = check_limits(trajectory, file=args.plan, plan=plan)
    # Everything is checked: now write (each file atomically).
    texts = {}
    if outputs["--urscript"] is not None:
        texts["--urscript"] = urscript_program(trajectory, lookahead_time_s=args.lookahead_time, gain=args.gain)
    if outputs["--csv"] is not None:
        texts["--csv"] = rtde_csv_text(trajectory)
    if outputs["--ros2"] is not None:
        texts["--ros2"] = ros2_trajectory_yaml(trajectory, joint_prefix=args.joint_prefix)
    for option, text in texts.items():
        atomic_write_bytes(outputs[option], text.encode("utf-8"))
    print(f"{plan.task}: {len(trajectory.t)} targets every 2 ms over {trajectory.duration_s:.2f} s "
          f"(plan time x {trajectory.slow_down:g}); largest joint speed {fractions['speed_fraction']:.0%} "
          f"and acceleration {fractions['acceleration_fraction']:.0%} of the UR5e's limits")
    for option, path in outputs.items():
        if path is not None:
            print(f"  {option.lstrip('-')}: {path}")
    if not texts:
        print("  (checked only: --urscript, --csv or --ros2 write the files)")
    return 0
