"""Strict JSON: every document drake-lfd writes is valid JSON, never ``NaN`` or ``Infinity``.

Python's ``json`` writes ``NaN``, ``Infinity`` and ``-Infinity`` for non-finite floats by
default, which no strict JSON parser reads. :func:`strict_json_text` writes a number that
is not finite as ``null`` (docs/cli.rst: ``null`` means the value does not exist or
could not be computed, such as ``min_shell_distance_m`` of a scene without obstacles)
and then serialises with ``allow_nan=False``, so nothing non-finite can slip through.
Inputs that would make numbers overflow (a position of ``1e300``) are refused when the
file is read (:mod:`drake_lfd.io.yaml_checks`). NumPy scalars and arrays become plain
numbers and lists.

:func:`write_json` writes a document atomically (:mod:`drake_lfd.io.atomic_files`).

Not for: the JSON-lines files of finished trials (:mod:`drake_lfd.io.json_lines`, which
uses :func:`strict_json_text`), reading JSON.
"""

from __future__ import annotations

import json
import math
import sys
from pathlib import Path

from drake_lfd.io.atomic_files import atomic_write_bytes

__all__ = ["json_ready", "strict_json_text", "write_json"]


def json_ready(value):
    """``value`` with every non-finite float replaced by None, NumPy scalars and arrays
    made plain Python, tuples made lists; mappings and lists are copied, not changed."""
    if isinstance(value, dict):
        return {key: json_ready(item) for key, item in value.items()}
    if isinstance(value, (list, tuple)):
        return [json_ready(item) for item in value]
    # NumPy's types exist only once numpy is imported; the command line writes JSON
    # without importing it for its own sake (it starts without numpy).
    np = sys.modules.get("numpy")
    if np is not None and isinstance(value, np.ndarray):
        return json_ready(value.tolist())
    if isinstance(value, bool) or (np is not None and isinstance(value, np.bool_)):
        return bool(value)
    if isinstance(value, int) or (np is not None and isinstance(value, np.integer)):
        return int(value)
    if isinstance(value, float) or (np is not None and isinstance(value, np.floating)):
        number = float(value)
        return number if math.isfinite(number) else None
    return value


def strict_json_text(document, *, indent: int | None = 1) -> str:
    """``document`` as strict JSON text (non-finite numbers as ``null``); ``indent=None``
    gives one line."""
    separators = (",", ":") if indent is None else None
    return json.dumps(json_ready(document), indent=indent, allow_nan=False, separators=separators)


def write_json(path: str | Path, document) -> None:
    """Writes ``document`` to ``path`` as strict, indented JSON, atomically.

    Raises
    ------
    OSError
        The write failed (a full disk: ``ENOSPC``); its ``filename`` is ``path``, and
        ``path`` is untouched.
    """
    data = (strict_json_text(document) + "\n").encode("utf-8")
    try:
        atomic_write_bytes(Path(path), data)
    except OSError as error:
        raise OSError(error.errno, error.strerror or str(error), str(path)) from None
