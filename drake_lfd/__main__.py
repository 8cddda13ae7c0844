"""``python -m drake_lfd``: the same as the ``drake-lfd`` command."""

import sys

from drake_lfd.cli import main

if __name__ == "__main__":
    sys.exit(main())
