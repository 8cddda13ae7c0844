"""Print the comparison of the bundled features with the paper's Table 5 (markdown).

    python sims/table5_comparison.py > docs/table5.md
"""

import sys

from drake_lfd.experiments.table5 import main

if __name__ == "__main__":
    sys.exit(main())
