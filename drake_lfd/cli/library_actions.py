"""What ``drake-lfd library add|show|copy|remove`` do (the parser is :mod:`drake_lfd.cli.library`).

A thin front end over :mod:`drake_lfd.io.library` (documented in docs/cli.rst):

- ``library add LIB DEMO --name NAME [--description TEXT]`` reads a UR RTDE joint
  log (or the project's own CSV), or a ROS 1/2 bag of ``sensor_msgs/JointState``
  (:mod:`drake_lfd.io.log_import`: ``--rate``, ``--topic``, ``--start``/``--end``,
  ``--tcp-offset``, whose report goes to stdout), and adds it. If ``LIB`` does not exist (or is an empty
  directory) and is not a bundled library's name, a new library is created there, with
  the end-effector frame ``X_tool0_E`` given by ``--tool0-E-p X Y Z`` and
  ``--tool0-E-euler-zyx YAW PITCH ROLL`` (radians; ``pi/2`` or ``90deg`` forms
  accepted); both are required then, so no library gets the identity by accident. An
  existing library keeps its frame: the options may be left out, and any given must
  match it (they can never change it: that would silently invalidate every feature). ``--keep-all-rows``
  skips the ``runtime_state`` filter. Warnings about the log (a cut-off last line that
  was dropped) go to stderr after a successful add; a refused add prints one error line
  and leaves the library exactly as it was (a refused add to a new directory creates
  nothing). Concurrent ``add`` and ``remove`` on one library take turns (the library's
  lock, :mod:`drake_lfd.io.library`).
- ``library add LIB DEMO_OR_DIR_OR_GLOB...`` without ``--name`` adds every log the
  arguments name (files, folders, glob patterns: :func:`~drake_lfd.io.bulk_add.find_logs`),
  each named after its file's stem, the other options applying to all; a progress bar on
  a terminal; every valid log added (in batches, each one turn of the library's lock:
  :func:`~drake_lfd.io.bulk_add.add_logs`, which ``Library.add_many`` runs too), each
  other one refused with one line naming it and why, then one summary line; exit 0 when
  all were added, 2 when any was refused.
- ``library show LIB [--json OUT]`` prints a table: per demonstration its samples,
  duration and the rotation of its feature at the start, middle and three quarters of
  the way (``delta`` at 0, 50 and 75 % of the resampled motion, like the paper's Table
  5), as a quaternion (w, x, y, z) and as axis-angle, with the direction of the delta's
  translation (in the frame of that sample). ``--json OUT`` also writes the
  machine-readable listing, strict JSON written atomically (``-`` writes it to stdout
  instead of the table). First it
  writes the missing or stale feature caches of a user's library
  (``Library.write_feature_caches``; reading a library writes nothing by itself). It
  also names the bundled libraries and where they are installed.
- ``library copy SRC DIR`` makes an editable copy of a bundled library (or of any
  library directory) in a new or empty directory (``io.library.copy_library``).
- ``library remove LIB NAME`` removes one demonstration; it works on an entry whose
  joint log is missing or disagrees with the manifest (which every other command
  refuses), so the command line can repair a library.

Not for: the library's files and their guarantees (:mod:`drake_lfd.io.library`), the
other commands (one module each in ``drake_lfd/cli``).
"""

from __future__ import annotations

import math
import os
import sys
from pathlib import Path

import numpy as np

from drake_lfd.core.quaternion import axis_angle_from_quaternion
from drake_lfd.core.errors import EXIT_BAD_INPUT, EXIT_OK, InputError
from drake_lfd.core.tasks import rigid_transform_from_euler_zyx
from drake_lfd.cli.argument_checks import prepare_output
from drake_lfd.cli.library import IDENTITY_FRAME_OPTIONS
from drake_lfd.cli.progress import ProgressBar
from drake_lfd.io.atomic_files import atomic_write_bytes
from drake_lfd.io.feature_cache import SUMMARY_FRACTIONS as CACHED_SUMMARY_FRACTIONS
from drake_lfd.io.feature_cache import feature_summary_rows, summary_indices
from drake_lfd.io.bulk_add import LogReadOptions, add_logs, find_logs
from drake_lfd.io.log_import import read_demonstration_log
from drake_lfd.io.library import (
    END_EFFECTOR_FRAME_TOLERANCE,
    Library,
    bundled_library_names,
    bundled_library_paths,
    collection_paused,
    copy_library,
    is_unused_library_directory,
    tool_frame_options,
)
from drake_lfd.io.library_manifest import check_demo_name
from drake_lfd.io.pose_records import pose_json_from_rigid_transform
from drake_lfd.io.strict_json import strict_json_text
from drake_lfd.io.yaml_values import angle_from_text

__all__ = [
    "SUMMARY_FRACTIONS",
    "run_add",
    "run_bulk_add",
    "find_logs",
    "feature_summary",
    "library_listing",
    "format_listing",
    "run_show",
    "run_copy",
    "run_remove",
]

# Where along the feature ``show`` samples its rotation (fractions of the deltas; the feature
# cache stores each feature's numbers there, io/feature_cache.py).
SUMMARY_FRACTIONS = tuple(zip(("start", "middle", "late"), CACHED_SUMMARY_FRACTIONS))


# --------------------------------------------------------------------------------- add


def _requested_tool_frame(args):
    """The options' X_tool0_E parts: (position or None, euler_zyx or None), checked."""
    p = None if args.tool0_E_p is None else [float(v) for v in args.tool0_E_p]
    if p is not None and not all(math.isfinite(v) for v in p):
        raise InputError(f"{p} is not a finite position", field="--tool0-E-p")
    euler = None
    if args.tool0_E_euler_zyx is not None:
        euler = []
        for index, text in enumerate(args.tool0_E_euler_zyx):
            value = angle_from_text(text)
            if value is None or not math.isfinite(value):
                raise InputError(f"{text!r} is not an angle", field=f"--tool0-E-euler-zyx[{index}]")
            euler.append(value)
    return p, euler


def _new_library_frame(args, p, euler):
    """A new library's X_tool0_E: both options are required (no silent identity)."""
    if p is None or euler is None:
        missing = " and ".join(
            name for name, value in (("--tool0-E-p X Y Z", p), ("--tool0-E-euler-zyx YAW PITCH ROLL", euler))
            if value is None
        )
        raise InputError(
            f"a new library needs its end-effector frame: give {missing} (E on tool0: metres, and "
            f"R = Rz(yaw) Ry(pitch) Rx(roll)); E = tool0, the identity, is {IDENTITY_FRAME_OPTIONS}; "
            "the paper scenarios' frame (sims/*.yaml) is --tool0-E-p 0 0 0.2 --tool0-E-euler-zyx 0 pi/2 0",
            file=args.library,
            field="X_tool0_E",
        )
    return rigid_transform_from_euler_zyx(p, euler)


def _check_same_frame(library, p, euler):
    """Options given for an existing library must match its frame, part by part."""
    ours = library.X_tool0_E
    differs = False
    if p is not None:
        differs |= bool(np.max(np.abs(np.asarray(p) - ours.translation())) > END_EFFECTOR_FRAME_TOLERANCE)
    if euler is not None:
        rotation = rigid_transform_from_euler_zyx([0.0, 0.0, 0.0], euler).rotation().matrix()
        differs |= bool(np.max(np.abs(rotation - ours.rotation().matrix())) > END_EFFECTOR_FRAME_TOLERANCE)
    if differs:
        raise InputError(
            f"the library was recorded with the end-effector frame {tool_frame_options(ours)}, and a "
            "library's frame never changes; leave the options out to add with that frame, or add to a "
            "new library directory to record with another",
            file=library.label,
            field="X_tool0_E",
        )


def _is_new_library(path_text):
    path = Path(path_text)
    if path.is_dir():
        return is_unused_library_directory(path)
    return not path.exists() and path_text not in bundled_library_names()


def run_add(args):
    if args.name is None:
        return run_bulk_add(args)
    if len(args.log) != 1:
        raise InputError(
            f"names one demonstration but {len(args.log)} logs were given; add one log with --name, or leave "
            "--name out to add every log, each named after its file's stem",
            file=args.library,
            field="--name",
        )
    args.log = args.log[0]
    p, euler = _requested_tool_frame(args)
    # Everything that can refuse the add runs before the library is touched.
    new = _is_new_library(args.library)
    X_tool0_E = _new_library_frame(args, p, euler) if new else None
    try:
        check_demo_name(args.name)
    except InputError as error:  # the option, and the library it was meant for
        raise InputError(error.problem, file=args.library, field="--name") from None
    demonstration, warnings, reports = read_demonstration_log(
        args.log, name=args.name, description=args.description, filter_runtime_state=not args.keep_all_rows,
        rate_hz=args.rate, topic=args.topic, start_s=args.start, end_s=args.end, tcp_offset=args.tcp_offset,
    )
    if new:  # checks the demonstration before it creates anything
        library, entry = Library.create_with(
            args.library, demonstration, args.name, args.description, X_tool0_E=X_tool0_E, source=args.log
        )
    else:
        library = Library.open(args.library)
        if not library.read_only:  # a bundled one is refused for that, with a hint to copy it
            _check_same_frame(library, p, euler)
        entry = library.add(demonstration, args.name, args.description, source=args.log)
    for warning in warnings:
        print(f"drake-lfd library: warning: {warning}", file=sys.stderr)
    for report in reports:
        print(report)
    print(
        f"added {entry.name!r} to {library.label}: {entry.samples} samples, "
        f"{entry.duration_s:.3f} s"
    )
    return EXIT_OK


# --------------------------------------------------------------------------- bulk add


def run_bulk_add(args):
    """``library add LIB DIR_OR_GLOB...`` without ``--name`` (docs/cli.rst): the options
    checked, :func:`~drake_lfd.io.bulk_add.add_logs` run with a progress bar, its report
    printed (the logs' warnings and reports, one line per refusal, a summary line)."""
    p, euler = _requested_tool_frame(args)
    new = _is_new_library(args.library)
    X_tool0_E = _new_library_frame(args, p, euler) if new else None
    options = LogReadOptions(keep_all_rows=args.keep_all_rows, rate_hz=args.rate, topic=args.topic,
                             start_s=args.start, end_s=args.end, tcp_offset=args.tcp_offset)
    bars = []

    def progress(done, total, accepted, refused):
        if not bars:
            bars.append(ProgressBar("adding", total, quiet_unless_terminal=True))
        if done:
            bars[0].update(done, f"{accepted} accepted, {refused} refused")

    report = add_logs(args.library, args.log, args.description, X_tool0_E=X_tool0_E, options=options,
                      progress=progress, before_adding=lambda library: _check_same_frame(library, p, euler))
    for bar in bars:
        bar.close()
    for added in report.added:
        for warning in added.warnings:
            print(f"drake-lfd library: warning: {warning}", file=sys.stderr)
        for text in added.reports:
            print(text)
    for refusal in report.refused:
        print(f"drake-lfd library: refused {refusal.path}: {refusal.reason}", file=sys.stderr)
    label = report.library.label if report.library is not None else args.library
    summary = f"added {len(report.added)} of {report.logs} logs to {label}"
    if report.refused:
        counts = report.refusal_counts()
        summary += f"; refused {len(report.refused)}: " + ", ".join(f"{n} {kind}" for kind, n in counts.items())
        if report.library is None:
            summary += " (no library was created)"
    print(summary)
    return EXIT_OK if not report.refused else EXIT_BAD_INPUT


# -------------------------------------------------------------------------------- show


def feature_summary(feature):
    """Rotation (and translation direction) of a feature at a few points, as in Table 5.

    Parameters
    ----------
    feature : Feature
        With n - 1 deltas.

    Returns
    -------
    rows : list of dict
        One per :data:`SUMMARY_FRACTIONS`: ``label``, ``delta`` (1-based index),
        ``q_wxyz``, ``axis``, ``angle_rad``, ``translation_m`` (in the frame of that
        sample).
    """
    return _feature_summaries([(len(feature), *feature_summary_rows(feature))])[0]


def _feature_summaries(summaries):
    """:func:`feature_summary` of many features, given as ``(num_deltas, rotations,
    translations)`` (``Library.feature_summaries``); the axis-angles of all at once."""
    if not summaries:
        return []
    axis, angle = axis_angle_from_quaternion(np.array([rotations for _, rotations, _ in summaries], dtype=float))
    axis, angle = axis.tolist(), angle.tolist()
    labels = [label for label, _ in SUMMARY_FRACTIONS]
    return [
        [
            {"label": label, "delta": index + 1, "q_wxyz": list(rotations[j]), "axis": axis[i][j],
             "angle_rad": angle[i][j], "translation_m": list(translations[j])}
            for j, (label, index) in enumerate(zip(labels, summary_indices(num_deltas)))
        ]
        for i, (num_deltas, rotations, translations) in enumerate(summaries)
    ]


def library_listing(library):
    """The ``library show --json`` document (docs/cli.rst), plus optional fields:
    ``read_only``, ``directory``, ``bundled_libraries``, and per demonstration ``added``
    and ``feature`` (resampled sample count and :func:`feature_summary`)."""
    # One query for all, 168 bytes of each feature: not one file (or feature) per demonstration.
    rows = library.feature_summaries()
    entries = library.entries
    summaries = _feature_summaries([rows[entry.name] for entry in entries])
    directory = str(library.path)
    demos = [
        {
            "name": entry.name,
            "path": os.path.join(directory, entry.file),
            "samples": entry.samples,
            "duration_s": entry.duration_s,
            "description": entry.description,
            "added": entry.added,
            "feature": {"samples": rows[entry.name][0] + 1, "summary": summary},
        }
        for entry, summary in zip(entries, summaries)
    ]
    return {
        "library": library.label,
        "X_tool0_E": pose_json_from_rigid_transform(library.X_tool0_E),
        "X_tool0_E_options": tool_frame_options(library.X_tool0_E),
        "read_only": library.read_only,
        "directory": str(library.path),
        "bundled_libraries": [{"name": name, "directory": str(path)} for name, path in bundled_library_paths().items()],
        "demos": demos,
    }


def _format_vector(values, digits=3):
    return "(" + ", ".join(f"{v:+.{digits}f}" for v in values) + ")"


# The rows of a listing, formatted with one %-format each (a library may list 10,000).
_Q_FORMAT = "(%+.3f, %+.3f, %+.3f, %+.3f)"
_AXIS_FORMAT = "(%+.2f, %+.2f, %+.2f)"


def format_listing(listing):
    """The human-readable table of a :func:`library_listing`, as one string."""
    pose = listing["X_tool0_E"]
    lines = [
        f"library {listing['library']}" + (
            f"  (bundled, read-only, installed in {listing['directory']}; editable copy: "
            f"drake-lfd library copy {listing['library']} DIR)" if listing["read_only"] else ""),
        f"X_tool0_E: p = {_format_vector(pose['p'])} m, q_wxyz = {_format_vector(pose['q_wxyz'])}"
        + (f"  ({listing['X_tool0_E_options']})" if "X_tool0_E_options" in listing else ""),
    ]
    bundled = ", ".join(f"{b['name']} ({b['directory']})" for b in listing.get("bundled_libraries", ()))
    footer = f"bundled libraries: {bundled}" if bundled else "no bundled libraries installed"
    if not listing["demos"]:
        lines.append("no demonstrations yet")
        lines.append(footer)
        return "\n".join(lines)
    width = max(4, *(len(demo["name"]) for demo in listing["demos"]))
    lines.append(
        f"{'name':<{width}}  {'samples':>7}  {'duration_s':>10}  {'delta':<12}  "
        f"{'rotation q_wxyz':<34}  {'axis-angle':<34}   translation direction"
    )
    for demo in listing["demos"]:
        for row_index, row in enumerate(demo["feature"]["summary"]):
            if row_index == 0:
                head = f"{demo['name']:<{width}}  {demo['samples']:>7}  {demo['duration_s']:>10.3f}"
            else:
                head = " " * (width + 2 + 7 + 2 + 10)
            delta = f"{row['label']} ({row['delta']})"
            x, y, z = row["translation_m"]
            length = math.sqrt(x * x + y * y + z * z)
            direction = _AXIS_FORMAT % (x / length, y / length, z / length) if length >= 1e-3 else "(none, < 1 mm)"
            lines.append(
                f"{head}  {delta:<12}  {_Q_FORMAT % tuple(row['q_wxyz']):<34}  "
                f"{math.degrees(row['angle_rad']):6.1f} deg about {_AXIS_FORMAT % tuple(row['axis'])}"
                f"   {direction}"
            )
        if demo["description"]:
            lines.append(" " * (width + 2) + demo["description"])
    lines.append(footer)
    return "\n".join(lines)


def run_show(args):
    library = Library.open(args.library)
    library.write_feature_caches()  # a user's library keeps fresh caches; bundled ones none
    with collection_paused():  # tens of thousands of small dicts and lines, no cycles
        listing = library_listing(library)
    if args.json == "-":
        print(strict_json_text(listing, indent=2))
        return EXIT_OK
    if args.json:
        text = strict_json_text(listing, indent=2)
        output = prepare_output(args.json, "--json")
        try:
            atomic_write_bytes(output, (text + "\n").encode("utf-8"))
        except OSError as error:  # one line naming OUT; a full disk is exit 1 (cli/app.py)
            raise OSError(error.errno, error.strerror or str(error), str(output)) from None
    with collection_paused():
        text = format_listing(listing)
    print(text)
    return EXIT_OK


# -------------------------------------------------------------------------------- copy


def run_copy(args):
    copy = copy_library(args.source, args.destination)
    print(f"copied {args.source} to {copy.label}: {len(copy)} demonstrations, "
          f"X_tool0_E {tool_frame_options(copy.X_tool0_E)}; add to it with "
          f"drake-lfd library add {args.destination} DEMO.csv --name NAME")
    return EXIT_OK


# ------------------------------------------------------------------------------ remove


def run_remove(args):
    # Not checked against the logs: removing an entry whose log is gone repairs the library.
    library = Library.open(args.library, check_logs=False)
    library.remove(args.name)
    print(f"removed {args.name!r} from {library.label}")
    return EXIT_OK

