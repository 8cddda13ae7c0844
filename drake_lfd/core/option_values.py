"""The closed sets and defaults of user options, in plain Python.

The command line checks ``--planner`` and ``--cost`` and prints its defaults before
Drake is imported (``drake-lfd plan --planner exakt`` answers at once), so these values
live here, with no import beyond the standard library; the modules that act on them
(:mod:`drake_lfd.planning.options`, :mod:`drake_lfd.core.fidelity`,
:mod:`drake_lfd.planning.training`, :mod:`drake_lfd.experiments.parallel_trials`) import
them from here.

Not for: what the options do, or checking their values (the command line does).
"""

from __future__ import annotations

import os

__all__ = ["PLANNERS", "COST_MODES", "DEFAULT_CHAINED_TASKS", "default_workers"]

#: The planners: the exact shortest-path planner and the greedy walk on a Q-policy.
PLANNERS = ("exact", "q")

#: The action costs: the paper's Eq. 31 (total rotation distance), or shape fidelity.
COST_MODES = ("paper", "fidelity")

#: Tasks chained from the library's own demonstrations added to the random training
#: tasks (``train --chained-tasks``); the paper trains on random tasks only.
DEFAULT_CHAINED_TASKS = 0


def default_workers(trials: int) -> int:
    """Worker processes for ``trials`` closed-loop trials when ``--workers`` is not given:
    every core, but no more workers than trials."""
    return max(1, min(os.cpu_count() or 1, int(trials)))
