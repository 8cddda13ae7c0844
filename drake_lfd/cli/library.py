"""``drake-lfd library add|show|copy|remove``: the parser of the library commands.

Its options, help texts and the bundled libraries' names, in plain Python, so ``drake-lfd
library add --help`` and a bad flag answer before Drake loads. Each action's work is in
:mod:`drake_lfd.cli.library_actions` (documented there and in docs/cli.rst), imported when
the action runs.

Not for: the work of the actions, the library's files (:mod:`drake_lfd.io.library`).
"""

from __future__ import annotations

from drake_lfd.cli.startup import interrupts_deferred
from drake_lfd.core.resources import bundled_library_names, bundled_library_paths

__all__ = ["add_parser", "run_add", "run_show", "run_copy", "run_remove", "bundled_libraries_text",
           "IDENTITY_FRAME_OPTIONS"]

#: What a new library's frame is asked for with (docs/cli.rst, library add).
IDENTITY_FRAME_OPTIONS = "--tool0-E-p 0 0 0 --tool0-E-euler-zyx 0 0 0"


def add_parser(subparsers):
    parser = subparsers.add_parser(
        "library",
        help="add, list, copy or remove demonstrations of a library directory",
        description="Manage a demonstration library (a directory with library.json, demos/, cache/).",
        epilog=bundled_libraries_text(),
    )
    actions = parser.add_subparsers(dest="library_command", metavar="ACTION", required=True)

    add = actions.add_parser(
        "add",
        help="add a demonstration (RTDE CSV joint log, or ROS 1/2 bag of sensor_msgs/JointState) to a library, "
             "or many at once",
        description=(
            "Add a demonstration to LIB (DEMO --name NAME), or, without --name, every log that the DEMO "
            "arguments name: log files, folders (their *.csv and *.bag files and ROS 2 bag directories) and "
            "glob patterns ('logs/*.csv'), each named after its file's stem, with a progress bar; every valid "
            "log is added, each other one refused with one line naming it and why, then one summary line "
            "(exit 0 when all were added, 2 when any was refused). The other options apply to every log of "
            "such a bulk add. LIB is created when it does not exist; its end-effector "
            "frame X_tool0_E must then be given with both --tool0-E-p and --tool0-E-euler-zyx "
            f"(E = tool0 is {IDENTITY_FRAME_OPTIONS}). An existing library keeps its frame."
        ),
    )
    add.add_argument("library", metavar="LIB", help="library directory (created if missing)")
    add.add_argument(
        "log",
        metavar="DEMO",
        nargs="+",
        help="UR RTDE CSV joint log (actual_q_0..5, and timestamp or --rate), a ROS 1 .bag file or a ROS 2 bag "
             "directory (sqlite3 or mcap) with sensor_msgs/JointState; without --name, any number of logs, "
             "folders of logs and glob patterns",
    )
    add.add_argument("--name", help="demonstration name: letters, digits, '_', '-' (one DEMO); without it, "
                                    "every log is named after its file's stem")
    add.add_argument("--description", default="", help="what was demonstrated (bulk add: the same for every log)")
    add.add_argument(
        "--tool0-E-p",
        nargs=3,
        type=float,
        metavar=("X", "Y", "Z"),
        help="position of E in tool0 (m); required for a new library, must match an existing one",
    )
    add.add_argument(
        "--tool0-E-euler-zyx",
        nargs=3,
        metavar=("YAW", "PITCH", "ROLL"),
        help="orientation of E in tool0, R = Rz Ry Rx (rad; pi/2 or 90deg accepted; write a negative "
             "angle as a number or add 2*pi); required for a new library, must match an existing one",
    )
    add.add_argument(
        "--keep-all-rows",
        action="store_true",
        help="keep every row of the log (default: only rows with runtime_state 2, PLAYING, if that column exists)",
    )
    add.add_argument("--rate", type=float, metavar="HZ",
                     help="sample rate of an RTDE CSV without a timestamp column (for example 50, 125 or 500)")
    add.add_argument("--topic", metavar="T",
                     help="bag only: the sensor_msgs/JointState topic (default /joint_states)")
    add.add_argument("--start", type=float, metavar="S",
                     help="keep from S seconds after the log's first sample (a bag: its first message)")
    add.add_argument("--end", type=float, metavar="S",
                     help="keep up to S seconds after the log's first sample (a bag: its first message)")
    add.add_argument(
        "--tcp-offset",
        nargs="+",
        type=float,
        metavar="V",
        help="RTDE CSV with actual_TCP_pose_0..5: the robot's TCP on tool0, X Y Z (m) [RX RY RZ (rotation vector, "
             "rad)]; reports how far the joints' forward kinematics is from the logged TCP pose",
    )
    add.set_defaults(func=run_add)

    show = actions.add_parser("show", help="list the demonstrations and their features")
    show.add_argument("library", metavar="LIB",
                      help=f"library directory or bundled library name ({', '.join(bundled_library_names())})")
    show.add_argument("--json", metavar="OUT", help="also write the listing as JSON to OUT ('-': stdout)")
    show.set_defaults(func=run_show)

    copy = actions.add_parser(
        "copy",
        help="make an editable copy of a bundled library (or any library) in a new directory",
        description=(
            "Copy library SRC (a bundled library's name or a library directory) into DIR, which must "
            "not exist or be empty; the copy is yours to add to and remove from."
        ),
        epilog=bundled_libraries_text(),
    )
    copy.add_argument("source", metavar="SRC", help="bundled library name or library directory")
    copy.add_argument("destination", metavar="DIR", help="new (or empty) directory for the copy")
    copy.set_defaults(func=run_copy)

    remove = actions.add_parser("remove", help="remove one demonstration")
    remove.add_argument("library", metavar="LIB", help="library directory")
    remove.add_argument("name", metavar="NAME", help="the demonstration to remove")
    remove.set_defaults(func=run_remove)
    return parser


def bundled_libraries_text():
    """One sentence naming the bundled libraries, where they are installed and how to
    get an editable copy (``library --help``, ``library show``)."""
    paths = bundled_library_paths()
    if not paths:
        return "No bundled libraries are installed."
    listed = ", ".join(f"{name} ({path})" for name, path in paths.items())
    return (f"Bundled libraries (read-only; pass the name as LIB): {listed}. "
            f"Make an editable copy with: drake-lfd library copy {next(iter(paths))} DIR")


def _actions():
    with interrupts_deferred():
        from drake_lfd.cli import library_actions
    return library_actions


def run_add(args):
    """``library add``: one log with ``--name``, else every log the arguments name."""
    return _actions().run_add(args)


def run_show(args):
    """``library show``: the table, or the JSON listing."""
    return _actions().run_show(args)


def run_copy(args):
    """``library copy``: an editable copy of a library."""
    return _actions().run_copy(args)


def run_remove(args):
    """``library remove``: one demonstration out."""
    return _actions().run_remove(args)
