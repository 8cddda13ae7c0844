"""Kinesthetic demonstrations: UR5e joint logs read, checked and written (Eq. 11).

A demonstration is a time series of the six UR5e joint angles, as the robot records it.
Users already have logs from Universal Robots' RTDE interface, so that is the import
format: a CSV whose header names the columns, among them ``timestamp`` and
``actual_q_0`` .. ``actual_q_5`` (radians, joint order shoulder_pan .. wrist_3),
separated by spaces (UR's ``record.py``) or commas (``ur_rtde``'s file recording); the
separator is sniffed from the header and any other columns are ignored.

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
and column, and what is wrong. Not for: features (``features.py``) or storing
demonstrations (``library.py``).
"""

from __future__ import annotations

import dataclasses
import math
import re
from pathlib import Path
from typing import NamedTuple

import numpy as np

from drake_lfd.io.atomic_files import atomic_write_bytes
from drake_lfd.core.dual_quaternion import dual_quaternion_from_matrices
from drake_lfd.core.errors import InputError
from drake_lfd.core.read_only_arrays import read_only_array

NUM_JOINTS = 6
TIMESTAMP_COLUMN = "timestamp"
JOINT_COLUMNS = tuple(f"actual_q_{i}" for i in range(NUM_JOINTS))
RUNTIME_STATE_COLUMN = "runtime_state"
# UR RTDE runtime_state value of a running (playing) program.
RUNTIME_STATE_PLAYING = 2
# |q| above this is not a UR joint angle in radians (joint range is +-2 pi).
MAX_ABS_JOINT_RAD = 2.0 * math.pi + 0.05

_JOINT_COLUMN_PATTERN = re.compile(r"^actual_q_(\d+)$")


@dataclasses.dataclass(frozen=True, eq=False)
class Demonstration:
    """One kinesthetic demonstration (Eq. 11).

    Attributes
    ----------
    name : str
        Its name in a library (``[A-Za-z0-9_-]+``), or the log's file stem.
    timestamps : array, shape (m,)
        Sample times in seconds, strictly increasing (read-only).
    joint_positions : array, shape (m, 6)
        UR5e joint angles in radians, joint order shoulder_pan .. wrist_3 (read-only).
    description : str
        What was demonstrated, in words.
    """

    name: str
    timestamps: np.ndarray
    joint_positions: np.ndarray
    description: str = ""

    def __post_init__(self):
        timestamps = read_only_array(self.timestamps)
        joint_positions = read_only_array(self.joint_positions)
        if timestamps.ndim != 1:
            raise ValueError(f"timestamps must have shape (m,), got {timestamps.shape}")
        if joint_positions.shape != (timestamps.shape[0], NUM_JOINTS):
            raise ValueError(
                f"joint_positions must have shape ({timestamps.shape[0]}, {NUM_JOINTS}), "
                f"got {joint_positions.shape}"
            )
        object.__setattr__(self, "timestamps", timestamps)
        object.__setattr__(self, "joint_positions", joint_positions)

    @property
    def num_samples(self) -> int:
        """m, the number of samples."""
        return int(self.timestamps.shape[0])

    @property
    def duration_s(self) -> float:
        """Time from the first to the last sample, seconds."""
        return float(self.timestamps[-1] - self.timestamps[0]) if self.num_samples else 0.0


class LoadedDemonstration(NamedTuple):
    """A demonstration read from a log, and the warnings reading it raised.

    ``warnings`` are one-line messages (for example a cut-off last line that was
    dropped); they do not stop the log from being used.
    """

    demonstration: Demonstration
    warnings: tuple[str, ...]


def check_demonstration(demonstration, *, file=None):
    """Checks a demonstration built in code, as the log reader checks a file.

    Parameters
    ----------
    demonstration : Demonstration
    file : str or Path, optional
        Named in error messages.

    Raises
    ------
    InputError
        Fewer than 2 samples, non-finite values, timestamps not strictly increasing,
        or joint angles beyond :data:`MAX_ABS_JOINT_RAD` (degrees?).
    """
    t = demonstration.timestamps
    q = demonstration.joint_positions
    if t.shape[0] < 2:
        raise InputError(
            f"has {t.shape[0]} sample(s); a demonstration needs at least 2", file=file, field="samples"
        )
    for index in range(t.shape[0]):
        if not math.isfinite(t[index]):
            raise InputError(f"{t[index]!r} is not finite", file=file, field=f"sample {index}, timestamp")
        for joint in range(NUM_JOINTS):
            _check_joint_value(q[index, joint], file=file, field=f"sample {index}, {JOINT_COLUMNS[joint]}")
    steps = np.diff(t)
    if np.any(steps <= 0.0):
        index = int(np.argmax(steps <= 0.0)) + 1
        raise InputError(
            f"timestamp {t[index]!r} is not after the previous one ({t[index - 1]!r}); "
            "timestamps must strictly increase",
            file=file,
            field=f"sample {index}",
        )


def _check_joint_value(value, *, file, field):
    if not math.isfinite(value):
        raise InputError(f"{value!r} is not a finite number", file=file, field=field)
    if abs(value) > MAX_ABS_JOINT_RAD:
        raise InputError(
            f"{value!r} rad is beyond the UR joint range (+-2 pi); is the log in degrees?",
            file=file,
            field=field,
        )


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
            _check_joint_value(value, file=path, field=f"line {number}, column {column}")

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


# ------------------------------------------------------------------------ kinematics


def poses_from_demonstration(demonstration, kinematics):
    """End-effector poses of every sample by forward kinematics.

    Parameters
    ----------
    demonstration : Demonstration
    kinematics : UR5eKinematics
        Carries ``X_WB`` and ``X_tool0_E``; a library uses ``X_WB = identity``.

    Returns
    -------
    X_WE : array, shape (m, 4, 4)
        Homogeneous matrices.
    """
    return kinematics.X_WE_batch(demonstration.joint_positions)


def dual_quaternions_from_demonstration(demonstration, kinematics):
    """End-effector poses of every sample as dual quaternions, shape (m, 8)."""
    return dual_quaternion_from_matrices(poses_from_demonstration(demonstration, kinematics))
