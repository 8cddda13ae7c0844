"""Layer 8, the ``drake-lfd`` command line: thin argparse front ends over the library.

One module per command (``record``, ``library``, ``train``, ``plan``, ``simulate``,
``paper``, ``show_model``); :mod:`drake_lfd.cli.app` wires them together and maps errors
to exit codes. Nothing below this layer parses arguments or prints to the console.
"""

from drake_lfd.cli.app import main

__all__ = ["main"]
