"""Paper figs. 11-12: the Joule heat lag U^2 -> displacement (eq. 7) vs the paper's K1, K2 and 0.510 mm.

    python experiments/fig11_12_joule.py [--out experiments/out/fig11_12_joule] [--quick]

Runs the same code as the corresponding section of `smafl paper` on the bundled
records and prints the numbers; figures and the fitted model go to --out.
"""

import sys
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))
from _section import run_section

if __name__ == "__main__":
    raise SystemExit(run_section("fig11_12_joule", "section_joule", __doc__))
