"""UR5e joint logs: RTDE CSV files read, checked and written as demonstrations (Eq. 11).

A demonstration (:class:`~drake_lfd.core.demonstrations.Demonstration`) is a time series
of the six UR5e joint angles, as the robot records it. Users already have logs from
Universal Robots' RTDE interface, so that is the import format: a CSV whose header
names the columns, among them ``timestamp`` and ``actual_q_0`` .. ``actual_q_5``
(radians, joint order shoulder_pan .. wrist_3), separated by spaces (UR's
``record.py``) or commas (``ur_rtde``'s file recording); the separator is sniffed from
the header and any other columns are ignored.

The project's own format is the same CSV with exactly the columns
``timestamp,actual_q_0,...,actual_q_5``, floats written with ``repr`` precision so a
write/read round trip is exact (:func:`write_rtde_csv`).

Choices for real logs:

- ``runtime_state`` (UR's program state: 0 stopping, 1 stopped, 2 playing, 3 pausing,
  4 paused, 5 resuming): when the column is present, only rows with the value 2
  (PLAYING, the robot running its program) are kept, so the lead-in and tail of a
  recording do not become part of the motion. A freedrive demonstration taught with no
  program running has no PLAYING row at all; then every row is kept and a warning says
  so, rather than refusing the log.
- A log cut off mid-line by a crash or a full disk is common. If the *last* line has
  fewer fields than the header, or its last token does not parse and the file does not
  end with a newline, that line is dropped and a warning returned. The same damage
  anywhere else is an error: the file is not a log.
- Joint angles beyond ``2 pi + 0.05`` rad (the UR joint range plus a margin for
  measurement overshoot) are refused: the log is probably in degrees.

Every problem is one :class:`~drake_lfd.core.errors.InputError` naming the file, the line
and column, and what is wrong.

Not for: the demonstration type and its checks (:mod:`drake_lfd.core.demonstrations`),
forward kinematics (:mod:`drake_lfd.robot.kinematics`), features (``features.py``) or
storing demonstrations (``library.py``).
"""

from __future__ import annotations

import math
import re
from pathlib import Path
from typing import NamedTuple

import numpy as np

from drake_lfd.core.demonstrations import JOINT_COLUMNS, NUM_JOINTS, Demonstration, check_joint_value
from drake_lfd.core.errors import InputError
from drake_lfd.io.atomic_files import atomic_write_bytes

__all__ = [
    "TIMESTAMP_COLUMN",
    "RUNTIME_STATE_COLUMN",
    "RUNTIME_STATE_PLAYING",
    "LoadedDemonstration",
    "read_rtde_csv",
    "rtde_csv_text",
    "write_rtde_csv",
]

TIMESTAMP_COLUMN = "timestamp"
RUNTIME_STATE_COLUMN = "runtime_state"
# UR RTDE runtime_state value of a running (playing) program.
RUNTIME_STATE_PLAYING = 2

_JOINT_COLUMN_PATTERN = re.compile(r"^actual_q_(\d+)$")


class LoadedDemonstration(NamedTuple):
    """A demonstration read from a log, and the warnings reading it raised.

    ``warnings`` are one-line messages (for example a cut-off last line that was
    dropped); they do not stop the log from being used.
    """

    demonstration: Demonstration
    warnings: tuple[str, ...]


# ----------------------------------------------------------------------------- reading


def _split(line, delimiter):
    if delimiter is None:
        return line.split()
    return [field.strip() for field in line.split(delimiter)]


def _header_columns(header_line, path):
    delimiter = "," if "," in header_line else None  # None: any run of whitespace
    columns = _split(header_line, delimiter)
    seen = set()
    for column in columns:
        if not column:
            raise InputError("the header has an empty column name", file=path, field="line 1")
        if column in seen:
            raise InputError(f"the header names column {column!r} twice", file=path, field="line 1")
        seen.add(column)
    joint_indices = sorted(
        int(match.group(1)) for match in map(_JOINT_COLUMN_PATTERN.match, columns) if match
    )
    if joint_indices and joint_indices != list(range(NUM_JOINTS)):
        names = ", ".join(f"actual_q_{i}" for i in joint_indices)
        raise InputError(
            f"wrong number of joints: the joint columns are {names} "
            f"({len(joint_indices)} joints); a UR5e log has actual_q_0 .. actual_q_5",
            file=path,
            field="line 1",
        )
    missing = [name for name in (TIMESTAMP_COLUMN,) + JOINT_COLUMNS if name not in columns]
    if missing:
        raise InputError(
            f"missing column(s) {', '.join(missing)} (an RTDE log needs timestamp and "
            "actual_q_0 .. actual_q_5)",
            file=path,
            field="line 1",
        )
    return columns, delimiter


def read_rtde_csv(path, *, name=None, description="", filter_runtime_state=True):
    """Reads a UR RTDE joint log (or the project's own format) as a demonstration.

    Parameters
    ----------
    path : str or Path
        A CSV with a header row naming ``timestamp`` and ``actual_q_0`` ..
        ``actual_q_5``; space- or comma-separated (sniffed); other columns ignored.
    name : str, optional
        The demonstration's name; the file stem by default.
    description : str
        Stored on the demonstration.
    filter_runtime_state : bool
        If the log has a ``runtime_state`` column, keep only rows with the robot
        running its program (:data:`RUNTIME_STATE_PLAYING`); see the module docstring.

    Returns
    -------
    loaded : LoadedDemonstration
        ``(demonstration, warnings)``.

    Raises
    ------
    InputError
        Naming the file, line and column: empty file, missing columns, wrong number of
        joints, a short line before the last, a non-numeric or non-finite cell,
        fewer than 2 samples, timestamps not strictly increasing, angles in degrees.
    """
    path = Path(path)
    try:
        raw = path.read_bytes()
    except FileNotFoundError:
        raise InputError("no such file", file=path) from None
    except IsADirectoryError:
        raise InputError("is a directory, not a joint log", file=path) from None
    except OSError as error:
        raise InputError(f"cannot read: {error.strerror}", file=path) from None
    try:
        text = raw.decode("utf-8-sig")
    except UnicodeDecodeError as error:
        raise InputError(
            f"not a text CSV (byte {error.start} is not UTF-8)", file=path
        ) from None
    ends_with_newline = text.endswith(("\n", "\r"))
    # (line number, text) of every non-blank line; line numbers count from 1.
    lines = [(number, line) for number, line in enumerate(text.splitlines(), start=1) if line.strip()]
    if not lines:
        raise InputError("the file is empty; expected an RTDE CSV log with a header row", file=path)
    header_number, header_line = lines[0]
    columns, delimiter = _header_columns(header_line, path)
    wanted = (TIMESTAMP_COLUMN,) + JOINT_COLUMNS
    wanted_index = [columns.index(column) for column in wanted]
    runtime_index = columns.index(RUNTIME_STATE_COLUMN) if RUNTIME_STATE_COLUMN in columns else None

    warnings = []
    rows = []  # (line number, [t, q0..q5], runtime_state or None)
    data_lines = lines[1:]
    for position, (number, line) in enumerate(data_lines):
        is_last = position == len(data_lines) - 1
        fields = _split(line, delimiter)
        if len(fields) < len(columns) and is_last:
            warnings.append(
                f"{path}: line {number}: the log ends mid-line ({len(fields)} of "
                f"{len(columns)} fields); dropped that line"
            )
            break
        if len(fields) != len(columns):
            raise InputError(
                f"has {len(fields)} fields but the header has {len(columns)}",
                file=path,
                field=f"line {number}",
            )
        values = []
        cut_off = False
        for column_index, column in zip(wanted_index, wanted):
            token = fields[column_index]
            try:
                values.append(float(token))
            except ValueError:
                if is_last and not ends_with_newline and column_index == len(columns) - 1:
                    cut_off = True
                    break
                raise InputError(
                    f"{token!r} is not a number", file=path, field=f"line {number}, column {column}"
                ) from None
        runtime_state = None
        if not cut_off and runtime_index is not None:
            token = fields[runtime_index]
            try:
                runtime_state = float(token)
            except ValueError:
                if not (is_last and not ends_with_newline and runtime_index == len(columns) - 1):
                    raise InputError(
                        f"{token!r} is not a number",
                        file=path,
                        field=f"line {number}, column {RUNTIME_STATE_COLUMN}",
                    ) from None
                cut_off = True
        if cut_off:
            warnings.append(
                f"{path}: line {number}: the log ends mid-value ({fields[-1]!r} without a "
                "newline); dropped that line"
            )
            break
        for column, value in zip(wanted, values):
            if not math.isfinite(value):
                raise InputError(
                    f"{value!r} is not a finite number", file=path, field=f"line {number}, column {column}"
                )
        rows.append((number, values, runtime_state))

    if runtime_index is not None and filter_runtime_state and rows:
        playing = [row for row in rows if row[2] == RUNTIME_STATE_PLAYING]
        if not playing:
            warnings.append(
                f"{path}: no row has runtime_state {RUNTIME_STATE_PLAYING} (PLAYING), as in "
                "freedrive with no program running; kept all rows"
            )
        elif len(playing) < len(rows):
            warnings.append(
                f"{path}: kept the {len(playing)} of {len(rows)} rows with runtime_state "
                f"{RUNTIME_STATE_PLAYING} (PLAYING)"
            )
            rows = playing

    if len(rows) < 2:
        raise InputError(
            f"has {len(rows)} sample(s); a demonstration needs at least 2", file=path, field="samples"
        )
    for previous, current in zip(rows[:-1], rows[1:]):
        if not current[1][0] > previous[1][0]:
            raise InputError(
                f"timestamp {current[1][0]!r} is not after the previous sample's "
                f"{previous[1][0]!r} (line {previous[0]}); timestamps must strictly increase",
                file=path,
                field=f"line {current[0]}, column {TIMESTAMP_COLUMN}",
            )
    for number, values, _ in rows:
        for column, value in zip(JOINT_COLUMNS, values[1:]):
            check_joint_value(value, file=path, field=f"line {number}, column {column}")

    table = np.array([values for _, values, _ in rows])
    demonstration = Demonstration(
        name=path.stem if name is None else name,
        timestamps=table[:, 0],
        joint_positions=table[:, 1:],
        description=description,
    )
    return LoadedDemonstration(demonstration, tuple(warnings))


# ----------------------------------------------------------------------------- writing


def rtde_csv_text(demonstration):
    """The project's own log format as text: ``timestamp,actual_q_0,...,actual_q_5``.

    Floats are written with ``repr`` (shortest round-tripping digits), so reading the
    text back gives bit-identical arrays. Ends with a newline.
    """
    lines = [",".join((TIMESTAMP_COLUMN,) + JOINT_COLUMNS)]
    for t, q in zip(demonstration.timestamps, demonstration.joint_positions):
        lines.append(",".join(repr(float(v)) for v in (t, *q)))
    return "\n".join(lines) + "\n"


def write_rtde_csv(demonstration, path):
    """Writes a demonstration as the project's own RTDE-style CSV.

    The file is replaced atomically (``atomic_files.atomic_write_bytes``), so a reader
    never sees half a log.

    Parameters
    ----------
    demonstration : Demonstration
    path : str or Path
    """
    atomic_write_bytes(path, rtde_csv_text(demonstration).encode("utf-8"))
