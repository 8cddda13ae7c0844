"""The values of drake-lfd's YAML files, converted and checked one by one, in plain Python.

A file's structure is checked first (``yaml_checks.py``: keys, kinds of values); these
functions then convert each value and check its range: :func:`finite`, :func:`positive`,
:func:`non_negative`, :func:`coordinate` (positions farther than :data:`MAX_COORDINATE_M`
from the origin are out of any robot's reach and refused, so ``1e300`` can never reach
the planner as ``inf``), :func:`angle` (radians, multiples of pi or degrees,
:func:`angle_from_text`, at most :data:`MAX_ANGLE_RAD`), :func:`numbers` (a list of
them), :func:`pose_values` and :func:`unique_name`. Every problem is one
:class:`~drake_lfd.core.errors.InputError` that names the file and the field
(``waypoints[2].euler_zyx[0]``, list indices from 0).

Everything here is plain Python, so a file's values are checked before Drake is
imported (``task_checks.py``); :func:`vector` (a numpy array) and :func:`pose` (a Drake
``RigidTransform``) import what they build when called.

Not for: a file's structure (``yaml_checks.py``) or what its values mean together
(``task_checks.py``, ``people_checks.py``, ``guidance_scripts.py``).
"""

import math
import re

from drake_lfd.core.errors import InputError
from drake_lfd.io.yaml_checks import kind_of

__all__ = [
    "MAX_COORDINATE_M",
    "MAX_ANGLE_RAD",
    "angle_from_text",
    "finite",
    "positive",
    "non_negative",
    "coordinate",
    "angle",
    "numbers",
    "vector",
    "pose_values",
    "pose",
    "unique_name",
]

#: Largest magnitude of a position coordinate, in metres: ten times a UR5e's reach and
#: more than any work cell; a larger value is nearly always millimetres or centimetres
#: written as metres (``450`` for 0.45 m).
MAX_COORDINATE_M = 10.0
#: Largest magnitude of an angle, in radians: a full turn. A larger one is nearly always
#: degrees written without ``deg`` (``-90`` for -pi/2).
MAX_ANGLE_RAD = 2.0 * math.pi

_PI_EXPRESSION = re.compile(
    r"^([+-]?)\s*(\d+(?:\.\d*)?|\.\d+)?\s*\*?\s*pi\s*(?:/\s*(\d+(?:\.\d*)?|\.\d+))?$", re.ASCII
)
_DEGREES = re.compile(r"^([+-]?(?:\d+(?:\.\d*)?|\.\d+)(?:[eE][+-]?\d+)?)\s*deg$", re.ASCII)


def _python_only_spelling(text):
    """Whether ``text`` spells a number only Python's ``float`` reads: an underscore
    (``0_5``) or any character that is not ASCII (Arabic-Indic or fullwidth digits,
    Unicode spaces). YAML, C and every other reader refuse those."""
    return "_" in text or not text.isascii()


def angle_from_text(text):
    """The angle written in ``text``, in radians, or None if the text is not an angle.

    Accepts plain numbers (``"1.5"``), multiples of pi (``"pi"``, ``"-pi/2"``,
    ``"3*pi/4"``, ``"0.5pi"``) and degrees (``"-90deg"``).
    """
    text = text.strip()
    if _python_only_spelling(text):
        return None
    try:
        return float(text)
    except ValueError:
        pass
    match = _DEGREES.match(text)
    if match:
        return math.radians(float(match.group(1)))
    match = _PI_EXPRESSION.match(text)
    if match:
        sign, coefficient, divisor = match.groups()
        value = math.pi * (float(coefficient) if coefficient else 1.0)
        if divisor is not None:
            if float(divisor) == 0.0:
                return None
            value /= float(divisor)
        return -value if sign == "-" else value
    return None


def finite(value, *, file, field, what="a number"):
    """A finite float from a checked scalar (a number or a numeric string in ASCII,
    without Python's ``_`` digit separators)."""
    if isinstance(value, str) and _python_only_spelling(value):
        raise InputError(f"expected {what}, got {kind_of(value)} (write ASCII digits, without '_')",
                         file=file, field=field)
    try:
        number = float(value)
    except (TypeError, ValueError):
        raise InputError(f"expected {what}, got {kind_of(value)}", file=file, field=field) from None
    except OverflowError:  # an integer of hundreds of digits
        raise InputError("is not a finite number (too large for any float)", file=file, field=field) from None
    if not math.isfinite(number):
        raise InputError(f"{value!r} is not a finite number", file=file, field=field)
    return number


def positive(value, *, file, field):
    """A finite number > 0 (a size, a speed, a time span)."""
    number = finite(value, file=file, field=field)
    if not number > 0.0:
        raise InputError(f"must be > 0, got {number:g}", file=file, field=field)
    return number


def unique_name(name, seen: dict, *, what: str, file, field) -> None:
    """Checks that ``name`` (of a ``what`` at ``field``, as ``people[0]``) is non-empty and
    not one of ``seen`` (name -> the field that used it), then records it there."""
    if not name:
        raise InputError(f"a {what} needs a non-empty name", file=file, field=f"{field}.name")
    if name in seen:
        raise InputError(f"{what} name {name!r} is used by {seen[name]} already", file=file, field=f"{field}.name")
    seen[name] = field


def non_negative(value, *, file, field):
    """A finite number >= 0."""
    number = finite(value, file=file, field=field)
    if number < 0.0:
        raise InputError(f"must be >= 0, got {number:g}", file=file, field=field)
    return number


def coordinate(value, *, file, field):
    """A position coordinate in metres: finite and within :data:`MAX_COORDINATE_M`."""
    number = finite(value, file=file, field=field)
    if abs(number) > MAX_COORDINATE_M:
        raise InputError(
            f"{number:g} m is out of any robot's reach (positions are in metres, within +-{MAX_COORDINATE_M:g} m "
            f"of the origin; for millimetres write {number / 1000:g})",
            file=file, field=field,
        )
    return number


def angle(value, *, file, field):
    """Radians from a checked scalar: a number or any spelling of :func:`angle_from_text`,
    at most a full turn (:data:`MAX_ANGLE_RAD`) in magnitude."""
    written = value
    if isinstance(value, str):
        number = angle_from_text(value)
        if number is None:
            raise InputError(
                f"{value!r} is not an angle (write radians, a multiple of pi such as -pi/2, "
                "or degrees such as -90deg)",
                file=file,
                field=field,
            )
        value = number
    number = finite(value, file=file, field=field)
    if abs(number) > MAX_ANGLE_RAD + 1e-9:
        if isinstance(written, str) and not _plain_number(written):  # -720deg, 3pi
            message = f"{written.strip()} is more than a full turn (angles are within +-2 pi, +-360deg)"
        else:
            message = (f"{number:g} rad is more than a full turn: angles are radians; "
                       f"for degrees write {number:g}deg")
        raise InputError(message, file=file, field=field)
    return number


def _plain_number(text):
    """Whether ``text`` is an angle written as a bare number (radians: no ``deg``, no pi)."""
    try:
        float(text)
    except ValueError:
        return False
    return True


def numbers(values, count, *, file, field, convert):
    """A tuple of ``count`` values, each ``convert(value, file=, field=)``; the entries
    are named ``field[i]`` in errors."""
    if len(values) != count:
        raise InputError(f"expected {count} values, got {len(values)}", file=file, field=field)
    return tuple(convert(v, file=file, field=f"{field}[{i}]") for i, v in enumerate(values))


def vector(values, count, *, file, field, convert):
    """:func:`numbers` as an array, shape (count,)."""
    checked = numbers(values, count, file=file, field=field, convert=convert)
    import numpy as np

    return np.array(checked)


def pose_values(spec, *, file, field):
    """``(p, euler_zyx)`` of a spec with ``p`` (metres) and ``euler_zyx`` (angles), such
    as ``PoseSpec``, checked: two tuples of 3 floats. Errors name ``field.p[i]`` or
    ``field.euler_zyx[i]``."""
    p = numbers(spec.p, 3, file=file, field=f"{field}.p", convert=coordinate)
    euler = numbers(spec.euler_zyx, 3, file=file, field=f"{field}.euler_zyx", convert=angle)
    return p, euler


def pose(spec, *, file, field):
    """The ``RigidTransform`` of :func:`pose_values`."""
    p, euler = pose_values(spec, file=file, field=field)
    import numpy as np

    from drake_lfd.core.tasks import rigid_transform_from_euler_zyx

    return rigid_transform_from_euler_zyx(np.array(p), np.array(euler))
