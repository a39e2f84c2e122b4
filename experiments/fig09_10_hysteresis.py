"""Paper figs. 9-10: EUPI hysteresis loops (main and minor loop) and the e_r of eq. (3) vs the paper's 6.3 %.

    python experiments/fig09_10_hysteresis.py [--out experiments/out/fig09_10_hysteresis] [--quick]

Runs the same code as the corresponding section of `smafl paper` on the bundled
records and prints the numbers; figures and the fitted model go to --out.
"""

import sys
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))
from _section import run_section

if __name__ == "__main__":
    raise SystemExit(run_section("fig09_10_hysteresis", "section_eupi", __doc__))
