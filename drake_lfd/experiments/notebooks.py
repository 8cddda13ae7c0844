"""What the tutorials need to run both as scripts and as Jupyter notebooks.

A tutorial is one source, a jupytext percent-format script paired with a notebook. As a
script it reads its command line; in a notebook there is none, so it takes its defaults.
In both, the environment variable ``DRAKE_LFD_TUTORIAL_SHORT=1`` selects the short run
(the test suite's). Figures a tutorial writes are shown inline in a notebook.

Not for: anything a tutorial computes (it calls the library like any user).
"""

from __future__ import annotations

import argparse
import os
import sys
from pathlib import Path

__all__ = ["SHORT_RUN_VARIABLE", "running_as_notebook", "show", "parse_tutorial_arguments"]

SHORT_RUN_VARIABLE = "DRAKE_LFD_TUTORIAL_SHORT"


def running_as_notebook() -> bool:
    """True in a Jupyter kernel (a tutorial opened as a notebook), False as a script."""
    ipython = sys.modules.get("IPython")
    shell = ipython.get_ipython() if ipython is not None else None
    return shell is not None and hasattr(shell, "kernel")


def show(png: str | Path) -> None:
    """Shows a figure just written to ``png`` in the notebook (a script only writes it)."""
    if running_as_notebook():
        from IPython.display import Image, display

        display(Image(filename=str(png)))


def parse_tutorial_arguments(parser: argparse.ArgumentParser) -> tuple[argparse.Namespace, bool]:
    """The tutorial's settings and whether this is the short run.

    ``parser`` must have a ``--short`` flag. A script parses its command line, a notebook
    none (its defaults); :data:`SHORT_RUN_VARIABLE` set to anything but ``0`` selects the
    short run for both.
    """
    args = parser.parse_args([] if running_as_notebook() else None)
    short = args.short or os.environ.get(SHORT_RUN_VARIABLE, "0") not in ("", "0")
    return args, short
