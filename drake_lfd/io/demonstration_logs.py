"""UR5e joint logs: RTDE CSV files read, checked and written as demonstrations (Eq. 11).

A demonstration (:class:`~drake_lfd.core.demonstrations.Demonstration`) is a time series
of the six UR5e joint angles, as the robot records it. Users already have logs from
Universal Robots' RTDE interface, so that is the import format: a CSV whose header
names the columns, among them ``timestamp`` and ``actual_q_0`` .. ``actual_q_5``
(radians, joint order shoulder_pan .. wrist_3), separated by spaces (UR's
``record.py``) or commas (``ur_rtde``'s file recording); the separator is sniffed from
the header and any other columns are ignored, in any order (a full recording's 125
columns; a name the header repeats is refused only if the read uses that column). A
log without ``timestamp`` (a free-drive recording) is read with its sample rate
(:func:`read_rtde_log`, ``rate_hz``), which can also return further columns (the TCP
pose that ``rtde_logs.py`` checks the joints against). ROS bags are ``rosbag_logs.py``'s;
``log_import.py`` picks the reader.

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
- A log cut off mid-line by a crash or a full disk is common. A file whose last line
  has no newline after it may have been cut anywhere in that line, even inside a
  number (``-3.6277474137027124`` cut to ``-3`` still parses), so that line is dropped
  with a warning, whatever it parses to; so is a last line with fewer fields than the
  header. The same damage anywhere else is an error: the file is not a log.
- Numbers are spelled as C and every CSV reader reads them: ASCII digits, an optional
  sign, decimal point and exponent (``nan``/``inf`` are read and then refused as not
  finite). Spellings only Python's ``float`` accepts (``0_5``, Arabic-Indic or other
  non-ASCII digits, surrounding Unicode spaces) are refused.
- Joint angles beyond ``2 pi + 0.05`` rad (the UR joint range plus a margin for
  measurement overshoot) are refused: the log is probably in degrees.
- Timestamps are seconds (:func:`check_plausible_motion`): samples a median of more
  than :data:`MAX_SAMPLE_INTERVAL_S` apart, or a log spanning more than
  :data:`MAX_DURATION_S`, are refused (milliseconds or nanoseconds, or a recording left
  running), naming the line.
- A joint moving faster than :data:`MAX_JOINT_SPEED_RAD_S` (twice the UR5e's 180 deg/s)
  between two samples is refused, naming the line: the log jumps (a lost stretch of
  samples, a teleport, spliced recordings).

Every problem is one :class:`~drake_lfd.core.errors.InputError` naming the file, the line
and column, and what is wrong.

Not for: the demonstration type and its checks (:mod:`drake_lfd.core.demonstrations`),
forward kinematics (:mod:`drake_lfd.robot.kinematics`), features (``features.py``) or
storing demonstrations (``library.py``).
"""

from __future__ import annotations

import math
import os
import re
import stat
from pathlib import Path
from typing import NamedTuple

import numpy as np

from drake_lfd.core.demonstrations import JOINT_COLUMNS, NUM_JOINTS, Demonstration, check_joint_value
from drake_lfd.core.errors import InputError
from drake_lfd.io.atomic_files import atomic_write_bytes

__all__ = [
    "UR5E_JOINT_SPEED_LIMIT_RAD_S",
    "MAX_JOINT_SPEED_RAD_S",
    "MAX_SAMPLE_INTERVAL_S",
    "MAX_DURATION_S",
    "MAX_LOG_BYTES",
    "read_log_bytes",
    "TIMESTAMP_COLUMN",
    "RUNTIME_STATE_COLUMN",
    "RUNTIME_STATE_PLAYING",
    "LoadedDemonstration",
    "RtdeLog",
    "parse_number",
    "check_plausible_motion",
    "read_rtde_csv",
    "read_rtde_log",
    "log_sample_summary",
    "rtde_csv_text",
    "write_rtde_csv",
]

TIMESTAMP_COLUMN = "timestamp"
RUNTIME_STATE_COLUMN = "runtime_state"
# UR RTDE runtime_state value of a running (playing) program.
RUNTIME_STATE_PLAYING = 2

_JOINT_COLUMN_PATTERN = re.compile(r"^actual_q_(\d+)$")

#: The UR5e's joint speed limit (180 deg/s, every joint; as in models/ur5e/ur5e.urdf).
UR5E_JOINT_SPEED_LIMIT_RAD_S = math.pi
#: A joint faster than this between two samples is a jump in the log, not a motion.
MAX_JOINT_SPEED_RAD_S = 2.0 * UR5E_JOINT_SPEED_LIMIT_RAD_S
#: RTDE streams at 10-500 Hz; a median sample interval above this is not seconds.
MAX_SAMPLE_INTERVAL_S = 1.0
#: A kinesthetic demonstration longer than this (10 minutes) is not one.
MAX_DURATION_S = 600.0
# The largest joint log read, bytes: MAX_DURATION_S at 500 Hz of a UR's full RTDE record
# (about 1,700 bytes a row with every column), with room.
MAX_LOG_BYTES = 1 << 30

# A number as C's strtod, numpy and every CSV reader spell it: ASCII only.
_NUMBER_PATTERN = re.compile(r"[+-]?(?:[0-9]+(?:\.[0-9]*)?|\.[0-9]+)(?:[eE][+-]?[0-9]+)?\Z", re.ASCII)
_NON_FINITE_SPELLINGS = frozenset(
    sign + word for sign in ("", "+", "-") for word in ("nan", "inf", "infinity")
)


class RtdeLog(NamedTuple):
    """What :func:`read_rtde_log` read: the demonstration, its warnings, the extra
    columns asked for that the log has (name -> array, shape (m,), for the kept rows)
    and the timestamp of the log's first data row (before any ``runtime_state``
    filter; the origin of a time window)."""

    demonstration: Demonstration
    warnings: tuple[str, ...]
    extra: dict
    first_timestamp: float


class LoadedDemonstration(NamedTuple):
    """A demonstration read from a log, and the warnings reading it raised.

    ``warnings`` are one-line messages (for example a cut-off last line that was
    dropped); they do not stop the log from being used.
    """

    demonstration: Demonstration
    warnings: tuple[str, ...]


# ----------------------------------------------------------------------------- reading


# Separators and the blanks around fields are ASCII (str.split() would also split on
# no-break and other Unicode spaces, which no CSV writer puts between fields).
_ASCII_BLANKS = " \t\r\n\f\v"
_ASCII_BLANK_RUN = re.compile(r"[ \t\f\v]+")


def _split(line, delimiter):
    if delimiter is None:
        return _ASCII_BLANK_RUN.split(line.strip(_ASCII_BLANKS))
    return [field.strip(_ASCII_BLANKS) for field in line.split(delimiter)]


def _cell(token, path, number, column):
    value = parse_number(token)
    if value is None:
        raise InputError(
            f"{token!r} is not a number (write ASCII digits with an optional sign, '.' and "
            "exponent, as in -0.5 or 1e-3)",
            file=path,
            field=f"line {number}, column {column}",
        )
    return value


def _header_columns(header_line, path, *, used=None, needs_timestamp=True):
    # used: the columns a reader takes; a duplicated name outside it is ignored (a full
    # RTDE recording can name an unused column twice). None: every duplicate is refused.
    delimiter = "," if "," in header_line else None  # None: any run of whitespace
    columns = _split(header_line, delimiter)
    seen = set()
    for column in columns:
        if not column:
            raise InputError("the header has an empty column name", file=path, field="line 1")
        if column in seen and (used is None or column in used):
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
    required = ((TIMESTAMP_COLUMN,) if needs_timestamp else ()) + JOINT_COLUMNS
    missing = [name for name in required if name not in columns]
    if missing:
        raise InputError(
            f"missing column(s) {', '.join(missing)} (an RTDE log needs timestamp and "
            "actual_q_0 .. actual_q_5"
            + ("; for a log without timestamps give its sample rate, library add --rate HZ)"
               if TIMESTAMP_COLUMN in missing else ")"),
            file=path,
            field="line 1",
        )
    return columns, delimiter


def parse_number(token):
    """The float a CSV cell spells, or None if it is not a number in the ASCII spelling
    every CSV reader shares (``1``, ``-0.5``, ``.5``, ``1e-3``; ``nan`` and ``inf`` are
    numbers here, refused later as not finite). Python-only spellings that ``float``
    accepts, such as ``0_5`` or non-ASCII digits, give None."""
    if _NUMBER_PATTERN.match(token) or token.lower() in _NON_FINITE_SPELLINGS:
        return float(token)
    return None


def check_plausible_motion(timestamps, joint_positions, *, file, field_of):
    """Refuses timestamps that are not seconds and joints that jump.

    Parameters
    ----------
    timestamps : array, shape (m,)
        Strictly increasing (checked before).
    joint_positions : array, shape (m, 6)
    file : str or Path
        Named in the error.
    field_of : callable
        Sample index -> where that sample is (``"line 12"``, ``"sample 11"``).

    Raises
    ------
    InputError
        The median sample interval exceeds :data:`MAX_SAMPLE_INTERVAL_S` (naming the
        first interval that does), the samples span more than :data:`MAX_DURATION_S`
        (naming the first sample beyond it), or a joint moves faster than
        :data:`MAX_JOINT_SPEED_RAD_S` between two samples (naming the sample and joint).
    """
    t = np.asarray(timestamps, dtype=float)
    q = np.asarray(joint_positions, dtype=float)
    if t.shape[0] < 2:
        return
    steps = np.diff(t)
    median = float(np.median(steps))
    units = "are the timestamps in milliseconds or nanoseconds? They must be seconds"
    if median > MAX_SAMPLE_INTERVAL_S:
        k = int(np.argmax(steps > MAX_SAMPLE_INTERVAL_S)) + 1
        raise InputError(
            f"timestamp {float(t[k])!r} is {steps[k - 1]:.6g} s after the previous sample's "
            f"({field_of(k - 1)}), and samples are a median {median:.6g} s apart, where a UR "
            f"RTDE log samples every 0.002-0.1 s; {units}",
            file=file,
            field=f"{field_of(k)}, column {TIMESTAMP_COLUMN}",
        )
    elapsed = t - t[0]
    if elapsed[-1] > MAX_DURATION_S:
        k = int(np.argmax(elapsed > MAX_DURATION_S))
        raise InputError(
            f"timestamp {float(t[k])!r} is {elapsed[k]:.6g} s after the first sample's, and the log "
            f"spans {elapsed[-1]:.6g} s, more than a demonstration's {MAX_DURATION_S:g} s; "
            f"{units} (or trim the recording to the demonstration)",
            file=file,
            field=f"{field_of(k)}, column {TIMESTAMP_COLUMN}",
        )
    speeds = np.abs(np.diff(q, axis=0)) / steps[:, None]
    too_fast = speeds > MAX_JOINT_SPEED_RAD_S
    if np.any(too_fast):
        k, joint = (int(v) for v in np.argwhere(too_fast)[0])
        raise InputError(
            f"joint {JOINT_COLUMNS[joint]} moves {q[k + 1, joint] - q[k, joint]:+.6g} rad in "
            f"{steps[k]:.6g} s after the previous sample ({field_of(k)}): {speeds[k, joint]:.6g} "
            f"rad/s, more than twice the UR5e's 180 deg/s joint speed limit; the log jumps "
            "(lost samples, a teleport, spliced recordings)",
            file=file,
            field=f"{field_of(k + 1)}, column {JOINT_COLUMNS[joint]}",
        )


def read_log_bytes(path) -> bytes:
    """The bytes of the joint log at ``path``: a regular file of at most
    :data:`MAX_LOG_BYTES` (a device such as ``/dev/zero``, a pipe or a runaway file is
    refused before it is read).

    Raises
    ------
    InputError
        Naming ``path``: missing, a directory, not a regular file, too large, unreadable.
    """
    path = Path(path)
    not_regular = "is not a regular file (a device, pipe or socket is no joint log)"
    try:
        # Before opening: opening a pipe would wait for a writer.
        if stat.S_ISDIR(os.stat(path).st_mode):
            raise IsADirectoryError
        if not stat.S_ISREG(os.stat(path).st_mode):
            raise InputError(not_regular, file=path)
        with open(path, "rb") as log:
            status = os.fstat(log.fileno())
            if not stat.S_ISREG(status.st_mode):
                raise InputError(not_regular, file=path)
            if status.st_size > MAX_LOG_BYTES:
                raise InputError(f"is {status.st_size:,} bytes; a joint log is at most {MAX_LOG_BYTES:,} "
                                 f"({MAX_DURATION_S:g} s of a UR's full RTDE record at 500 Hz)", file=path)
            raw = log.read(MAX_LOG_BYTES + 1)
    except FileNotFoundError:
        raise InputError("no such file", file=path) from None
    except IsADirectoryError:
        raise InputError("is a directory, not a joint log", file=path) from None
    except OSError as error:
        raise InputError(f"cannot read: {error.strerror}", file=path) from None
    if len(raw) > MAX_LOG_BYTES:
        raise InputError(f"grew past {MAX_LOG_BYTES:,} bytes while it was read", file=path)
    return raw


def read_rtde_log(path, *, name=None, description="", filter_runtime_state=True, rate_hz=None,
                  extra_columns=()):
    """Reads a UR RTDE joint log (or the project's own format) as a demonstration, with
    any extra columns asked for (:class:`RtdeLog`).

    Without a ``timestamp`` column, ``rate_hz`` gives the sample times: data row ``k``
    (counting from 0, before the ``runtime_state`` filter) is at ``k / rate_hz`` s. With
    one, the timestamps are used and a given rate is ignored, with a warning. A column
    name the header repeats is refused only if it is one this read uses (``timestamp``,
    the joints, ``runtime_state``, ``extra_columns``); other duplicates are ignored.

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
    rate_hz : float, optional
        The sample rate of a log without a ``timestamp`` column (Hz, positive).
    extra_columns : sequence of str
        Further numeric columns to return, for the kept rows, when the log has them
        (for example ``actual_TCP_pose_0`` .. ``actual_TCP_pose_5``).

    Returns
    -------
    log : RtdeLog
        ``(demonstration, warnings, extra, first_timestamp)``.

    Raises
    ------
    InputError
        Naming the file, line and column: empty file, missing columns, wrong number of
        joints, a short line before the last, a non-numeric (or Python-only spelled) or
        non-finite cell, fewer than 2 samples, timestamps not strictly increasing,
        angles in degrees, timestamps not in seconds or a joint jump
        (:func:`check_plausible_motion`).
    """
    path = Path(path)
    raw = read_log_bytes(path)
    try:
        text = raw.decode("utf-8-sig")
    except UnicodeDecodeError as error:
        raise InputError(
            f"not a text CSV (byte {error.start} is not UTF-8)", file=path
        ) from None
    # Whether the last non-blank line has a newline after it (a complete write).
    ends_with_newline = text.rstrip(" \t").endswith(("\n", "\r"))
    # (line number, text) of every non-blank line; line numbers count from 1.
    lines = [(number, line) for number, line in enumerate(text.splitlines(), start=1) if line.strip()]
    if not lines:
        raise InputError("the file is empty; expected an RTDE CSV log with a header row", file=path)
    header_number, header_line = lines[0]
    if rate_hz is not None and not (math.isfinite(rate_hz) and rate_hz > 0):
        raise InputError(f"{rate_hz!r} is not a sample rate (Hz, a positive number)", field="rate")
    extra_columns = tuple(extra_columns)
    used = {TIMESTAMP_COLUMN, RUNTIME_STATE_COLUMN, *JOINT_COLUMNS, *extra_columns}
    columns, delimiter = _header_columns(header_line, path, used=used, needs_timestamp=rate_hz is None)
    from_rate = TIMESTAMP_COLUMN not in columns  # then rate_hz gives the sample times
    warnings = []
    if rate_hz is not None and not from_rate:
        warnings.append(f"{path}: the log has a timestamp column; used it and ignored the rate {rate_hz:g} Hz")
    extras = tuple(column for column in extra_columns if column in columns)
    wanted = (() if from_rate else (TIMESTAMP_COLUMN,)) + JOINT_COLUMNS + extras
    wanted_index = [columns.index(column) for column in wanted]
    runtime_index = columns.index(RUNTIME_STATE_COLUMN) if RUNTIME_STATE_COLUMN in columns else None

    rows = []  # (line number, [t, q0..q5, extras...], runtime_state or None)
    data_lines = lines[1:]
    for position, (number, line) in enumerate(data_lines):
        is_last = position == len(data_lines) - 1
        fields = _split(line, delimiter)
        if is_last and not ends_with_newline:
            # Cut anywhere in this line, perhaps inside a number that still parses.
            warnings.append(
                f"{path}: line {number}: the log ends mid-line (no newline after its last line, "
                f"which ends {fields[-1]!r} and may be cut short); dropped that line"
            )
            break
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
        for column_index, column in zip(wanted_index, wanted):
            value = _cell(fields[column_index], path, number, column)
            values.append(value)
        runtime_state = None
        if runtime_index is not None:
            runtime_state = _cell(fields[runtime_index], path, number, RUNTIME_STATE_COLUMN)
        for column, value in zip(wanted, values):
            if not math.isfinite(value):
                raise InputError(
                    f"{value!r} is not a finite number", file=path, field=f"line {number}, column {column}"
                )
        if from_rate:  # data row `position` is at position / rate_hz
            values.insert(0, position / rate_hz)
        rows.append((number, values, runtime_state))

    first_timestamp = rows[0][1][0] if rows else None  # before the runtime_state filter
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
    joints = table[:, 1 : 1 + NUM_JOINTS]
    check_plausible_motion(
        table[:, 0], joints, file=path, field_of=lambda index: f"line {rows[index][0]}"
    )
    demonstration = Demonstration(
        name=path.stem if name is None else name,
        timestamps=table[:, 0],
        joint_positions=joints,
        description=description,
    )
    extra = {column: table[:, 1 + NUM_JOINTS + i].copy() for i, column in enumerate(extras)}
    return RtdeLog(demonstration, tuple(warnings), extra, float(first_timestamp))


def read_rtde_csv(path, *, name=None, description="", filter_runtime_state=True, rate_hz=None):
    """Reads a UR RTDE joint log (or the project's own format) as a demonstration:
    :func:`read_rtde_log` without extra columns.

    Returns
    -------
    loaded : LoadedDemonstration
        ``(demonstration, warnings)``.
    """
    log = read_rtde_log(
        path, name=name, description=description, filter_runtime_state=filter_runtime_state, rate_hz=rate_hz
    )
    return LoadedDemonstration(log.demonstration, log.warnings)


def log_sample_summary(log_bytes, path):
    """``(samples, duration_s)`` of a log in the project's own format, cheaply: the
    number of non-blank lines after the header, and the last timestamp minus the first.

    What a library checks its manifest against when it is opened, without reading
    every number (:func:`read_rtde_csv` checks those when the log is used).

    Raises
    ------
    InputError
        Naming ``path``: not UTF-8, no header with a ``timestamp`` column, or a first
        or last timestamp that is not a number.
    """
    try:
        text = log_bytes.decode("utf-8-sig")
    except UnicodeDecodeError as error:
        raise InputError(f"not a text CSV (byte {error.start} is not UTF-8)", file=path) from None
    lines = [(number, line) for number, line in enumerate(text.splitlines(), start=1) if line.strip()]
    if not lines:
        raise InputError("the file is empty; expected an RTDE CSV log with a header row", file=path)
    columns, delimiter = _header_columns(lines[0][1], path)
    index = columns.index(TIMESTAMP_COLUMN)
    data = lines[1:]
    if len(data) < 2:
        return len(data), 0.0
    times = []
    for number, line in (data[0], data[-1]):
        fields = _split(line, delimiter)
        if index >= len(fields):
            raise InputError(
                f"has {len(fields)} fields but the header has {len(columns)}", file=path, field=f"line {number}"
            )
        times.append(_cell(fields[index], path, number, TIMESTAMP_COLUMN))
    return len(data), float(times[1] - times[0])


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
