"""The closed sets and bounds a task is made of, in plain Python.

The path-constraint kinds, the speed-override policies of people in the cell and the
fewest critical configurations a task has. A task file's values are checked against
them before Drake is imported (``io/task_checks.py``), so they live here, with no import
beyond the standard library; :mod:`drake_lfd.core.tasks` and :mod:`drake_lfd.core.people`,
whose records use them, import them from here.

Not for: the records themselves (``tasks.py``, ``people.py``).
"""

from __future__ import annotations

__all__ = ["MIN_CRITICAL_CONFIGURATIONS", "PATH_CONSTRAINT_KINDS", "SSM_POLICY", "STOP_ONLY_POLICY", "POLICIES"]

#: Fewest critical configurations of a task: a start and an end.
MIN_CRITICAL_CONFIGURATIONS = 2
#: What a path constraint may ask of a run: the tool's orientation within a tolerance.
PATH_CONSTRAINT_KINDS = ("orientation",)

#: The override policies: ISO/TS 15066 speed and separation monitoring, or a safety
#: scanner's fixed radius (stop when anyone is inside it, resume when clear).
SSM_POLICY = "speed_and_separation"
STOP_ONLY_POLICY = "stop_only"
POLICIES = (SSM_POLICY, STOP_ONLY_POLICY)
