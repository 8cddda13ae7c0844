"""Layer 8, the ``drake-lfd`` command line: thin argparse front ends over the library.

Nothing below this layer parses arguments or prints to the console. The command
modules are plain Python at import, so ``--version``, ``--help``, a bad flag and a task
file's structure are answered before Drake is imported. ``drake-lfd
simulate`` runs the default pipeline (``drake_lfd.diagrams.pipeline``).

The modules:

* ``app``: the parser, the commands wired together, errors mapped to exit codes.
* ``record``: ``drake-lfd record``, a simulated kinesthetic demonstration.
* ``library``: ``drake-lfd library add|show|copy|remove``, the parser;
  ``library_actions``: what those actions do.
* ``train``: ``drake-lfd train``, Q-learning of a general policy.
* ``plan``: ``drake-lfd plan``, one SE(3) motion plan or a demonstration request.
* ``simulate``: ``drake-lfd simulate``, closed-loop runs of N trials of a task.
* ``sweep``: ``drake-lfd sweep``, trials at every base placement of a grid.
* ``export``: ``drake-lfd export``, a planned joint trajectory as files a real UR5e runs.
* ``paper``: ``drake-lfd paper``, the paper's Section 6 with a report.
* ``show_model``: ``drake-lfd show-model``, a Meshcat animation of the UR5e.
* ``shared_options``: options several commands share, as argparse parent parsers.
* ``startup``: a command's heavy imports, with interrupts deferred.
* ``argument_checks``: checks of command-line values shared by the commands.
* ``progress``: a minimal text progress bar on stderr.

It exports ``main`` (``drake_lfd.cli.main(["plan", ...])`` runs a command and returns its
exit code; the ``drake-lfd`` script calls it), loaded from ``app`` on first use. Its
modules are internal: the command line itself is documented in docs/cli.rst.
"""

from __future__ import annotations

from drake_lfd.core._lazy import lazy_exports

# name -> module that defines it (imported on first access, PEP 562).
_EXPORTS = {
    "main": "drake_lfd.cli.app",
}

__all__ = list(_EXPORTS)
__getattr__, __dir__ = lazy_exports(globals(), _EXPORTS)
